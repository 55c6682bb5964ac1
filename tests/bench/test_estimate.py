"""The estimate of a run's time: the measured cost table, scaled to the machine and its load."""

from __future__ import annotations

import io
import math

import pandas as pd
import pytest

from nsbench.bench import Suite, load_suite, run_suite
from nsbench.bench.estimate import CostTable, calibrate, location_label, measure, plan
from nsbench.bench.targets import locations

SMALL = {
    "name": "small",
    "t_span": [0.0, 20.0],
    "problems": [{"name": "one-dof", "case": 1}],
    "integrators": {"only": ["exact", "scipy-rk45"]},
}


def _table(**kw) -> CostTable:
    cases = Suite.from_dict(SMALL).cases()
    return CostTable(
        calibration=0.02,
        warm_up={c.label: 0.5 for c in cases[:2]},
        run={c.label: 1.0 for c in cases[:2]},
        first={c.label: 1.5 for c in cases[:2]},
        reference=2.0,
        report=10.0,
        overhead=4.0,
        **kw,
    )


def test_the_estimate_adds_the_measured_tasks_and_spreads_them_over_the_workers():
    cases = Suite.from_dict(SMALL).cases()  # exact (1 level) and scipy-rk45 (3 levels)
    assert len(cases) == 4 and all(c.repeats == 5 for c in cases)
    p = plan(cases, n_references=1, workers=2, table=_table(), calibration=0.02, load=0.0, cores=2)
    # two known cases: warm-up 0.5, the first timing task 1.5 (calibration run, a sample, the metrics),
    # 4 more samples of 1.0 each; two unknown ones counted as the median known case
    work = 4 * (0.5 + 1.5 + 4 * 1.0) + 2.0
    assert p.n_unknown == 2 and p.n_runs == 20 and p.speed == pytest.approx(1.0)
    assert p.seconds == pytest.approx(work / 2 + 4.0 + 10.0)
    assert p.weights[cases[0].label] == pytest.approx((0.5, (1.5 + 4 * 1.0) / 5))  # per timing round
    assert "4 case(s): 20 timed samples" in p.statement() and "2 task(s) of unmeasured cost" in p.statement()
    # at most: every case's samples spread, so each gets max_repeats (twice repeats by default) samples
    assert all(c.max_repeats == 10 for c in cases)
    assert p.seconds_most == pytest.approx(p.seconds + 4 * 5 * 1.0 / 2)
    # a machine twice as slow, then the cores shared with two busy programs
    slow = plan(cases, n_references=1, workers=2, table=_table(), calibration=0.04, load=0.0, cores=2)
    assert slow.seconds == pytest.approx(2 * p.seconds)
    busy = plan(cases, n_references=1, workers=2, table=_table(), calibration=0.02, load=2.0, cores=2)
    # the calibration's best repeat runs at the core's own speed beside two busy programs; the workers
    # then get half a core each, and the one process that writes the report (and starts the workers)
    # two thirds of one
    assert busy.speed == pytest.approx(1.0) and "load 2.0 on 2 cores" in busy.statement()
    assert busy.seconds == pytest.approx(work + 1.5 * (4.0 + 10.0))


def test_a_suite_measured_apart_keeps_its_own_costs_in_the_time_scale_of_the_table():
    """A suite merged in (``--merge``) keeps its own tasks and fixed costs: a case label names no span, so the
    default suite's cases over [0, 100] never replace the full suite's of the same label over [0, 300]."""
    cases = Suite.from_dict(SMALL).cases()
    full = _table()
    # the short suite measured on a machine twice as slow: its seconds halve into the table's scale
    quick = CostTable(
        calibration=0.04,
        warm_up={cases[0].label: 0.2, cases[3].label: 1.0},
        run={cases[0].label: 0.4, cases[3].label: 2.0},
        target={"t exact[]": 6.0},
        reference=1.0,
        overhead=3.0,
        report=2.0,
        measured="later",
    )
    table = full.merged(quick, "small")
    assert table.costs(cases[3].label, "small") == (0.5, 1.0, 1.0) and table.costs(cases[3].label) is None
    assert table.costs(cases[0].label, "small") == (0.1, 0.2, 0.2)  # its own, over the same label's full one
    assert table.costs(cases[0].label) == (0.5, 1.5, 1.0) and table.costs(cases[1].label, "small") == (0.5, 1.5, 1.0)
    assert table.target_cost("t exact[]", "small") == 3.0 and table.target_cost("t exact[]") is None
    assert table.fixed("small") == (1.5, 1.0, 0.5) and table.fixed("other") == table.fixed() == (4.0, 10.0, 2.0)
    assert table.calibration == full.calibration and CostTable(**__import__("json").loads(table.to_json())) == table
    on_its_own = plan(cases, workers=2, table=table, calibration=0.02, load=0.0, cores=2, suite="small")
    as_another = plan(cases, workers=2, table=table, calibration=0.02, load=0.0, cores=2)
    assert (on_its_own.n_unknown, as_another.n_unknown) == (1, 2) and on_its_own.seconds < as_another.seconds
    assert full.suites == {}  # merged returns a new table


