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
SAFE_GIT = ("git", "-c", "core.fsmonitor=false", "-c", "core.hooksPath=/dev/null", "--no-optional-locks")


def source_checkout(package: str | Path | None = None) -> Path | None:
    """The git checkout of nsbench whose ``src/nsbench`` is ``package`` (default: this package), or ``None``.

    nsbench installed into a virtual environment that lies inside some other
    repository has that repository above it; its commit is not nsbench's, and
    asking git about it runs that repository's filters and config. Found without
    running git: the nearest folder above ``package`` with a ``.git`` entry must
    hold a ``pyproject.toml`` naming the project ``nsbench``, and ``package``
    must be its ``src/nsbench``.
    """
    import tomllib

    pkg = Path(package).resolve() if package is not None else Path(__file__).resolve().parent
    top = next((d for d in pkg.parents if (d / ".git").exists()), None)
    if top is None or pkg != top / "src" / "nsbench":
        return None
    try:
        name = tomllib.loads((top / "pyproject.toml").read_text()).get("project", {}).get("name")
    except (OSError, ValueError, UnicodeDecodeError):
        return None
    return top if name == "nsbench" else None


def git_commit(package: str | Path | None = None) -> str | None:
    """The commit of nsbench's own checkout (:func:`source_checkout`), ``+dirty`` if modified; else ``None``.

    Never the current directory, and never a repository nsbench merely lies in
    (an installed copy in a virtual environment inside another checkout): that
    checkout's git config and attributes could run commands (``core.fsmonitor``,
    clean filters on ``git status``) and its commit is not nsbench's. In nsbench's
    own checkout git is still called with fsmonitor and hooks disabled.
    """
    top = source_checkout(package)
    if top is None:
        return None
    env = {**os.environ, "GIT_OPTIONAL_LOCKS": "0"}
    for key in ("GIT_DIR", "GIT_WORK_TREE", "GIT_INDEX_FILE", "GIT_CONFIG_PARAMETERS"):
        env.pop(key, None)
    try:
        sha = subprocess.run(
            [*SAFE_GIT, "rev-parse", "HEAD"], cwd=top, capture_output=True, env=env, text=True, timeout=5, check=True
        ).stdout.strip()
        dirty = subprocess.run(
            [*SAFE_GIT, "status", "--porcelain", "--untracked-files=no"],
            cwd=top,
            capture_output=True,
            text=True,
            timeout=5,
            env=env,
        ).stdout.strip()
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
            rows.append(
                {
                    "kind": kind[:-1],
                    "name": entry.name,
                    "target": entry.target,
                    "distribution": entry.distribution,
                    "version": _version(entry.distribution) if entry.distribution else None,
                }
            )
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
