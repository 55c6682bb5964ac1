"""The runner: the tidy schema, statuses instead of lost suites, the time limit, the
reference cache, resume after an interruption (in-process and by Ctrl-C of a CLI run),
crashes, and scripts without a main guard."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from nsbench.bench import Suite, load_results, run_suite
from nsbench.bench.schema import COLUMN_NAMES, markdown_table
from nsbench.bench.timing import DEFAULT_SAMPLES, MIN_SAMPLE_TIME
from tests.bench import _integrators as ti


def small_suite(only, **kw):
    data = {
        "name": "small",
        "t_span": [0.0, 40.0],
        "repeats": 3,
        "max_repeats": 3,
        "problems": [{"name": "one-dof", "case": 1}],
        "integrators": {"only": list(only)},
    }
    data.update(kw)
    return Suite.from_dict(data)


@pytest.fixture(scope="module")
def pooled(tmp_path_factory):
    """One pooled run (2 workers) over linear problems and a cubic one without reference.

    The reference list leaves out the registered `reference` integrator, so the
    cubic problem takes the "no reference available" path.
    """
    out = tmp_path_factory.mktemp("pooled")
    suite = Suite.from_dict(
        {
            "name": "pooled",
            "t_span": [0.0, 40.0],
            "repeats": 3,
            "max_repeats": 3,
            "reference": ["exact"],
            "problems": [{"name": "one-dof", "case": 1}, {"name": "two-dof", "cases": [2, 3]}],
            "integrators": {"only": ["exact", "scipy-dop853"]},
        }
    )
    summary = run_suite(suite, out, workers=2, progress=False)
    return out, summary


def test_tidy_schema_one_row_per_case(pooled):
    out, summary = pooled
    frame = summary.results
    assert list(frame.columns) == list(COLUMN_NAMES)
    assert len(frame) == summary.n_cases == 3 * (1 + 3) and frame["case_id"].is_unique
    assert set(load_results(out)["case_id"]) == set(frame["case_id"])
    docs = (Path(__file__).resolve().parents[2] / "docs" / "bench.md").read_text()
    for name in COLUMN_NAMES:  # the documented column list covers every column
        assert f"`{name}`" in markdown_table() and f"| `{name}` |" in docs
    ok = frame[(frame["status"] == "success") & (frame["reference_status"] == "ok")]
    assert len(ok) == 2 * 4
    assert (ok["n_missed"] == 0).all() and (ok["n_extra"] == 0).all() and ok["sequence_ok"].all()
    exact = ok[ok["integrator"] == "exact"]
    # the reference against itself differs by 0, reported as its own certified error (never below it)
    assert (exact["event_err"].map(lambda e: max(map(abs, e))) == 0.0).all() and (exact["state_err_l2"] == 0.0).all()
    assert exact["at_ref_accuracy"].all() and (exact["switch_err_max"] == exact["ref_certainty"]).all()
    assert ((exact["ref_certainty"] > 0) & (exact["ref_certainty"] < 1e-13)).all()
    dop = ok[ok["integrator"] == "scipy-dop853"].sort_values(["problem_label", "level"])
    for _, g in dop.groupby("problem_label"):  # tighter tolerance, smaller error
        assert g["switch_err_max"].iloc[-1] < g["switch_err_max"].iloc[0] < 1e-4
        assert np.isfinite(g["state_err_l2"]).all()
    # every success: median of 3 warm timed samples, its range and spread; setup and warm-up apart
    timed = frame[frame["status"] == "success"]
    assert (timed["n_repeats"] == 3).all() and all(len(w) == 3 for w in timed["wall_times"])
    assert all(len(w) == 3 for w in timed["cpu_times"]) and (timed["cpu_time"] > 0).all()
    # a sample is one run, or a loop of 1, 2, 5, 10, 20, ... runs chosen by the calibration run
    autorange = {int(round(10 ** (k // 3) * (1, 2, 5)[k % 3])) for k in range(13)}
    assert set(timed["loops"]) <= autorange
    # exact over [0, 40] runs in about 1e-4 s (2-core development machine): a run 400 times slower
    # would still be shorter than the 50 ms minimum, so it is always looped
    assert (timed.loc[timed["integrator"] == "exact", "loops"] > 1).all()
    assert np.allclose(timed["wall_time"], [np.median(w) for w in timed["wall_times"]])
    assert np.allclose(timed["wall_time_min"], [min(w) for w in timed["wall_times"]])
    assert np.allclose(timed["wall_time_max"], [max(w) for w in timed["wall_times"]])
    assert np.allclose(timed["wall_spread"], (timed["wall_time_max"] - timed["wall_time_min"]) / timed["wall_time"])
    assert all(len(t) == 3 for t in timed["integrator_times"])  # NaN until the engine reports it
    timing = json.loads((out / "provenance.json").read_text())["timing"]
    assert timing["samples"] == 3 and timing["min_sample_time"] == MIN_SAMPLE_TIME
    # the load is read each time a sample is sent: at least once per stored sample (a sample sent again
    # after a worker was replaced on a busy machine reads it again)
    assert timing["load"]["n"] >= len(timed) * 3 and timing["load"]["min"] >= 0
    assert (timed["setup_time"] >= 0).all() and (timed["setup_time_timed"] >= 0).all()
    assert (timed["warmup_time"] > 0).all()
    assert not summary.in_process and summary.ok and summary.problems() == []

    import nsbench

    row = dop.iloc[0]
    integ = nsbench.integrator_from_config(json.loads(row["integrator_config"]))
    assert integ.config() == json.loads(row["integrator_config"])
    assert nsbench.problem_from_config(json.loads(row["problem_config"])).config() == json.loads(row["problem_config"])


def test_unsupported_and_missing_reference_are_rows(pooled):
    frame = pooled[1].results
    cubic = frame[frame["problem_label"] == "two-dof/3"]
    assert cubic.loc[cubic["integrator"] == "exact", "status"].tolist() == ["unsupported"]
    dop = cubic[cubic["integrator"] == "scipy-dop853"].sort_values("level")
    # at rtol 1e-6 DOP853's steps straddle the stick of block 1 at t ~ 25.68 and the slip after it (the
    # velocity guard dips across and back inside one step): its per-step check integrates that step again
    # and finds them (before it, the core saw it in the dense states and ended the run 'event missed')
    assert dop["status"].tolist() == ["success", "success", "success"]
    assert dop["reference_status"].str.startswith("no reference available").all()
    assert dop["switch_err_max"].isna().all()


def test_provenance_in_every_file(pooled):
    from nsbench.bench.storage import read_provenance

    out = pooled[0]
    files = [out / "results.parquet", out / "results.csv", next((out / "cases").glob("*.parquet")), out]
    for f in files:
        prov = read_provenance(f)
        for key in (
            "version_nsbench",
            "version_numpy",
            "version_scipy",
            "version_heyoka",
            "version_scikit-sundae",
            "python",
            "cpu",
            "date",
            "git_commit",
            "suite",
        ):
            assert key in prov, (f, key)
    csv = load_results(out / "results.csv")
    assert csv["event_err"].map(len).tolist() == pooled[1].results["event_err"].map(len).tolist()


def test_references_are_cached_on_disk(pooled, tmp_path):
    out, summary = pooled
    refs = sorted((out / "references").glob("*.json"))
    assert len(refs) == 3  # one per problem config
    stamps = [p.stat().st_mtime_ns for p in refs]
    again = run_suite(small_suite(["exact"], t_span=[0.0, 40.0]), out, workers=1, progress=False)
    assert again.n_computed == 0
    assert [p.stat().st_mtime_ns for p in refs] == stamps


def test_failures_become_rows_with_a_reason(register, tmp_path):
    register(ti.SleepyRK45.name, ti.SleepyRK45)
    register(ti.BrokenSetup.name, ti.BrokenSetup)
    suite = small_suite([ti.SleepyRK45.name, ti.BrokenSetup.name, "exact"], time_limit=1.0)
    frame = run_suite(suite, tmp_path, workers=1, progress=False).results.set_index("integrator")
    assert frame.loc["sleepy-rk45-test", "status"] == "time limit"
    assert "wall-clock limit of 1 s per run reached" in frame.loc["sleepy-rk45-test", "message"]
    assert "the worker process was stopped" in frame.loc["sleepy-rk45-test", "message"]
    assert frame.loc["broken-setup-test", "status"] == "error"
    assert "RuntimeError: plug-in bug in setup" in frame.loc["broken-setup-test", "message"]
    assert frame.loc["exact", "status"] == "success"


def test_stand_in_reference_for_a_cubic_problem(register, tmp_path):
    # A tight DOP853 registered under a test-only name stands in for the quad-precision
    # reference; it is not a certified reference, only a way through the cubic code path.
    register(ti.StandInReference.name, ti.StandInReference)
    suite = Suite.from_dict(
        {
            "t_span": [0.0, 40.0],
            "problems": [{"name": "two-dof", "case": 3}],
            "integrators": {"only": ["scipy-rk45"]},
            "reference": ["exact", ti.StandInReference.name],
        }
    )
    frame = run_suite(suite, tmp_path, workers=2, progress=False).results  # workers see the registration
    assert (frame["reference"] == ti.StandInReference.name).all() and (frame["reference_status"] == "ok").all()
    assert frame["sequence_ok"].all()
    errs = frame.sort_values("level")["switch_err_max"].to_numpy()
    assert errs[-1] < errs[0] < 1e-3


def test_resume_after_interrupt_computes_only_missing_cases(register, tmp_path, monkeypatch):
    # The interrupt comes from a timed run of the interrupting case once some row is stored (the
    # order of the timed runs follows the warm-ups' timings, which a busy machine may reorder).
    register(ti.Interrupting.name, ti.Interrupting)
    suite = small_suite(["scipy-rk45", "scipy-dop853", ti.Interrupting.name])
    n = len(suite.cases())
    monkeypatch.setenv("NSBENCH_TEST_INTERRUPT", str(tmp_path))
    with pytest.raises(KeyboardInterrupt):
        run_suite(suite, tmp_path, workers=1, progress=False)
    stored = sorted((tmp_path / "cases").glob("*.parquet"))
    assert 0 < len(stored) <= n
    frame = load_results(tmp_path)
    assert (frame["status"] == "success").all()
    # rows are stored after every timing round: those with all 3 runs are kept as they are,
    # those interrupted between rounds are timed again
    whole = set(frame.loc[frame["n_repeats"] == 3, "case_id"])
    assert len(whole) < n  # the interrupting case never finished its rounds
    before = {p.name: p.read_bytes() for p in stored if p.name[: -len(".parquet")] in whole}
    # the samples of the rounds that finished before the interrupt (the interrupted case: at least its first)
    partial = {r.case_id: list(r.wall_times) for r in frame.itertuples() if r.n_repeats < 3}
    assert partial
    monkeypatch.delenv("NSBENCH_TEST_INTERRUPT")
    summary = run_suite(suite, tmp_path, workers=1, progress=False)
    assert (summary.n_resumed, summary.n_computed) == (len(whole), n - len(whole))
    assert all((tmp_path / "cases" / name).read_bytes() == b for name, b in before.items())
    assert len(summary.results) == n and (summary.results["status"] == "success").all()
    assert (summary.results["n_repeats"] == 3).all()
    # a case interrupted between its rounds keeps its samples: the resume times only the rounds it lacked
    resumed = summary.results.set_index("case_id")
    for case_id, samples in partial.items():
        assert list(resumed.loc[case_id, "wall_times"])[: len(samples)] == samples, case_id


def _ctrl_c_as_in_a_terminal() -> None:
    """SIGINT's default disposition in the child, as a terminal gives it.

    A shell starts a background job with SIGINT ignored, and Python then installs no
    KeyboardInterrupt handler: a test run started that way (``pytest &`` in a script)
    would see the interrupt ignored, which is the job's setting, not nsbench's.
    """
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def test_ctrl_c_of_a_parallel_cli_run_keeps_finished_cases(tmp_path):
    # Twelve cases of similar cost: once two are stored, the other ten take far
    # longer than the moment between seeing the files and the interrupt, on any
    # machine; the wait itself has no clock (a cold compile may take minutes).
    steps = [0.004 - 0.0002 * k for k in range(12)]
    suite = tmp_path / "s.toml"
    suite.write_text(f"""
