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


def test_it_is_swept_on_its_own_events_and_refused_a_section_it_has_no_state_for(plugin_env, tmp_path):
    """`nsbench bifurcation thermostat`: peaks (the rate of a position) need a state the thermostat does not
    have, so the default section is refused in one line that names the ones it has (``event:off``,
    ``event:on``); swept on ``event:off``, every point is the switch-off level ``x_hi`` and the points are
    one closed-form cycle apart: cooling from ``x_hi`` to ``x_lo`` takes ``ln(x_hi / x_lo) / a``, heating
    back ``ln((b / a - x_lo) / (b / a - x_hi)) / a`` (``b = 2``, ``x_lo = 1``, ``x_hi = 1.5``: its defaults).
    Before sections went by the problem's state names, every value failed with an ``IndexError``."""
    import math

    env, _ = plugin_env
    sweep = ["bifurcation", "thermostat", "--sweep", "a=0.8:1.0:3", "--transient", "10", "--record", "4"]
    refused = _nsbench(env, *sweep, "--out", str(tmp_path / "peaks"), "--workers", "1")
    assert refused.returncode == 2, refused.stdout + refused.stderr
    assert "use section event:off or event:on" in refused.stderr and "Traceback" not in refused.stderr
    assert len(refused.stderr.strip().splitlines()) == 1
    out = _nsbench(env, *sweep, "--section", "event:off", "--out", str(tmp_path / "off"), "--workers", "1")
    assert out.returncode == 0, out.stdout + out.stderr
    frame = pd.concat(pd.read_parquet(f) for f in sorted((tmp_path / "off" / "points").glob("*.parquet")))
    assert (frame["status"] == "success").all() and len(frame) == 3 * 4
    assert (frame["x"] - 1.5).abs().max() <= 1e-12
    for a, rows in frame.groupby("value"):
        cycle = math.log(1.5) / a + math.log((2 / a - 1.0) / (2 / a - 1.5)) / a
        assert abs(rows["t"].diff().dropna() - cycle).max() <= 1e-10, (a, rows["t"].tolist())
