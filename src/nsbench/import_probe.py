"""A plug-in's first import, tried in a child process under a time limit.

Importing a plug-in runs its code in the importing process: one that calls
``os._exit``, crashes in compiled code or never finishes its import would take
``nsbench list``, every suite with ``registered = true`` and any command that
names it along. :func:`check_import` imports the entry point's module (and
looks up its object) in a separate Python process first, once per process and
plug-in, and turns an abnormal end into a :class:`~nsbench.errors.PluginLoadError`
with the reason, as for an import that raises. A plug-in that imports cleanly
there is then imported as usual. nsbench's own entries are not probed; the
verdicts of a process reach the processes it starts (``NSBENCH_IMPORTS_CHECKED``),
so workers do not probe again.
"""

from __future__ import annotations

import os
import subprocess
import sys

from nsbench.errors import PluginLoadError

#: Seconds a plug-in's import may take in the probe (``NSBENCH_IMPORT_LIMIT`` overrides it).
IMPORT_LIMIT = 60.0
#: Environment variable listing the entry points (``module:object``) already seen to import.
CHECKED_VAR = "NSBENCH_IMPORTS_CHECKED"

_PROBE = (
    "import importlib, sys\n"
    "module, _, attr = sys.argv[1].partition(':')\n"
    "obj = importlib.import_module(module)\n"
    "for part in filter(None, attr.split('.')):\n"
    "    obj = getattr(obj, part)\n"
)


def _limit() -> float:
    try:
        value = float(os.environ.get("NSBENCH_IMPORT_LIMIT", IMPORT_LIMIT))
    except ValueError:
        return IMPORT_LIMIT
    return value if value > 0 else IMPORT_LIMIT


#: Entry points whose probe failed in this process, with the error (never probed twice).
_FAILED: dict[str, str] = {}


def _checked() -> set[str]:
    return set(filter(None, os.environ.get(CHECKED_VAR, "").split(",")))


def check_import(what: str, target: str) -> None:
    """Import ``target`` (``'module:object'``) in a child process; ``PluginLoadError`` if that process
    dies, is killed by a signal, or does not finish within the import limit.

    An import that merely raises is left to the caller's own import (which
    reports the exception itself); ``what`` names the component in messages.
    """
    if target in _checked():
        return
    if target in _FAILED:
        raise PluginLoadError(_FAILED[target])
    limit = _limit()
    try:
        done = subprocess.run(
            [sys.executable, "-c", _PROBE, target],
            stdin=subprocess.DEVNULL,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.PIPE,
            timeout=limit,
            env={**os.environ, "PYTHONPATH": os.pathsep.join(p for p in sys.path if p)},
        )
    except subprocess.TimeoutExpired:
        _FAILED[target] = (
            f"{what} ({target}) did not finish importing within {limit:g} s (NSBENCH_IMPORT_LIMIT); it was not imported"
        )
        raise PluginLoadError(_FAILED[target]) from None
    if done.returncode < 0 or (done.returncode != 0 and b"Traceback" not in done.stderr):
        _FAILED[target] = (
            f"{what} ({target}): importing it ended its process ({_describe(done.returncode)}); it was not imported"
        )
        raise PluginLoadError(_FAILED[target])
    if done.returncode == 0:  # a raising import is not remembered: the caller's import reports it
        os.environ[CHECKED_VAR] = ",".join(sorted(_checked() | {target}))


def _describe(returncode: int) -> str:
    """``'exit code 3'`` or ``'signal 11 (SIGSEGV)'`` (as :func:`nsbench.workers.pool.describe_exit`)."""
    import signal

    if returncode >= 0:
        return f"exit code {returncode}"
    try:
        return f"signal {-returncode} ({signal.Signals(-returncode).name})"
    except ValueError:
        return f"signal {-returncode}"
