"""Installing an example plug-in of ``examples/`` for a test: never into the developer's environment."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def install_example(work: Path, name: str) -> tuple[dict[str, str], Path]:
    """Install ``examples/<name>`` with pip into ``work/site``; the environment that puts it on the path, and the site.

    The subprocesses the tests start with that environment find the plug-in's entry points.
    """
    source = work / "source"
    shutil.copytree(EXAMPLES / name, source, ignore=shutil.ignore_patterns("build", "*.egg-info", "__pycache__"))
    site = work / "site"
    install = subprocess.run(
        [
            sys.executable,
            "-m",
            "pip",
            "install",
            "--no-deps",
            "--no-build-isolation",
            "--no-index",
            "--quiet",
            "--target",
            str(site),
            str(source),
        ],
        capture_output=True,
        text=True,
    )
    assert install.returncode == 0, install.stderr[-2000:]
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(site), env.get("PYTHONPATH", "")]).rstrip(os.pathsep)
    return env, site


def run_nsbench(env: dict[str, str], *args: str) -> subprocess.CompletedProcess:
    """``python -m nsbench ARGS`` in ``env``, its output captured."""
    return subprocess.run(
        [sys.executable, "-m", "nsbench", *args], capture_output=True, text=True, env=env, timeout=600
    )
