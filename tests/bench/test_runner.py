"""The runner: the tidy schema, statuses instead of lost suites, the time limit, the
reference cache, resume after an interruption (in-process and by Ctrl-C of a CLI run)."""

from __future__ import annotations

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
from tests.bench import _integrators as ti


def small_suite(only, **kw):
    data = {"name": "small", "t_span": [0.0, 40.0], "repeats": 3, "problems": [{"name": "one-dof", "case": 1}],
            "integrators": {"only": list(only)}}
    data.update(kw)
    return Suite.from_dict(data)


@pytest.fixture(scope="module")
def pooled(tmp_path_factory):
    """One pooled run (2 workers) over linear problems and a cubic one without reference.

    The reference list leaves out the registered `reference` integrator, so the
    cubic problem takes the "no reference available" path.
    """
    out = tmp_path_factory.mktemp("pooled")
    suite = Suite.from_dict({
        "name": "pooled", "t_span": [0.0, 40.0], "repeats": 3, "reference": ["exact"],
        "problems": [{"name": "one-dof", "case": 1}, {"name": "two-dof", "cases": [2, 3]}],
        "integrators": {"only": ["exact", "scipy-dop853"]},
    })
    summary = run_suite(suite, out, workers=2, progress=False)
    return out, summary


def test_tidy_schema_one_row_per_case(pooled):
    out, summary = pooled
    frame = summary.results
    assert list(frame.columns) == list(COLUMN_NAMES)
    assert len(frame) == summary.n_cases == 3 * (1 + 3) and frame["case_id"].is_unique
    assert set(load_results(out)["case_id"]) == set(frame["case_id"])
    docs = (Path(__file__).resolve().parents[2] / "docs" / "bench.md").read_text()
    for name in COLUMN_NAMES:           # the documented column list covers every column
        assert f"`{name}`" in markdown_table() and f"| `{name}` |" in docs
    ok = frame[(frame["status"] == "success") & (frame["reference_status"] == "ok")]
    assert len(ok) == 2 * 4
    assert (ok["n_missed"] == 0).all() and (ok["n_extra"] == 0).all() and ok["sequence_ok"].all()
    exact = ok[ok["integrator"] == "exact"]
    assert (exact["switch_err_max"] == 0.0).all() and (exact["state_err_l2"] == 0.0).all()
    dop = ok[ok["integrator"] == "scipy-dop853"].sort_values(["problem_label", "level"])
    for _, g in dop.groupby("problem_label"):  # tighter tolerance, smaller error
        assert g["switch_err_max"].iloc[-1] < g["switch_err_max"].iloc[0] < 1e-4
        assert np.isfinite(g["state_err_l2"]).all()
    # warm median of repeats; setup time in its own column; configs rebuild the components
    cheap = frame[frame["n_repeats"] == 3]
    assert len(cheap) and all(len(w) == 3 for w in cheap["wall_times"])
    assert np.allclose(cheap["wall_time"], [np.median(w[1:]) for w in cheap["wall_times"]])
    assert (frame.loc[frame["status"] == "success", "setup_time"] >= 0).all()
    import json

    import nsbench
    row = dop.iloc[0]
    integ = nsbench.integrator_from_config(json.loads(row["integrator_config"]))
    assert integ.config() == json.loads(row["integrator_config"])
    assert nsbench.problem_from_config(json.loads(row["problem_config"])).config() == json.loads(row["problem_config"])


def test_unsupported_and_missing_reference_are_rows(pooled):
    frame = pooled[1].results
    cubic = frame[frame["problem_label"] == "two-dof/3"]
    assert cubic.loc[cubic["integrator"] == "exact", "status"].tolist() == ["unsupported"]
    dop = cubic[cubic["integrator"] == "scipy-dop853"]
    assert (dop["status"] == "success").all()
    assert dop["reference_status"].str.startswith("no reference available").all()
    assert dop["switch_err_max"].isna().all()


def test_provenance_in_every_file(pooled):
    from nsbench.bench.storage import read_provenance

    out = pooled[0]
    files = [out / "results.parquet", out / "results.csv", next((out / "cases").glob("*.parquet")), out]
    for f in files:
        prov = read_provenance(f)
        for key in ("version_nsbench", "version_numpy", "version_scipy", "version_heyoka",
                    "version_scikit-sundae", "python", "cpu", "date", "git_commit", "suite"):
            assert key in prov, (f, key)
    csv = load_results(out / "results.csv")
    assert csv["event_err"].map(len).tolist() == pooled[1].results["event_err"].map(len).tolist()


def test_references_are_cached_on_disk(pooled, tmp_path):
    out, summary = pooled
    refs = sorted((out / "references").glob("*.json"))
    assert len(refs) == 3                         # one per problem config
    stamps = [p.stat().st_mtime_ns for p in refs]
    again = run_suite(small_suite(["exact"], t_span=[0.0, 40.0]), out, workers=1, progress=False)
    assert again.n_computed == 0
    assert [p.stat().st_mtime_ns for p in refs] == stamps


