"""``check`` and ``continuation`` run plug-ins in supervised workers; a plug-in problem's factory is probed first.

Issue 52 items 1 and 2. Each command runs in a subprocess with a timeout: before the fix,
a looping plug-in hung the command itself, and a hung test suite is no failure report.
The misbehaving plug-ins (``tests/bench/_integrators.py``, ``tests/faulty_plugins.py``)
are registered at run time in that subprocess; its workers import them by module.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import re
import time

import pandas as pd
import pytest

from nsbench.cli import main
from tests import faulty_plugins as bad
from tests.bench import _integrators as faulty

#: Seconds a command may take here: its limits below are seconds, the rest is worker starts and a cold
#: compile of the core on a fresh install. The commands that hung before the fix end at this timeout.
TIMEOUT = 300.0

REGISTER = (
    "import sys; from nsbench import registry; from tests.bench import _integrators as f; "
    "from tests import faulty_plugins as g; "
    "[registry.register('integrators', c.name, c) for c in "
    "(f.HangingSetup, f.Crashing, g.HangingAdvance, g.CrashingPast)]; "
    "[registry.register('problems', n, p) for n, p in g.PROBLEMS.items()]; "
    "from nsbench.cli import main; sys.exit(main(sys.argv[1:]))"
)


def _run(*argv: str) -> tuple[subprocess.CompletedProcess, float]:
    """``nsbench ARGV`` with the faulty plug-ins registered, and its wall seconds."""
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([os.getcwd(), *sys.path])}
    tic = time.monotonic()
    done = subprocess.run(
        [sys.executable, "-c", REGISTER, *argv], env=env, capture_output=True, text=True, timeout=TIMEOUT
    )
    return done, time.monotonic() - tic


def _row(out: str, check: str) -> list[str]:
    return next(line.split(None, 3) for line in out.splitlines() if line.split()[:1] == [check])


# ------------------------------------------------------------------------------------------- check
def test_check_a_crashing_plugin_fails_its_checks_with_the_reason_and_the_others_run():
    # os._exit(3) in advance ended the command with exit 3 and no table
    done, _ = _run(
        "check", faulty.Crashing.name, "--check", "protocol", "--check", "config-round-trip", "--setup-limit", "120"
    )
    assert done.returncode == 1, done.stderr
    assert "Traceback" not in done.stderr
    assert _row(done.stdout, "protocol")[1] == "FAILED"
    assert _row(done.stdout, "protocol")[3] == "crashed (exit code 3) in check protocol"
    assert _row(done.stdout, "config-round-trip")[1] == "PASSED"
    assert "first call: not measured (crashed (exit code 3) in first call)" in done.stdout
    assert "2 checks: 1 passed, 1 failed" in done.stdout


def test_check_a_plugin_whose_advance_hangs_fails_at_its_time_limit():
    done, seconds = _run(
        "check",
        bad.HangingAdvance.name,
        "--check",
        "protocol",
        "--check",
        "config-round-trip",
        "--time-limit",
        "3",
        "--setup-limit",
        "120",
    )
    assert done.returncode == 1, done.stderr
    row = _row(done.stdout, "protocol")
    assert row[1] == "FAILED" and row[3] == "time limit (3 s) in check protocol", row
    assert "first call: not measured (time limit (3 s) in first call)" in done.stdout
    assert _row(done.stdout, "config-round-trip")[1] == "PASSED"
    assert seconds < TIMEOUT


def test_check_a_plugin_whose_setup_hangs_fails_the_checks_that_run_it_once():
    # a set-up that loops would hang every check again: they fail at once with its reason
    done, seconds = _run(
        "check",
        faulty.HangingSetup.name,
        "--check",
        "protocol",
        "--check",
        "determinism",
        "--check",
        "config-round-trip",
        "--setup-limit",
        "3",
    )
    assert done.returncode == 1, done.stderr
    for check in ("protocol", "determinism"):
        row = _row(done.stdout, check)
        assert row[1] == "FAILED" and row[3].endswith("(time limit (3 s) in integrator set-up)"), row
    assert _row(done.stdout, "config-round-trip")[1] == "PASSED"
    assert "3 checks: 1 passed, 2 failed" in done.stdout
    assert seconds < TIMEOUT


@pytest.mark.parametrize(
    "command, flag",
    [
        *((c, f) for c in ("check", "continuation") for f in ("--time-limit", "--setup-limit")),
        ("simulate", "--setup-limit"),  # simulate and lyapunov run in their own process: no --time-limit
        ("lyapunov", "--setup-limit"),
    ],
)
def test_a_bad_limit_is_refused_with_one_line(command, flag, tmp_path, capsys):
    argv = {
        "check": ["check", "exact"],
        "continuation": ["continuation", "two-dof", "--sweep", "v0=0.1:0.2", "--out", str(tmp_path / "c")],
        "simulate": ["simulate", "two-dof", "--events-out", str(tmp_path / "c")],
        "lyapunov": ["lyapunov", "two-dof", "--out", str(tmp_path / "c")],
    }[command]
    for text in ("0", "-1", "nan", "inf", "soon"):
        assert main([*argv, flag, text]) == 2
        (line,) = capsys.readouterr().err.strip().splitlines()
        assert line.startswith(f"nsbench: error: {flag} = "), line
    assert not (tmp_path / "c").exists()


# ------------------------------------------------------------------------------------ continuation
CONTINUATION = ("continuation", "two-dof", "--sweep", "v0=0.16:0.17", "--steps", "2", "--no-progress")


def test_continuation_a_plugin_whose_setup_hangs_stops_at_the_setup_limit(tmp_path):
    out = tmp_path / "c"
    done, seconds = _run(
        *CONTINUATION, "--integrator", faulty.HangingSetup.name, "--setup-limit", "3", "--out", str(out)
    )
    assert done.returncode == 1, done.stderr
    (line,) = done.stderr.strip().splitlines()
    assert line == (
        "nsbench: continuation: stopped: time limit (3 s) in flow set-up; no branch was complete, nothing written"
    )
    assert not out.exists() and seconds < TIMEOUT


def test_continuation_a_plugin_whose_advance_hangs_stops_at_the_time_limit(tmp_path):
    out = tmp_path / "c"
    done, _ = _run(*CONTINUATION, "--integrator", bad.HangingAdvance.name, "--time-limit", "3", "--out", str(out))
    assert done.returncode == 1, done.stderr
    assert (
        done.stderr.strip()
        .splitlines()[-1]
        .startswith("nsbench: continuation: stopped: time limit (3 s) in continuation")
    )
    assert "Traceback" not in done.stderr


def test_continuation_a_crash_keeps_the_branches_computed_before(tmp_path):
    # the first branch ends at v0 = 0.27442 (grazing-sliding); the plug-in crashes at the next value sought
    out = tmp_path / "c"
    argv = ["continuation", "two-dof", "--case", "1", "--sweep", "v0=0.2:0.3", "--steps", "16", "--origin", "0.16"]
    done, _ = _run(*argv, "--integrator", bad.CrashingPast.name, "--formats", "png", "--no-progress", "--out", str(out))
    assert done.returncode == 1, done.stderr
    assert done.stderr.strip().splitlines()[-1] == (
        f"nsbench: continuation: stopped: crashed (exit code 7) in continuation; the 1 branch(es) complete "
        f"before are written to {out}"
    )
    branch = pd.read_csv(out / "branch.csv")
    assert set(branch["branch"].astype(str)) == {"1"}
    assert branch["value"].min() == 0.2 and 0.274 < branch["value"].max() < bad.CRASH_PAST_V0
    bifs = pd.read_csv(out / "bifurcations.csv")
    assert (bifs["kind"] == "grazing-sliding").any()
    assert len(pd.read_csv(out / "points.csv")) > 0 and (out / "branches.png").is_file()
    meta = json.loads((out / "meta.json").read_text())
    assert meta["stopped"] == "crashed (exit code 7) in continuation"


# ------------------------------------------------------------------------- a problem plug-in's factory
@pytest.mark.parametrize(
    "problem, fault",
    [
        ("looping-problem-test", "its factory ran past the set-up limit of 3 s (time limit; worker ended)"),
        ("raising-problem-test", "its factory raised RuntimeError: plug-in bug in the problem factory"),
    ],
)
@pytest.mark.parametrize("command", ["check", "bifurcation", "continuation", "simulate", "lyapunov"])
def test_a_faulty_problem_factory_is_one_line(command, problem, fault, tmp_path):
    # simulate and lyapunov built the problem in their own process: the looping factory hung them
    out = ["--out", str(tmp_path / "o"), "--no-progress"]
    argv = {
        "check": ["check", "exact", "--problem", problem, "--check", "protocol"],
        "bifurcation": ["bifurcation", problem, "--sweep", "v0=0.1:0.2:3", "--workers", "1", *out],
        "continuation": ["continuation", problem, "--sweep", "v0=0.1:0.2", *out],
        "simulate": ["simulate", problem, "--t-end", "1", "--events-out", str(tmp_path / "o")],
        "lyapunov": ["lyapunov", problem, "--workers", "1", "--out", str(tmp_path / "o")],
    }[command]
    done, seconds = _run(*argv, "--setup-limit", "3")
    assert done.returncode == 1, done.stderr
    (line,) = done.stderr.strip().splitlines()
    assert line.startswith(f"nsbench: {command}: problem {problem}: {fault}; "), line
    assert "Traceback" not in done.stderr
    assert not (tmp_path / "o").exists() and seconds < TIMEOUT


SUITE = """
name = "probe"
t_span = [0.0, 2.0]
setup_limit = 3.0
repeats = 3
max_repeats = 3

