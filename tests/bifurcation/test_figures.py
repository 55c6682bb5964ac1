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


@pytest.mark.skipif(not hasattr(__import__("os"), "fork"), reason="formats are written in forked copies only with fork")
def test_every_format_is_written_even_when_a_forked_copy_fails(tmp_path, monkeypatch):
    import os
    import threading

    import matplotlib.pyplot as plt

    parent, write = os.getpid(), figures._write

    def fail_in_a_copy(fig, path, fmt, dpi):
        if os.getpid() != parent:
            raise OSError("no space left in the copy")
        write(fig, path, fmt, dpi)

    forks = []
    fork = os.fork
    monkeypatch.setattr(os, "fork", lambda: forks.append(1) or fork())
    monkeypatch.setattr(figures, "_write", fail_in_a_copy)
    alone = threading.active_count() == 1  # else no copy is forked (nor may be)
    fig, ax = plt.subplots()
    ax.plot([0, 1], [1, 0])
    paths = figures.save(fig, tmp_path / "line", formats=("png", "svg", "pdf"))
    assert [p.name for p in paths] == ["line.png", "line.svg", "line.pdf"]
    assert all(p.stat().st_size > 0 for p in paths)
    assert paths[1].read_text().lstrip().startswith("<?xml") and paths[2].read_bytes().startswith(b"%PDF")
    assert len(forks) == (2 if alone else 0)