t_span = [0, 100]
repeats = 3
max_repeats = 3
problems = [{{ name = "one-dof", case = 1 }}]
[integrators]
only = ["henon-rk4"]
grids = {{ henon-rk4 = {{ grid = {{ h = {steps} }} }} }}
""")
    out = tmp_path / "out"
    proc = subprocess.Popen(
        [sys.executable, "-m", "nsbench", "bench", str(suite), "--out", str(out), "--workers", "2", "--no-progress"],
        start_new_session=True,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        preexec_fn=_ctrl_c_as_in_a_terminal,
    )
    while proc.poll() is None and len(list((out / "cases").glob("*.parquet"))) < 2:
        time.sleep(0.01)
    assert proc.poll() is None, "the suite ended before it could be interrupted"
    os.killpg(proc.pid, signal.SIGINT)
    _, err = proc.communicate(timeout=600)
    assert proc.returncode == 130, err
    stored = {p.name for p in (out / "cases").glob("*.parquet")}
    assert 2 <= len(stored) < len(steps)
    frame = load_results(out)  # what was stored is whole and readable
    assert (frame["status"] == "success").all() and (frame["n_repeats"] >= 1).all()
    # rows are stored after each timing round: a case with all its runs is kept, one with
    # fewer (interrupted between its rounds) is timed again
    whole = int((frame["n_repeats"] == 3).sum())
    summary = run_suite(suite, out, workers=1, progress=False)
    assert summary.n_resumed == whole and summary.n_computed == len(steps) - whole
    assert (summary.results["n_repeats"] == 3).all() and len(summary.results) == len(steps)


def test_a_crashing_worker_is_a_row_and_the_others_finish(register, tmp_path):
    register(ti.Crashing.name, ti.Crashing)
    suite = small_suite(["scipy-rk45", ti.Crashing.name], t_span=[0.0, 20.0])
    summary = run_suite(suite, tmp_path, workers=2, progress=False)
    frame = summary.results
    assert not summary.ok and "1 case(s) crashed" in summary.problems()[0]
    crashed = frame[frame["integrator"] == ti.Crashing.name]
    assert crashed["status"].tolist() == ["crashed"]
    assert "worker process died (exit code 3) during the warm-up run" in crashed["message"].iloc[0]
    assert (frame.loc[frame["integrator"] == "scipy-rk45", "status"] == "success").all() and len(frame) == 4


def assert_nothing_else_while_timing(timeline):
    """No worker start, reference or warm-up overlaps any timed case (parent-side bounds)."""
    timed = [r for r in timeline if r.kind == "time"]
    for other in (r for r in timeline if r.kind != "time"):
        for t in timed:
            assert other.end <= t.start or t.end <= other.start, (other, t)


def test_a_first_use_compilation_is_not_held_against_the_time_limit(register, tmp_path):
    # on a fresh install a warm-up run compiles what its setup did not: that is nsbench's first-use
    # cost, and the worker's parent holds the case's clock while it lasts; the sleepy method's own
    # arcs still meet the same limit
    register(ti.CompilingRK45.name, ti.CompilingRK45)
    register(ti.SleepyRK45.name, ti.SleepyRK45)
    suite = small_suite([ti.CompilingRK45.name, ti.SleepyRK45.name], time_limit=1.0)
    frame = run_suite(suite, tmp_path, workers=1, progress=False).results.set_index("integrator")
    assert frame.loc[ti.CompilingRK45.name, "status"] == "success", frame.loc[ti.CompilingRK45.name, "message"]
    assert frame.loc[ti.CompilingRK45.name, "warmup_time"] > 1.5  # the compilation was in its warm-up run
    assert frame.loc[ti.SleepyRK45.name, "status"] == "time limit"


def test_crash_and_hang_while_timing_are_rows_and_the_pool_recovers(register, tmp_path):
    register(ti.CrashingWhenTimed.name, ti.CrashingWhenTimed)
    register(ti.HangingWhenTimed.name, ti.HangingWhenTimed)
    # The crashing and hanging cases are tighter than the rk45 ones, so they are timed first and
    # cheaper cases remain after them: the lost workers must be replaced.
    suite = small_suite(
        ["scipy-rk45", ti.CrashingWhenTimed.name, ti.HangingWhenTimed.name],
        t_span=[0.0, 20.0],
        time_limit=5.0,
        integrators={
            "only": ["scipy-rk45", ti.CrashingWhenTimed.name, ti.HangingWhenTimed.name],
            "grids": {"scipy-rk45": {"grid": {"rtol": [1e-3, 1e-4, 1e-5, 1e-6]}}},
        },
    )
    summary = run_suite(suite, tmp_path, workers=2, progress=False)
    frame = summary.results.set_index("integrator")
    crashed, hung = frame.loc[ti.CrashingWhenTimed.name], frame.loc[ti.HangingWhenTimed.name]
    assert crashed["status"] == "crashed"
    assert "died (exit code 5) during the timed sample 1 of 3 (its calibration run)" in crashed["message"]
    assert hung["status"] == "time limit"
    assert "limit of 5 s per run reached in the timed sample 1 of 3 (its calibration run)" in hung["message"]
    assert crashed["setup_time"] >= 0 and hung["warmup_time"] > 0  # their warm-ups went through
    rk45 = frame.loc["scipy-rk45"]
    assert len(rk45) == 4 and (rk45["status"] == "success").all() and (rk45["n_repeats"] == 3).all()
    assert not summary.ok and (tmp_path / "results.parquet").exists()
    timeline = summary.timeline
    starts = [r for r in timeline if r.kind == "start"]
    assert len(starts) >= 3 and len({r.pid for r in starts}) == len(starts)
    for lost in (r for r in timeline if r.outcome in ("crashed", "time limit")):
        later = [r for r in timeline if r.kind == "time" and r.start >= lost.end and r.slot == lost.slot]
        if later:  # the slot timed again: through a fresh worker that started and warmed up first
            fresh = [r for r in timeline if r.slot == lost.slot and lost.end <= r.start <= later[0].start]
            assert [r.kind for r in fresh][:2] == ["start", "warm-up"]
    assert_nothing_else_while_timing(summary.timeline)


def test_the_phases_keep_warm_ups_apart_from_timing(pooled):
    timeline = pooled[1].timeline
    kinds = [r.kind for r in timeline]
    assert kinds.count("start") == 2 and kinds.count("reference") == 3
    # one timing task per timed run: 3 rounds per successful case, and a case whose first timed run
    # does not succeed (here DOP853 missing an event) is not timed again
    status = pooled[1].results["status"]
    ran = status.isin(["success", "event missed"])
    assert kinds.count("time") == 3 * sum(status == "success") + sum(ran & (status != "success"))
    first_time = min(r.start for r in timeline if r.kind == "time")
    assert all(r.end <= first_time for r in timeline if r.kind != "time")  # one barrier, no replacement
    assert_nothing_else_while_timing(timeline)


def test_beside_the_first_reference_the_other_worker_warms_up_another_integrator(pooled):
    # every reference needs exact's kernels, which the first reference's worker compiles on a fresh install:
    # the other worker does not queue behind it but warms up a case of another integrator (here DOP853)
    timeline = pooled[1].timeline
    first = min((r for r in timeline if r.kind == "reference"), key=lambda r: r.start)
    beside = sorted(
        (r for r in timeline if r.kind in ("reference", "warm-up") and r.slot != first.slot and r.start < first.end),
        key=lambda r: r.start,
    )
    if beside:  # the other worker was ready before the first reference ended (its start takes seconds)
        assert beside[0].kind == "warm-up" and "scipy-dop853" in beside[0].label, beside[0]


def test_timed_runs_are_taken_in_rounds_over_all_cases(pooled):
    # A case's three runs are spread over the timing phase (a drifting machine speed is
    # sampled, not met three times in one state): no case starts its run k + 1 before
    # every case has started its run k. (Every case here is warm on both workers.)
    by_case: dict[str, list[float]] = {}
    for r in sorted((r for r in pooled[1].timeline if r.kind == "time"), key=lambda r: r.start):
        by_case.setdefault(r.label, []).append(r.start)
    by_case = {label: starts for label, starts in by_case.items() if len(starts) > 1}  # not the failed ones
    assert by_case and all(len(starts) == 3 for starts in by_case.values())
    for k in range(2):
        assert min(s[k + 1] for s in by_case.values()) >= max(s[k] for s in by_case.values())


SCRIPT = """
from nsbench.bench import Suite, run_suite
{extra}
suite = Suite(problems=[{{"name": "one-dof", "case": 1}}], t_span=(0, 20),
              integrators={{"only": {only!r}}})
