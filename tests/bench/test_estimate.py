"""The estimate of a run's time: the measured cost table, scaled to the machine and its load."""

from __future__ import annotations

import io
import math

import pandas as pd
import pytest

from nsbench.bench import Suite, load_suite, run_suite
from nsbench.bench.estimate import TASK_SECONDS, CostTable, Probe, calibrate, location_label, measure, plan
from nsbench.bench.execute import WarmResult
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
    # 4 more samples of 1.0 each; two unknown ones counted as the cheapest known case (here alike)
    work = 4 * (0.5 + 1.5 + 4 * 1.0) + 2.0
    assert p.n_unknown == 2 and p.n_runs == 20 and p.speed == pytest.approx(1.0)
    assert p.seconds == pytest.approx(work / 2 + 4.0 + 10.0)
    assert (p.prepare, p.timing, p.after) == pytest.approx(((4 * 0.5 + 2.0) / 2 + 4.0, 4 * 5.5 / 2, 10.0))
    assert p.weights[cases[0].label] == pytest.approx((0.5, (1.5 + 4 * 1.0) / 5))  # per timing round
    assert "4 case(s): 20 timed samples" in p.statement() and "2 case(s) of unmeasured cost" in p.statement()
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
        runner._Costs.of(suite, cases, 0, 2, tmp_path, err, True, resume)
        said[resume] = err.getvalue()
    assert "bifurcation-target location" not in said[True]
    assert f"then {len(every)} bifurcation-target location(s)" in said[False]


def _uneven_table() -> CostTable:
    """The two exact/scipy-rk45 cases of SMALL measured, one cheap and one dear; the other two not."""
    cases = Suite.from_dict(SMALL).cases()
    return CostTable(
        calibration=0.02,
        warm_up={cases[0].label: 0.2, cases[1].label: 3.0},
        run={cases[0].label: 0.1, cases[1].label: 2.0},
        first={cases[0].label: 0.3, cases[1].label: 4.0},
        reference=2.0,
        report=10.0,
        overhead=4.0,
    )


def test_an_unmeasured_case_counts_as_the_cheapest_measured_one_and_the_plan_says_at_least():
    cases = Suite.from_dict(SMALL).cases()
    p = plan(cases, workers=2, table=_uneven_table(), calibration=0.02, load=0.0, cores=2)
    cheap, dear = 0.2 + 0.3 + 4 * 0.1, 3.0 + 4.0 + 4 * 2.0
    assert p.unmeasured == (cases[2].label, cases[3].label) and p.n_unknown == 2
    assert p.seconds == pytest.approx((3 * cheap + dear) / 2 + 4.0 + 10.0)  # the median would be the dear one's
    said = p.statement()
    assert "estimated at least about " in said and "2 case(s) of unmeasured cost" in said
    assert "a revised plan follows as the timing starts" in said and "up to" not in said and "typical" not in said
    known = plan(cases[:2], workers=2, table=_uneven_table(), calibration=0.02, load=0.0, cores=2).statement()
    assert "estimated about " in known and "at least" not in known and "unmeasured" not in known
    assert "preparing about " in known and "timing about " in known


def test_a_probe_costs_its_runs_per_sample_and_the_first_task_its_calibration_and_metrics():
    # a probe of a tenth of the span: 0.02 s of the engine in a call of 0.025 s (0.005 s of set-up and result)
    slow = Probe.of(WarmResult(1.0, 0.5, probe_span=0.1, probe_wall=0.02, probe_call=0.025))
    assert slow == Probe(call=pytest.approx(0.205), wall=pytest.approx(0.2))
    first, later = slow.costs(0.05)  # a run of 0.2 s is a sample on its own: its calibration run is the first
    assert later == pytest.approx(0.205 + TASK_SECONDS) and first == pytest.approx(later + 0.5 * 0.205)
    # a run of 0.012 s is looped 5 times into a 50 ms sample, and the first task has its calibration run
    fast = Probe.of(WarmResult(1.0, 0.5, probe_span=1.0, probe_wall=0.012, probe_call=0.012))
    first, later = fast.costs(0.05)
    assert later == pytest.approx(5 * 0.012 + TASK_SECONDS) and first == pytest.approx(later + 1.5 * 0.012)
    assert Probe.of(WarmResult(1.0, 0.5)) is None  # a warm-up without a probe


def test_a_plan_with_probes_costs_the_unmeasured_cases_by_them_and_says_the_revision():
    cases = Suite.from_dict(SMALL).cases()
    table = _uneven_table()
    probe = Probe(call=0.4, wall=0.4)
    probes = {cases[2].label: probe, cases[3].label: probe}
    p = plan(cases, workers=2, table=table, calibration=0.02, load=0.0, cores=2, probes=probes)
    first, later = probe.costs(cases[2].min_sample_time)
    probed = first + 4 * later  # measured here and now: not scaled by the speed or the load
    assert p.unmeasured == () and p.n_probed == 2 and p.n_unknown == 0
    assert p.timing == pytest.approx((0.3 + 4 * 0.1 + 4.0 + 4 * 2.0 + 2 * probed) / 2)
    assert p.weights[cases[3].label] == pytest.approx((0.0, probed / 5))  # its warm-up has run
    # on a machine twice as slow and loaded, the table's cases cost more; the probed ones as measured
    busy = plan(cases, workers=2, table=table, calibration=0.04, load=2.0, cores=2, probes=probes)
    assert busy.timing == pytest.approx((0.3 + 4 * 0.1 + 4.0 + 4 * 2.0) * 2 * 2 / 2 + probed)
    line = p.revision(elapsed=100.0)
    total = 100.0 + p.timing + p.after
    assert line.startswith(f"revised with the probes of 2 case(s): about {total / 60:.0f} min in all")
    assert "timing about " in line and "1:40 so far" in line
    # a probe that did not come back: its case stays at the cheapest, and the line says so
    one = plan(cases, workers=2, table=table, calibration=0.02, load=0.0, cores=2, probes={cases[2].label: probe})
    assert "1 case(s) without one counted as the cheapest measured" in one.revision(10.0)


def test_a_run_with_an_unmeasured_case_probes_it_and_revises_its_plan(tmp_path):
    """A case at options the table has not measured: the first line says at least, its warm-up probes it, and
    the revised line comes as the timing starts, with the probe's cost in the bar's weights."""
    suite = Suite.from_dict(
        {
            **SMALL,
            "repeats": 3,
            "max_repeats": 3,  # no extra samples for a spread seen under load: the count below is exact
            "integrators": {
                "only": ["scipy-rk45"],
                "grids": {"scipy-rk45": {"options": [{"rtol": 3e-5, "atol": 1e-8}]}},
            },
        }
    )
    assert CostTable.packaged().costs(suite.cases()[0].label, suite.name) is None
    err = io.StringIO()
    summary = run_suite(suite, tmp_path, workers=1, progress=True, stream=err)
    lines = err.getvalue().splitlines()
    assert "estimated at least about" in lines[0] and "1 case(s) of unmeasured cost" in lines[0]
    revised = [line for line in lines if "revised with the probes of 1 case(s): about" in line]
    timing = [k for k, line in enumerate(lines) if line.startswith("nsbench: timing:")]
    assert len(revised) == 1 and lines.index(revised[0]) == timing[0] + 1, lines
    assert summary.ok and summary.results["n_repeats"].tolist() == [3]
