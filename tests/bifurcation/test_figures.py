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