summary = run_suite(suite, {out!r}, workers=2, progress=False)
print("ROWS", len(summary.results), "IN_PROCESS", summary.in_process, "OK", summary.ok)
"""


def run_script(tmp_path, only, extra=""):
    script = tmp_path / "script.py"
    script.write_text(SCRIPT.format(extra=extra, only=only, out=str(tmp_path / "out")))
    proc = subprocess.run([sys.executable, str(script)], cwd=tmp_path, capture_output=True, text=True, timeout=600)
    return proc, load_results(tmp_path / "out")


def test_a_case_whose_samples_spread_widely_gets_its_extra_samples(register, tmp_path):
    # every other run of uneven-rk45 does four times the work: its samples spread far beyond 25 % on
    # every clock, so it is timed up to max_repeats; single runs (min_sample_time 0), so no loop averages
    # the alternation away
    register(ti.UnevenRK45.name, ti.UnevenRK45)
    suite = small_suite([ti.UnevenRK45.name], repeats=3, max_repeats=5, min_sample_time=0.0, t_span=[0.0, 20.0])
    summary = run_suite(suite, tmp_path, workers=1, progress=False)
    row = summary.results.iloc[0]
    assert row["status"] == "success" and row["n_repeats"] == 5 and len(row["cpu_times"]) == 5
    assert row["loops"] == 1


def test_a_script_without_main_guard_runs_in_workers(tmp_path):
    proc, frame = run_script(tmp_path, ["exact", "scipy-rk45"])
    assert proc.returncode == 0, proc.stderr
    assert "ROWS 4 IN_PROCESS False OK True" in proc.stdout and "Traceback" not in proc.stderr
    assert (frame["status"] == "success").all() and (frame["reference"] == "exact").all()
    assert (frame["reference_status"] == "ok").all() and frame["switch_err_max"].notna().all()
    assert len(list((tmp_path / "out" / "references").glob("*.json"))) == 1


def test_a_component_defined_in_main_runs_in_process_with_a_warning(tmp_path):
    extra = """
