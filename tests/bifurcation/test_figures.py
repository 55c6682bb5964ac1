"""Sweep figures: legends beside the data (the diagram's failed values, the locus, the portrait)."""

from __future__ import annotations

import matplotlib
import numpy as np
import pandas as pd
import pytest

from nsbench import get_problem
from nsbench.bifurcation import figures
from tests.legends import overlaps

matplotlib.use("Agg")


@pytest.fixture
def kept(monkeypatch):
    """The figures handed to ``save``, kept open for inspection (nothing is written)."""
    out = []
    monkeypatch.setattr(figures, "save", lambda fig, base, formats=figures.FORMATS, dpi=100: out.append(fig) or [])
    yield out
    import matplotlib.pyplot as plt

    for fig in out:
        plt.close(fig)


def test_the_diagrams_legend_of_failed_values_is_beside_the_data(kept):
    values = np.linspace(0.1, 0.2, 40)
    rows = [
        {
            "param": "v0",
            "value": v,
            "index": i,
            "k": k,
            "status": "success" if i % 7 else "step budget exhausted",
            "x1": np.sin(30 * v) + 0.05 * k,
            "x2": np.cos(30 * v) + 0.05 * k,
        }
        for i, v in enumerate(values)
        for k in range(5)
    ]
    figures.diagram(pd.DataFrame(rows), "unused", title="planted sweep")
    (fig,) = kept
    assert any(ax.get_legend() is not None for ax in fig.axes) and overlaps(fig) == []


def test_the_locus_and_portrait_legends_are_beside_the_data(kept):
    from nsbench.bifurcation.locus import locus_run

    run = locus_run(get_problem("two-dof", case=1, v0=0.1), "exact", transient=300.0, duration=60.0, value=0.1)
    figures.locus(run, "unused", title="locus")
    figures.portrait(run, "unused", title="portrait")
    assert len(kept) == 2
    for fig in kept:
        assert fig.axes[0].get_legend() is not None and overlaps(fig) == []


def _legend_beside_the_axes():
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(4.0, 2.5))
    ax.plot([0, 1], [0, 1], label="a long label that sticks out of the figure")
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0))
    ax.set_xlabel("v0")
    fig.suptitle("title")
    fig.tight_layout()
    return fig


def test_save_finds_the_tight_box_once_and_writes_what_savefig_tight_writes(tmp_path):
    # save() draws the figure once for its tight box and hands every format that box, instead of
    # savefig's "tight" (which draws each format twice): the PNG must be the same image.
    import matplotlib.image as mpimg

    figures.save(_legend_beside_the_axes(), tmp_path / "ours", formats=("png", "svg", "pdf"))
    reference = _legend_beside_the_axes()
    reference.savefig(tmp_path / "tight.png", dpi=100, bbox_inches="tight")
    ours, tight = mpimg.imread(tmp_path / "ours.png"), mpimg.imread(tmp_path / "tight.png")
    assert ours.shape == tight.shape
    np.testing.assert_array_equal(ours, tight)
    assert (tmp_path / "ours.svg").stat().st_size > 0 and (tmp_path / "ours.pdf").stat().st_size > 0
