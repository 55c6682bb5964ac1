"""The continuation figure: its legend names the branches in their colours and lies beside the data."""

from __future__ import annotations

from types import SimpleNamespace

import matplotlib
import pandas as pd

from nsbench.periodic.output import LEGEND_BRANCHES, draw
from tests.legends import overlaps

matplotlib.use("Agg")


def _continuation(n_branches: int, unstable: bool = True):
    rows = []
    for b in range(1, n_branches + 1):
        for j, value in enumerate((0.1 * b, 0.1 * b + 0.02, 0.1 * b + 0.04)):
            stable = not (unstable and j == 2)
            rows += [
                {"branch": str(b), "value": value, "k": k, "stable": stable, "x1": b + 0.1 * k + 0.01 * j}
                for k in range(2)
            ]
    bifs = [
        SimpleNamespace(value=0.15, category="fixed-point"),
        SimpleNamespace(value=0.25, category="sliding"),
        SimpleNamespace(value=0.26, category="none"),
    ]
    return SimpleNamespace(param="v0", bifurcations=bifs), pd.DataFrame(rows)


def test_the_legend_names_each_branch_in_its_colour():
    import matplotlib.pyplot as plt
    from matplotlib.colors import to_hex

    result, points = _continuation(3)
    fig = draw(result, points, title="three branches")
    ax = fig.axes[0]
    legend = ax.get_legend()
    labels = [t.get_text() for t in legend.get_texts()]
    assert labels == [
        "branch 1",
        "branch 2",
        "branch 3",
        "stable orbits",
        "unstable orbits",
        "fixed-point bifurcation",
        "sliding bifurcation",
    ]
    # each branch's curves, solid and dashed, are drawn in the colour its legend entry shows
    curves = [line for line in ax.get_lines() if len(line.get_xdata()) > 1 or line.get_marker() == "."]
    for i, handle in enumerate(legend.legend_handles[:3]):
        mine = [c for c in curves if min(c.get_ydata()) >= i + 1 and max(c.get_ydata()) < i + 2]
        assert mine and {to_hex(c.get_color()) for c in mine} == {to_hex(handle.get_color())}
        assert {c.get_linestyle() for c in mine} == {"-", "--"}
    assert legend.legend_handles[3].get_linestyle() == "-" and legend.legend_handles[4].get_linestyle() == "--"
    assert overlaps(fig) == []
    plt.close(fig)


def test_many_branches_get_one_entry_saying_how_the_colours_repeat():
    import matplotlib.pyplot as plt

    result, points = _continuation(LEGEND_BRANCHES + 2, unstable=False)
    fig = draw(result, points)
    labels = [t.get_text() for t in fig.axes[0].get_legend().get_texts()]
    assert labels[0].startswith(f"{LEGEND_BRANCHES + 2} branches, one colour each, repeating every ")
    assert "unstable orbits" not in labels and "stable orbits" in labels  # only the styles drawn
    assert overlaps(fig) == []
    plt.close(fig)