def test_failures_become_rows_with_a_reason(register, tmp_path):
    register(ti.SleepyRK45.name, ti.SleepyRK45)
    register(ti.BrokenSetup.name, ti.BrokenSetup)
    suite = small_suite([ti.SleepyRK45.name, ti.BrokenSetup.name, "exact"], time_limit=0.15)
    frame = run_suite(suite, tmp_path, workers=1, progress=False).results.set_index("integrator")
    assert frame.loc["sleepy-rk45-test", "status"] == "time limit"
    assert "wall-clock limit of 0.15 s" in frame.loc["sleepy-rk45-test", "message"]
    assert 0 < frame.loc["sleepy-rk45-test", "t_final"] < 40
    assert frame.loc["broken-setup-test", "status"] == "error"
    assert "RuntimeError: plug-in bug in setup" in frame.loc["broken-setup-test", "message"]
    assert frame.loc["exact", "status"] == "success"


def test_stand_in_reference_for_a_cubic_problem(register, tmp_path):
    # A tight DOP853 registered under a test-only name stands in for the quad-precision
    # reference; it is not a certified reference, only a way through the cubic code path.
    register(ti.StandInReference.name, ti.StandInReference)
    suite = Suite.from_dict({"t_span": [0.0, 40.0], "problems": [{"name": "two-dof", "case": 3}],
                             "integrators": {"only": ["scipy-rk45"]},
                             "reference": ["exact", ti.StandInReference.name]})
    frame = run_suite(suite, tmp_path, workers=2, progress=False).results   # workers see the registration
    assert (frame["reference"] == ti.StandInReference.name).all() and (frame["reference_status"] == "ok").all()
    assert frame["sequence_ok"].all()
    errs = frame.sort_values("level")["switch_err_max"].to_numpy()
    assert errs[-1] < errs[0] < 1e-3


def test_resume_after_interrupt_computes_only_missing_cases(register, tmp_path, monkeypatch):
    register(ti.Interrupting.name, ti.Interrupting)
    suite = small_suite(["scipy-rk45", "scipy-dop853", ti.Interrupting.name])
    order = sorted(suite.cases(), key=lambda c: -c.level)    # the runner's order
    k = [c.integrator for c in order].index(ti.Interrupting.name)
    monkeypatch.setenv("NSBENCH_TEST_INTERRUPT", "1")
    with pytest.raises(KeyboardInterrupt):
        run_suite(suite, tmp_path, workers=1, progress=False)
    stored = sorted((tmp_path / "cases").glob("*.parquet"))
    assert len(stored) == k > 0
    before = {p.name: p.read_bytes() for p in stored}
    monkeypatch.delenv("NSBENCH_TEST_INTERRUPT")
    summary = run_suite(suite, tmp_path, workers=1, progress=False)
    assert (summary.n_resumed, summary.n_computed) == (k, len(order) - k)
    assert all((tmp_path / "cases" / n).read_bytes() == b for n, b in before.items())
    assert len(summary.results) == len(order) and (summary.results["status"] == "success").all()


def test_ctrl_c_of_a_parallel_cli_run_keeps_finished_cases(tmp_path):
    suite = tmp_path / "s.toml"
    suite.write_text("""
t_span = [0, 25]
repeats = 1
problems = [{ name = "one-dof", case = 1 }]
[integrators]
only = ["henon-rk4"]
grids = { henon-rk4 = { grid = { h = [0.04, 0.02, 0.01, 0.008, 0.006, 0.005] } } }
""")
    out = tmp_path / "out"
    proc = subprocess.Popen([sys.executable, "-m", "nsbench", "bench", str(suite), "--out", str(out),
                             "--workers", "2", "--no-progress"], start_new_session=True,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and len(list((out / "cases").glob("*.parquet"))) < 2:
        time.sleep(0.05)
    os.killpg(proc.pid, signal.SIGINT)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, err
    stored = {p.name for p in (out / "cases").glob("*.parquet")}
    assert 2 <= len(stored) < 6
    frame = load_results(out)                          # what was stored is whole and readable
    assert (frame["status"] == "success").all()
    summary = run_suite(suite, out, workers=1, progress=False)
    assert summary.n_resumed == len(stored) and summary.n_computed == 6 - len(stored)


def test_a_crashing_worker_is_a_row_and_the_others_finish(register, tmp_path):
    register(ti.Crashing.name, ti.Crashing)
    suite = small_suite(["scipy-rk45", ti.Crashing.name], t_span=[0.0, 20.0])
    frame = run_suite(suite, tmp_path, workers=2, progress=False).results
    crashed = frame[frame["integrator"] == ti.Crashing.name]
    assert crashed["status"].tolist() == ["crashed"] and "worker process died" in crashed["message"].iloc[0]
    assert (frame.loc[frame["integrator"] == "scipy-rk45", "status"] == "success").all() and len(frame) == 4
