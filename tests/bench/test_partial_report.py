"""A report of a folder that lacks some of its suite's cases says so first, and a resumed run says what it does."""

from __future__ import annotations

import math

import pandas as pd

from nsbench.bench import storage
from nsbench.bench.figures import report_figures
from nsbench.bench.report import _spread_blocks, _timing_text, completeness
from nsbench.cli import main

SUITE = """\
name = "part"
t_span = [0.0, 20.0]
repeats = 3
max_repeats = 3
min_sample_time = 0.0
reference = ["exact"]
problems = [{ name = "one-dof", case = 1 }]

[integrators]
only = ["exact", "henon-rk4"]
grids = { henon-rk4 = { options = [{ h = 0.04 }, { h = 0.01 }] } }
"""


def test_a_report_with_cases_missing_says_how_many_which_and_how_to_resume(tmp_path, capsys):
    suite, out = tmp_path / "part.toml", tmp_path / "out"
    suite.write_text(SUITE)
    assert main(["bench", str(suite), "--out", str(out), "--workers", "1", "--no-progress"]) == 0
    md = (out / "report.md").read_text()
    assert md.splitlines()[0] == "# nsbench report"  # complete: no word of a partial run
    assert "Partial report" not in md
    # a run stopped before the tighter RK4 case: its stored row is gone, as after an interruption
    rows = storage.load_results(out)
    lost = rows[(rows["integrator"] == "henon-rk4") & (rows["level"] == 1)]
    assert len(lost) == 1
    storage.case_path(out, lost["case_id"].iloc[0]).unlink()
    capsys.readouterr()
    assert main(["report", str(out)]) == 0
    md = (out / "report.md").read_text()
    planned = len(rows)
    assert md.splitlines()[0] == f"# nsbench report (partial: {planned - 1} of {planned} cases)"
    first = md.split("**Partial report.**")[1].split("\n")[0]
    assert f"holds {planned - 1} of the suite's {planned} cases" in first
    assert "`one-dof/1 henon-rk4[h=0.01]`" in first
    assert f"`nsbench bench {suite} --out {out}` computes only the missing cases" in first
    # resuming: said in words before the run, and the report is whole again
    assert main(["bench", str(suite), "--out", str(out), "--workers", "1", "--no-progress"]) == 0
    err = capsys.readouterr().err
    assert f"resuming {out}: 1 of {planned} cases to run, {planned - 1} stored" in err
    assert (out / "report.md").read_text().splitlines()[0] == "# nsbench report"


def test_the_suite_is_read_from_the_provenance_and_an_unbuildable_one_is_no_claim():
    frame = pd.DataFrame({"case_id": ["x"]})
    assert completeness(frame, {}) is None  # no suite recorded (an ingested folder)
    assert completeness(frame, {"suite": {"name": "gone", "problems": [{"name": "no-such-problem"}]}}) is None


def test_cases_are_planned_for_the_integrators_the_run_selected_not_those_registered_since():
    from nsbench.bench.suite import Suite

    suite = {"name": "all", "t_span": [0.0, 1.0], "problems": [{"name": "one-dof", "case": 1}], "reference": ["exact"]}
    cases = Suite.from_dict(suite).cases()
    names = sorted({c.integrator for c in cases})
    assert len(names) > 3  # the suite takes every registered integrator
    # the run saw every integrator but the last (registered after it, as lugre was after a committed run)
    ran = [c for c in cases if c.integrator != names[-1]]
    frame = pd.DataFrame({"case_id": [c.case_id for c in ran], "integrator": [c.integrator for c in ran]})
    prov = {"suite": suite, "integrators_selected": names[:-1]}
    held = completeness(frame, prov)
    assert held is not None and not held.partial and held.planned == len(ran)
    # a folder written before the record: the integrators of its rows stand for the run's selection
    assert not completeness(frame, {"suite": suite}).partial
    # a case of a selected integrator that is missing is still missing
    short = completeness(frame.iloc[1:], prov)
    assert short.partial and short.missing == (ran[0].label,) and short.planned == len(ran)


def test_nothing_timed_states_no_times_and_draws_no_empty_figure(tmp_path):
    frame = pd.DataFrame(
        {
            "problem_label": ["one-dof/1"],
            "integrator": ["exact"],
            "status": ["time limit"],
            "wall_time": [math.nan],
            "wall_time_min": [math.nan],
            "wall_time_max": [math.nan],
            "wall_spread": [math.nan],
            "reference_status": ["ok"],
            "options": [{}],
        }
    )
    assert _timing_text(frame).startswith("No case of this report was timed")
    assert "No case of this report was timed" in _spread_blocks(frame)[1].text
    assert report_figures(frame, tmp_path) == []
