"""Plug-ins that end, crash or hang their process at import are unavailable, not fatal.

A fake distribution with such entry points is put on the path of subprocesses
(never installed into the test environment): ``nsbench list`` and a suite with
``registered = true`` name each as unavailable with the reason and go on.
"""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from nsbench.integrators import list_integrators

PLUGINS = {
    "exits-at-import": ("evil_exit_plugin", "import os\nos._exit(3)\n", "ended its process (exit code 3)"),
    "segfaults-at-import": (
        "evil_segv_plugin",
        "import os, signal\nos.kill(os.getpid(), signal.SIGSEGV)\n",
        "ended its process (signal 11 (SIGSEGV))",
    ),
    "hangs-at-import": ("evil_hang_plugin", "import time\ntime.sleep(3600)\n", "did not finish importing within 5 s"),
    "raises-at-import": ("evil_raise_plugin", "raise RuntimeError('broken plug-in')\n", "RuntimeError: broken plug-in"),
}


@pytest.fixture(scope="module")
def evil_env(tmp_path_factory):
    site = tmp_path_factory.mktemp("evil-site")
    info = site / "nsbench_evil-0.1.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: nsbench-evil\nVersion: 0.1\n")
    lines = ["[nsbench.integrators]"]
    for name, (module, code, _) in PLUGINS.items():
        (site / f"{module}.py").write_text(code)
        lines.append(f"{name} = {module}:Thing")
    (info / "entry_points.txt").write_text("\n".join(lines) + "\n")
    env = {
        **os.environ,
        "NSBENCH_IMPORT_LIMIT": "5",
        "PYTHONPATH": os.pathsep.join([str(site), os.getcwd(), os.environ.get("PYTHONPATH", "")]).rstrip(os.pathsep),
    }
    return env


def _nsbench(env, *args):
    return subprocess.run(
        [sys.executable, "-m", "nsbench", *args], capture_output=True, text=True, env=env, timeout=600
    )


def test_nsbench_list_survives_plugins_that_end_their_process_at_import(evil_env):
    out = _nsbench(evil_env, "list", "integrators")
    assert out.returncode == 0, out.stderr
    for name, (_, _, reason) in PLUGINS.items():
        (line,) = [row for row in out.stdout.splitlines() if row.split()[:1] == [name]]
        assert reason in line, line
    assert any(row.split()[:1] == ["exact"] for row in out.stdout.splitlines())  # the others are listed


def test_a_registered_true_suite_leaves_them_out_and_runs(evil_env, tmp_path):
    others = [n for n in list_integrators() if n != "exact"]
    suite = tmp_path / "s.toml"
    suite.write_text(
        't_span = [0, 5]\nrepeats = 3\nproblems = [{ name = "one-dof", case = 1 }]\n'
        f"[integrators]\nregistered = true\nexclude = {others!r}\n".replace("'", '"')
    )
    out = _nsbench(
        evil_env, "bench", str(suite), "--out", str(tmp_path / "o"), "--no-progress", "--no-report", "--workers", "1"
    )
    assert out.returncode == 0, out.stdout + out.stderr
    for name, (_, _, reason) in PLUGINS.items():
        assert f"integrator {name!r} left out" in out.stderr and reason in out.stderr
    assert "1 cases: 1 computed" in out.stdout


def test_a_plugin_that_imports_cleanly_is_probed_once(tmp_path, monkeypatch):
    from nsbench import import_probe

    (tmp_path / "fine_plugin.py").write_text("class Thing:\n    pass\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.delenv(import_probe.CHECKED_VAR, raising=False)
    import_probe.check_import("integrator 'fine'", "fine_plugin:Thing")
    assert "fine_plugin:Thing" in os.environ[import_probe.CHECKED_VAR]  # the workers it starts skip the probe
