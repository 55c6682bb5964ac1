"""Report figures: the runtime distributions (COCO style) and legends beside the data, on planted rows."""

from __future__ import annotations

import matplotlib
import numpy as np
import pandas as pd
import pytest

from nsbench.bench import figures
from nsbench.bench.storage import to_frame
from nsbench.bench.tables import fixed_target
from tests.legends import overlaps

matplotlib.use("Agg")


@pytest.fixture
def kept(monkeypatch):
    """The figures handed to ``_save``, kept open (nothing written); each call returns its index."""
    out = []
    monkeypatch.setattr(figures, "_save", lambda fig, folder, name, title, caption: out.append(
        (fig, name, caption)) or len(out) - 1)
    yield out
    import matplotlib.pyplot as plt

    for fig, _, _ in out:
        plt.close(fig)


def _row(problem, integrator, level, wall, nfev, err, ok=True):
    return {"case_id": f"{problem}-{integrator}-{level}", "problem_label": problem, "integrator": integrator,
            "level": level, "status": "success", "reference": "exact", "reference_status": "ok", "sequence_ok": ok,
            "switch_err_max": err, "wall_time": wall, "nfev": nfev, "options": "{}",
            "event_t": [1.0, 2.0, 3.0], "event_err": [err, -err, err / 2], "wall_time_min": wall * 0.9,
            "wall_time_max": wall * 1.1}


@pytest.fixture
def frame():
    # two problems x three targets = six pairs; costs and errors planted
    rows = []
    for p in ("two-dof/1", "two-dof/2"):
        rows += [_row(p, "exact", 0, 0.001, 0, 0.0),
                 _row(p, "a", 0, 0.01, 1000, 1e-7), _row(p, "a", 1, 0.04, 4000, 1e-10), _row(p, "a", 2, 0.1, 9000, 1e-13),
                 _row(p, "b", 0, 0.02, 500, 1e-7), _row(p, "b", 1, 0.3, 6000, 1e-8)]
    rows.append(_row("two-dof/2", "b", 2, 0.5, 8000, 1e-10, ok=False))      # a wrong sequence never solves
    return to_frame(rows)


def test_runtime_distribution_counts_the_pairs_each_method_solves(frame, kept):
    long = fixed_target(frame, (1e-6, 1e-9, 1e-12))
    styles = figures._styles(["a", "b", "exact"])
    assert figures.runtime_distribution(long[long["integrator"] != "exact"], styles, None) == 0
    fig, name, caption = kept[0]
    assert name == "runtime_distribution" and "6 (problem, target) pairs (2 problems, 3" in caption
    left, right = fig.axes[:2]
    curves = {line.get_label(): line for line in left.get_lines() if not line.get_label().startswith("_")}
    assert set(curves) == {"a", "b"}
    # a reaches 1e-6 at 0.01 s, 1e-9 at 0.04 s, 1e-12 at 0.1 s on both problems: all 6 pairs
    x, y = curves["a"].get_data()
    assert y[-1] == pytest.approx(1.0) and x[-1] == pytest.approx(0.1)
    # b reaches only 1e-6 (at 0.02 s) on both problems: 2 of 6 pairs
    x, y = curves["b"].get_data()
    assert y[-1] == pytest.approx(2 / 6) and np.allclose(x[1:], [0.02, 0.02])
    nfev = {line.get_label(): line for line in right.get_lines() if not line.get_label().startswith("_")}
    assert nfev["a"].get_data()[0][-1] == pytest.approx(9000)
    assert overlaps(fig) == []


def test_nothing_to_grade_draws_nothing(frame):
    long = fixed_target(frame.assign(reference_status="no reference available"), (1e-6,))
    assert figures.runtime_distribution(long, figures._styles(["a", "b", "exact"]), None) is None


@pytest.mark.parametrize("draw", ["work_precision", "event_error_along"])
def test_legends_are_beside_the_data(frame, kept, draw):
    styles = figures._styles(sorted(frame["integrator"].unique()))
    group = frame[frame["problem_label"] == "two-dof/1"]
    if draw == "work_precision":
        figures.work_precision(group, "two-dof/1", "wall_time", styles, None)
    else:
        figures.event_error_along(group, "two-dof/1", styles, None)
    fig = kept[0][0]
    assert (fig.legends or any(ax.get_legend() for ax in fig.axes)) and overlaps(fig) == []