from nsbench import registry
from nsbench.integrators.scipy_ import ScipyRK45

class MyRK45(ScipyRK45):
    name = "my-rk45"
    accuracy_levels = ({"rtol": 1e-6, "atol": 1e-8},)

registry.register("integrators", "my-rk45", MyRK45)
"""
    proc, frame = run_script(tmp_path, ["my-rk45", "exact"], extra)
    assert proc.returncode == 0, proc.stderr
    assert "integrator 'my-rk45' is defined in __main__" in proc.stderr
    assert "ROWS 2 IN_PROCESS True OK True" in proc.stdout
    # the default 5 samples, and up to twice that for a case whose samples spread widely (a busy machine)
    assert (frame["status"] == "success").all() and frame["n_repeats"].between(
        DEFAULT_SAMPLES, 2 * DEFAULT_SAMPLES
    ).all()
    assert frame["switch_err_max"].notna().all()


KILLED = """
import sys
from nsbench import registry
from nsbench.bench import Suite, run_suite
from tests.bench import _integrators as ti
registry.register("integrators", ti.HangingWhenTimed.name, ti.HangingWhenTimed)
suite = Suite.from_dict({{"name": "k", "t_span": [0.0, 40.0], "repeats": 3, "reference": ["exact"],
                         "problems": [{{"name": "one-dof", "case": 1}}, {{"name": "two-dof", "case": 1}}],
                         "integrators": {{"only": [ti.HangingWhenTimed.name]}}}})