[[problems]]
name = "looping-problem-test"

[[problems]]
name = "one-dof"
case = 1

[[problems]]
name = "raising-problem-test"

[integrators]
only = ["henon-rk4"]
"""


def test_bench_a_faulty_problem_factory_costs_only_its_rows(tmp_path):
    suite = tmp_path / "suite.toml"
    suite.write_text(SUITE)
    out = tmp_path / "b"
    done, _ = _run("bench", str(suite), "--out", str(out), "--workers", "1", "--no-report", "--no-progress")
    assert done.returncode == 1, done.stderr
    lines = [ln for ln in done.stderr.splitlines() if ln.startswith("nsbench: bench: ")]
    assert lines == [
        "nsbench: bench: problem looping-problem-test: its factory ran past the set-up limit of 3 s (time limit; "
        "worker ended); its rows (problem table 1) are left out",
        "nsbench: bench: problem raising-problem-test: its factory raised RuntimeError: plug-in bug in the problem "
        "factory; its rows (problem table 3) are left out",
    ]
    assert "Traceback" not in done.stderr
    assert "INCOMPLETE: problem looping-problem-test" in done.stdout
    rows = pd.read_parquet(out / "results.parquet")
    assert set(rows["problem"]) == {"one-dof"} and len(rows) > 0


# ------------------------------------------------------------------------------------------- list coverage
def test_list_coverage_a_faulty_plugin_costs_its_own_column_or_row():
    # the looping factory is ended at the limit, the raising one named; the plug-in integrators' own set-ups
    # (one hangs, one crashes) are not run by the listing: their rows come from their capabilities
    done, seconds = _run("list", "coverage", "--setup-limit", "3")
    assert done.returncode == 0, done.stderr
    assert "Traceback" not in done.stderr
    out = done.stdout
    assert (
        "  looping-problem-test: problem looping-problem-test: its factory ran past the set-up limit of 3 s "
        "(time limit; worker ended)"
    ) in out
    assert (
        "  raising-problem-test: problem raising-problem-test: its factory raised RuntimeError: plug-in bug in "
        "the problem factory"
    ) in out
    for name in (faulty.HangingSetup.name, faulty.Crashing.name):
        assert re.search(rf"^  {re.escape(name)} +(yes|-)", out, re.M), name
    assert seconds < TIMEOUT
