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


#: Options that keep git from running programs a repository's own config names
#: (``core.fsmonitor``, hooks) while nsbench asks it for the commit.
_SAFE_GIT = ("git", "-c", "core.fsmonitor=false", "-c", "core.hooksPath=/dev/null", "--no-optional-locks")


def git_commit(path: str | Path | None = None) -> str | None:
    """The commit of the git checkout holding ``path`` (default: nsbench's own source), ``+dirty`` if modified.

    Never the current directory: a run started inside an untrusted checkout must
    not let that checkout's git config run commands (``core.fsmonitor`` runs on
    ``git status``). nsbench's own source is what is being run anyway, and git
    is called with fsmonitor and hooks disabled.
    """
    cwd = str(path) if path is not None else str(Path(__file__).resolve().parent)
    env = {**os.environ, "GIT_OPTIONAL_LOCKS": "0"}
    env.pop("GIT_DIR", None)
    env.pop("GIT_WORK_TREE", None)
    try:
        sha = subprocess.run([*_SAFE_GIT, "rev-parse", "HEAD"], cwd=cwd, capture_output=True, env=env,
                             text=True, timeout=5, check=True).stdout.strip()
        dirty = subprocess.run([*_SAFE_GIT, "status", "--porcelain", "--untracked-files=no"], cwd=cwd,
                               capture_output=True, text=True, timeout=5, env=env).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return None
    return sha + ("+dirty" if dirty else "") if sha else None


def plugins() -> list[dict[str, Any]]:
    """Every registered component that is not nsbench's own: kind, name, target, distribution and version.

    Plug-ins installed through an entry point name their distribution and its
    version; a component registered at run time (``nsbench.registry.register``)
    has neither (``None``). Listing imports none of them.
    """
    from nsbench import registry
    from nsbench.errors import ConfigError

    rows = []
    for kind in registry.GROUPS:
        try:
            entries = registry.entries(kind)  # type: ignore[arg-type]
        except ConfigError:  # nothing registered at all: no plug-in either
            continue
        for entry in entries:
            if entry.distribution == "nsbench":
                continue
            rows.append({"kind": kind[:-1], "name": entry.name, "target": entry.target,
                         "distribution": entry.distribution,
                         "version": _version(entry.distribution) if entry.distribution else None})
    return rows


def provenance() -> dict[str, Any]:
    """Versions of nsbench and its numerical stack, every plug-in, Python, machine, date and git commit."""
    info: dict[str, Any] = {f"version_{p}": _version(p) for p in PACKAGES}
    info["plugins"] = plugins()
    info.update(
        python=platform.python_version(),
        platform=platform.platform(),
        cpu=cpu_name(),
        cpu_count=os.cpu_count(),
        date=_dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
        git_commit=git_commit(),
    )
    return info
