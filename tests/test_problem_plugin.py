"""The example problem plug-in (examples/problem_plugin): one module, installed, listed, solved, checked.

Installed with pip into a temporary directory (never into the developer's
environment) and exercised in subprocesses that have it on their path.
"""

from __future__ import annotations

import os
import subprocess
import sys

import pandas as pd
import pytest

from tests.examples import install_example, run_nsbench


@pytest.fixture(scope="module")
def plugin_env(tmp_path_factory):
    env, site = install_example(tmp_path_factory.mktemp("problem_plugin"), "problem_plugin")
    return env, site


_nsbench = run_nsbench


def test_the_problem_is_listed_through_its_entry_point(plugin_env):
    env, _ = plugin_env
    out = _nsbench(env, "list", "problems")
    assert out.returncode == 0, out.stderr
    (line,) = [row for row in out.stdout.splitlines() if row.split()[:1] == ["thermostat"]]
    assert "[plug-in: nsbench-thermostat-example]" in line
    assert "thermostat" not in _nsbench(dict(os.environ), "list", "problems").stdout  # not installed here


@pytest.mark.parametrize(
    "integrator, bound", [("exact", 1e-12), ("henon-rk4", 1e-6), ("ofapi", 1e-10), ("scipy-dop853", 1e-6)]
)
def test_built_in_integrators_solve_it_against_its_closed_form(plugin_env, tmp_path, integrator, bound):
    env, site = plugin_env
    events = tmp_path / "ev.csv"
    out = _nsbench(
        env,
        "simulate",
        "thermostat",
        "--integrator",
        integrator,
        "--t-end",
        "20",
        "--param",
        "a=0.7",
        "--param",
        "x_hi=2.5",
        "--param",
        "b=2.2",
        "--events-out",
        str(events),
    )
    assert out.returncode == 0, out.stderr
    assert "status      success" in out.stdout
    got = pd.read_csv(events)
    code = (
        "import sys; sys.path.insert(0, %r); import nsbench_thermostat as m; "
        "p = m.thermostat(a=0.7, x_hi=2.5, b=2.2); print(repr(p.switching_times(%d)))"
    ) % (str(site), len(got))
    want = eval(
        subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True).stdout
    )
    assert len(got) >= 10 and list(got["kind"]) == [k for _, k in want]
    assert (got["t"] - [t for t, _ in want]).abs().max() <= bound


def test_a_bad_parameter_is_refused_in_one_line(plugin_env):
    env, _ = plugin_env
    out = _nsbench(env, "simulate", "thermostat", "--integrator", "exact", "--param", "x_lo=3")
    assert out.returncode == 2 and "x_lo < x_hi" in out.stderr and "Traceback" not in out.stderr


@pytest.mark.parametrize("integrator", ["exact", "scipy-dop853"])
def test_the_conformance_kit_passes_on_it(plugin_env, integrator):
    """`nsbench check INTEGRATOR --problem thermostat`: the kit runs on the plug-in problem as given,
    against `reference` (its closed form through `exact`), the belt-only checks skipped with their reason."""
    env, _ = plugin_env
    out = _nsbench(env, "check", integrator, "--problem", "thermostat")
    assert out.returncode == 0, out.stdout + out.stderr
    lines = {row.split()[0]: row for row in out.stdout.splitlines()[2:] if row.startswith("  ")}
    for check in ("protocol", "determinism", "inputs-not-mutated", "event-times", "failure-status", "problem-config"):
        assert "PASSED" in lines[check], lines[check]
    assert "presets (cases 1-4); thermostat has none" in lines["stuck-stays-stuck"]