def test_no_table_no_estimate(monkeypatch):
    monkeypatch.setattr(CostTable, "packaged", classmethod(lambda cls: None))
    cases = Suite.from_dict(SMALL).cases()
    p = plan(cases, workers=1)
    assert math.isinf(p.seconds) and "no estimate of the time" in p.statement()


def test_the_packaged_table_knows_every_task_of_the_packaged_suites():
    # Regenerate it when a built-in integrator or a level changes: see nsbench.bench.estimate.
    table = CostTable.packaged()
    assert table is not None and table.calibration > 0
    for name in ("default", "full"):
        suite = load_suite(name)
        missing = [c.label for c in suite.cases() if table.costs(c.label, name) is None]
        missing += [
            loc
            for loc in locations(suite)
            if table.target_cost(location_label(loc.target.name, loc.integrator, loc.options), name) is None
        ]
        assert not missing, f"suite {name!r}: no measured cost for {missing[:5]}"


def test_the_table_is_measured_from_a_timeline(tmp_path):
    pd.DataFrame(
        {
            "slot": [0, 0, 0, 1, 1, 1, 1],
            "pid": [1] * 7,
            "kind": ["start", "reference", "warm-up", "time", "time", "time", "time"],
            "label": ["worker start", "k", "a", "a", "a", "a", "a"],
            "start": [0.0, 0.5, 1.5, 2.0, 3.0, 5.0, 6.5],
            "end": [0.5, 1.5, 2.0, 3.0, 5.0, 6.5, 7.0],
            "outcome": ["ready"] + ["done"] * 6,
        }
    ).to_csv(tmp_path / "timeline.csv", index=False)
    t = measure(tmp_path, total=7.5, workers=1, calibration=0.03)
    # the first timing task (1.0 s) apart, the later samples' median (2.0, 1.5, 0.5 -> 1.5)
    assert t.warm_up == {"a": 0.5} and t.first == {"a": 1.0} and t.run == {"a": 1.5} and t.reference == 1.0
    assert t.overhead == pytest.approx(7.5 - (1.0 + 0.5 + 1.0 + 2.0 + 1.5 + 0.5)) and t.calibration == 0.03
    assert CostTable(**__import__("json").loads(t.to_json())) == t


def test_a_table_measured_before_calibrated_samples_still_estimates():
    # costs.json of an older nsbench has no 'first': its timed run stands for every timing task
    cases = Suite.from_dict(SMALL).cases()
    old = CostTable(
        calibration=0.02,
        warm_up={c.label: 0.5 for c in cases},
        run={c.label: 1.0 for c in cases},
        reference=2.0,
        report=10.0,
        overhead=4.0,
    )
    p = plan(cases, n_references=0, workers=1, table=old, calibration=0.02, load=0.0, cores=1)
    assert p.n_unknown == 0 and p.seconds == pytest.approx(4 * (0.5 + 5 * 1.0) + 4.0 + 10.0)


def test_calibration_is_a_short_positive_time():
    seconds = calibrate(0.05)
    assert 0 < seconds < 0.05 * 100


def test_a_run_says_what_it_will_do_before_it_starts(tmp_path):
    err = io.StringIO()
    run_suite(
        Suite.from_dict({**SMALL, "integrators": {"only": ["exact"]}}), tmp_path, workers=1, progress=True, stream=err
    )
    first = err.getvalue().splitlines()[0]
    assert first.startswith("nsbench: suite 'small': 1 case(s): 5 timed samples after a warm-up each, on 1 worker(s)")
    assert "estimated about" in first


def test_a_fresh_run_plans_every_target_location_though_earlier_rows_are_stored(tmp_path, monkeypatch):
    """--fresh locates every bifurcation target again: its plan counts them, where a resumed run skips the stored."""
    from nsbench.bench import runner, targets

    suite = load_suite("default")
    every = {loc.row_id for loc in locations(suite)}
    monkeypatch.setattr(targets, "done_rows", lambda out: every)  # an earlier run's rows, all stored
    cases = suite.cases()[:3]
    said = {}
    for resume in (True, False):
        err = io.StringIO()
        runner._weights(suite, cases, 0, 2, tmp_path, err, True, resume)
        said[resume] = err.getvalue()
    assert "bifurcation-target location" not in said[True]
    assert f"then {len(every)} bifurcation-target location(s)" in said[False]
