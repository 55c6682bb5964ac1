"""A worker process never stores a row once its parent is gone.

A timing task can still sit in a worker's input pipe when the runner is killed;
the worker's first message about it then fails (``BrokenPipeError``). Before,
the case caught that as its own error and the worker stored an ``error`` row,
which a resumed run kept as the case's result.
"""

from __future__ import annotations

import subprocess
import sys
import time

from nsbench.bench import Suite, load_results, run_suite
from nsbench.workers import pool as wp
from nsbench.workers import protocol as msg
from nsbench.bench import tasks
from nsbench.bench.execute import WarmResult
from nsbench.bench.reference import candidates, compute_reference
from tests.procs import alive, children_of


def test_a_task_whose_parent_stopped_reading_stores_no_row(tmp_path):
    suite = Suite.from_dict(
        {"t_span": [0.0, 20.0], "problems": [{"name": "one-dof", "case": 1}], "integrators": {"only": ["exact"]}}
    )
    case = suite.cases()[0]
    ref = compute_reference(case.problem, candidates(["exact"]), case.t0, case.t_end, case.dense_points)
    worker = wp.WorkerProcess(wp.hello({}, tmp_path, {}))
    assert isinstance(worker.receive(), msg.Ready)
    worker.proc.stdout.close()  # the parent reads no more: every message of the worker now fails
    worker.send(tasks.TimeCase(1, case, "s", ref, WarmResult(0.0, 0.0)))
    worker.proc.stdin.close()
    assert worker.proc.wait(timeout=120) == 0  # it ends quietly (no traceback, no error exit)
    assert not (tmp_path / "cases").exists() or not any((tmp_path / "cases").iterdir())


def _ids_and_results(frame):
    cols = ["case_id", "integrator", "status", "n_events", "n_repeats", "n_matched", "switch_err_max"]
    return frame[cols].sort_values("case_id", ignore_index=True)


def test_sigkill_in_the_first_timing_round_then_resume_gives_the_rows_of_a_whole_run(tmp_path):
    # Twelve cheap cases on two workers: the first case files appear during the first timing
    # round (rows are stored from it on), and the other cases are still to come then.
    # max_repeats = repeats: no extra samples for a noisy case, whose count depends on the load.
    steps = [0.004 - 0.0002 * k for k in range(12)]
    suite = tmp_path / "s.toml"
    suite.write_text(f"""
t_span = [0, 100]
repeats = 3
max_repeats = 3
reference = ["exact"]
problems = [{{ name = "one-dof", case = 1 }}]
[integrators]
only = ["henon-rk4"]
grids = {{ henon-rk4 = {{ grid = {{ h = {steps} }} }} }}
""")
    whole = run_suite(suite, tmp_path / "whole", workers=2, progress=False).results
    out = tmp_path / "killed"
    proc = subprocess.Popen(
        [sys.executable, "-m", "nsbench", "bench", str(suite), "--out", str(out), "--workers", "2", "--no-progress"],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    workers: set[int] = set()
    while proc.poll() is None and not list((out / "cases").glob("*.parquet")):
        workers |= children_of(proc.pid)
        time.sleep(0.002)
    assert proc.poll() is None, "the suite ended before it could be killed"
    proc.kill()
    proc.wait()
    deadline = time.monotonic() + 60  # a worker polls for its parent once a second
    while time.monotonic() < deadline and any(alive(p) for p in workers):
        time.sleep(0.1)
    stored = load_results(out)
    assert len(stored) < len(steps)
    assert (stored["status"] == "success").all(), stored[["status", "message"]]  # never an error row
    resumed = run_suite(suite, out, workers=2, progress=False).results
    assert _ids_and_results(resumed).equals(_ids_and_results(whole))