run_suite(suite, {out!r}, workers=2, progress=False)
"""


def test_killing_a_run_ends_its_workers(tmp_path):
    from tests.procs import kill_leaves_no_workers

    env = {**os.environ, "PYTHONPATH": os.pathsep.join([os.getcwd(), *sys.path])}
    proc = subprocess.Popen(
        [sys.executable, "-c", KILLED.format(out=str(tmp_path / "k"))],
        env=env,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    kill_leaves_no_workers(proc, 2)


def test_a_step_henon_rk4_cannot_take_is_an_unsupported_row_not_a_success(tmp_path):
    # h = 1e300 used to take one step over the span and report success
    suite = small_suite(
        [],
        t_span=[0.0, 20.0],
        reference=["exact"],
        integrators={"only": ["henon-rk4"], "grids": {"henon-rk4": {"grid": {"h": [0.01, 1e300]}}}},
    )
    frame = run_suite(suite, tmp_path, workers=1, progress=False).results.sort_values("step_value")
    assert frame["status"].tolist() == ["success", "unsupported"]
    assert "beyond RK4's stability limit" in frame["message"].iloc[1]


def test_a_setup_that_never_returns_costs_its_case_not_the_suite(register, tmp_path):
    # the setup (compilation) had no limit: a plug-in looping there hung the suite, nothing stored.
    # The limit covers scipy-rk45's own set-up in a fresh worker (loading its compiled law from the
    # cache): 3 s was passed on a machine loaded to ~7, and its cases ended in "time limit"
    register(ti.HangingSetup.name, ti.HangingSetup)
    suite = small_suite(["scipy-rk45", ti.HangingSetup.name], t_span=[0.0, 20.0], setup_limit=12.0)
    frame = run_suite(suite, tmp_path, workers=2, progress=False).results
    hung = frame[frame["integrator"] == ti.HangingSetup.name]
    assert hung["status"].tolist() == ["time limit"] and "in the setup" in hung["message"].iloc[0]
    assert (frame.loc[frame["integrator"] == "scipy-rk45", "status"] == "success").all() and len(frame) == 1 + 3
