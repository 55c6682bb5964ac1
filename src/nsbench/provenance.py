"""Provenance: versions, machine and commit that every report and result file records."""

from __future__ import annotations

import datetime as _dt
import os
import platform
import subprocess
from importlib import metadata
from pathlib import Path
from typing import Any

PACKAGES = ("nsbench", "numpy", "scipy", "pandas", "matplotlib", "heyoka", "scikit-sundae", "numba")


def _version(dist: str) -> str | None:
    try:
        return metadata.version(dist)
    except metadata.PackageNotFoundError:
        return None


def cpu_name() -> str:
    """A readable CPU model name (``/proc/cpuinfo`` on Linux, ``platform`` otherwise)."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def git_commit(path: str | Path | None = None) -> str | None:
    """The commit of the git checkout at ``path`` (default: cwd), with ``+dirty`` if modified."""
    cwd = str(path) if path is not None else None
    try:
        sha = subprocess.run(["git", "rev-parse", "HEAD"], cwd=cwd, capture_output=True,
                             text=True, timeout=5, check=True).stdout.strip()
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], cwd=cwd,
                               capture_output=True, text=True, timeout=5).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return None
    return sha + ("+dirty" if dirty else "") if sha else None


def provenance() -> dict[str, Any]:
    """Versions of nsbench and its numerical stack, Python, machine, date and git commit."""
    info: dict[str, Any] = {f"version_{p}": _version(p) for p in PACKAGES}
    info.update(
        python=platform.python_version(),
        platform=platform.platform(),
        cpu=cpu_name(),
        cpu_count=os.cpu_count(),
        date=_dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
        git_commit=git_commit(),
    )
    return info
