"""The example out-of-tree plug-in (examples/plugin): installed, discovered through its entry point, checked.

It is installed with pip into a temporary directory (never into the
developer's environment) and exercised in subprocesses that have that
directory on their path.
"""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from tests.examples import EXAMPLES, install_example, run_nsbench


@pytest.fixture(scope="module")
def plugin_env(tmp_path_factory):
    env, site = install_example(tmp_path_factory.mktemp("plugin"), "plugin")
    return env


_nsbench = run_nsbench


def test_plugin_is_listed_through_its_entry_point(plugin_env):
    out = _nsbench(plugin_env, "list", "integrators")
    assert out.returncode == 0, out.stderr
    (line,) = [row for row in out.stdout.splitlines() if row.split()[:1] == ["heun-bisect"]]
    assert "[plug-in: nsbench-heun-example]" in line and "order=2" in line
    assert "heun-bisect" not in _nsbench(dict(os.environ), "list", "integrators").stdout  # not installed here


def test_plugin_passes_the_conformance_kit(plugin_env):
    out = _nsbench(plugin_env, "check", "heun-bisect")
    assert out.returncode == 0, out.stdout + out.stderr
    assert "FAILED" not in out.stdout
    assert "14 checks: 12 passed, 2 skipped" in out.stdout  # switch-convergence: whole-system methods only


def test_plugin_runs_by_name(plugin_env):
    out = _nsbench(
        plugin_env, "simulate", "two-dof", "--case", "1", "--integrator", "heun-bisect", "--t-end", "20", "--h", "0.002"
    )
    assert out.returncode == 0, out.stderr
    assert "heun-bisect" in out.stdout and "status      success" in out.stdout


def test_plugin_is_in_the_provenance_with_its_version(plugin_env):
    """provenance.json (of every run, sweep, report) names each plug-in, its distribution and version."""
    code = (
        "import json; from nsbench.provenance import provenance; "
        "print(json.dumps([p for p in provenance()['plugins'] if p['name'] == 'heun-bisect']))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=plugin_env, timeout=120)
    assert out.returncode == 0, out.stderr
    import json
    import tomllib

    version = tomllib.loads((EXAMPLES / "plugin" / "pyproject.toml").read_text())["project"]["version"]
    assert json.loads(out.stdout) == [
        {
            "kind": "integrator",
            "name": "heun-bisect",
            "target": "nsbench_heun:HeunBisection",
            "distribution": "nsbench-heun-example",
            "version": version,
        }
    ]
