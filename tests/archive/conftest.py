"""Fixtures of the archive tests: two real ``nsbench bench`` runs of a tiny suite (different
integrator sets, one machine), and archives built from them, each made once per session."""

from __future__ import annotations

import shutil
from pathlib import Path

import pandas as pd
import pytest

from nsbench.archive import add_run
from nsbench.cli import main

SUITE = """
name = "tiny"
t_span = [0, 20]
repeats = 3
min_sample_time = 0  # one run per sample: the archive, not timing, is tested
problems = [{{ name = "one-dof", case = 1 }}]
[integrators]
only = [{only}]
"""
#: The two runs' integrator sets: the problem's reference and a method under test; two methods under test.
SETS = {"a": '"exact", "scipy-rk45"', "b": '"ofapi", "henon-rk4"'}


@pytest.fixture(scope="session")
def runs(tmp_path_factory) -> dict[str, Path]:
    """``{"a": folder, "b": folder}``: the results folders of two bench runs."""
    d = tmp_path_factory.mktemp("runs")
    out = {}
    for name, only in SETS.items():
        (d / f"{name}.toml").write_text(SUITE.format(only=only))
        out[name] = d / name
        argv = ["bench", str(d / f"{name}.toml"), "--out", str(out[name]), "--workers", "1", "--no-progress"]
        assert main([*argv, "--no-report"]) == 0
    return out


@pytest.fixture(scope="session")
def archive(runs, tmp_path_factory) -> Path:
    """An archive holding both runs (not to be changed by a test: copy it with :func:`copy`)."""
    path = tmp_path_factory.mktemp("archive") / "arch"
    for name in ("a", "b"):
        outcome = add_run(runs[name], path)
        assert outcome.run is not None and not outcome.refused, outcome
    return path


def copy(folder: Path, to: Path) -> Path:
    """A copy of ``folder`` at ``to`` (a test changes its own copy)."""
    shutil.copytree(folder, to)
    return to


def edited_run(run: Path, to: Path, edit) -> Path:
    """A results folder like ``run`` whose rows were rewritten by hand with pandas after ``edit(frame)``.

    The case files are left out and ``results.parquet`` is written by pandas alone, without the
    checksum nsbench stores with its tables (a checksum it could check is absent, so the folder reads
    as results: what a submitter editing the file by hand, or re-writing it with their own checksum,
    hands in). ``provenance.json`` is kept.
    """
    to.mkdir()
    shutil.copy(run / "provenance.json", to / "provenance.json")
    frame = pd.read_parquet(run / "results.parquet")
    edit(frame)
    frame.to_parquet(to / "results.parquet", index=False)
    return to
