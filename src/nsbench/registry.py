"""Discovery of problems and integrators through entry points.

Built-ins and plug-ins register the same way, in the ``nsbench.problems`` and
``nsbench.integrators`` entry-point groups. Entries are listed from package
metadata without importing them, read once per process (:func:`refresh` reads
them again); an entry is imported only when it is used, and one that fails to
import is reported as unavailable (with its reason) without breaking the others.
A plug-in's first import is tried in a child process (:mod:`nsbench.import_probe`),
so one that ends or hangs its process is unavailable too, instead of ending the
command.
"""

from __future__ import annotations

import difflib
from dataclasses import dataclass
from importlib import metadata
from typing import Any, Literal

from nsbench.errors import ConfigError, PluginLoadError

Kind = Literal["problems", "integrators"]
GROUPS: dict[str, str] = {
    "problems": "nsbench.problems",
    "integrators": "nsbench.integrators",
}

# Components registered in-process with `register` (tests, notebooks); they
# shadow entry points of the same name.
_RUNTIME: dict[str, dict[str, Any]] = {"problems": {}, "integrators": {}}
_LOADED: dict[tuple[str, str], Any] = {}
# The entry points of each group, read once per process: a plug-in installed while a run goes on
# would otherwise appear in the parts of it that read the metadata later, and only there.
_SNAPSHOT: dict[str, dict[str, metadata.EntryPoint]] = {}


@dataclass(frozen=True)
class Entry:
    """One registered component, as listed (not necessarily imported)."""

    kind: str
    name: str
    target: str
    distribution: str | None


def _group(kind: str) -> str:
    if kind not in GROUPS:
        raise ConfigError(f"unknown registry kind {kind!r}; allowed: {', '.join(GROUPS)}")
    return GROUPS[kind]


def _entry_points(kind: str) -> dict[str, metadata.EntryPoint]:
    group = _group(kind)
    if group not in _SNAPSHOT:
        found: dict[str, metadata.EntryPoint] = {}
        for ep in metadata.entry_points(group=group):
            found.setdefault(ep.name, ep)
        _SNAPSHOT[group] = found
    return dict(_SNAPSHOT[group])


def refresh() -> None:
    """Read the installed entry points again.

    The registry reads them once per process, so that every part of a run sees
    the same plug-ins; a long-lived session (a notebook) that installs one calls
    this to see it.
    """
    _SNAPSHOT.clear()
    _LOADED.clear()


def entries(kind: Kind) -> list[Entry]:
    """List the registered components of one kind, sorted by name, without importing them.

    Raises
    ------
    ConfigError
        If nothing at all is registered (nsbench itself is then not installed).
    """
    eps = _entry_points(kind)
    rows = {
        name: Entry(kind, name, ep.value, ep.dist.name if ep.dist is not None else None) for name, ep in eps.items()
    }
    for name, obj in _RUNTIME[kind].items():
        rows[name] = Entry(kind, name, f"{obj.__module__}:{getattr(obj, '__qualname__', obj)}", None)
    if not rows:
        raise ConfigError(
            f"no {kind} are registered in entry-point group {GROUPS[kind]!r}: "
            "is nsbench installed? (run `pip install -e .` in the checkout)"
        )
    return [rows[name] for name in sorted(rows)]


def names(kind: Kind) -> list[str]:
    """Names of all registered components of one kind."""
    return [e.name for e in entries(kind)]


def load(kind: Kind, name: str) -> Any:
    """Import and return the registered object ``name`` of ``kind``.

    Raises
    ------
    ConfigError
        If ``name`` is not registered; the message lists the registered names.
    PluginLoadError
        If the entry exists but fails to import.
    """
    if name in _RUNTIME[kind]:
        return _RUNTIME[kind][name]
    key = (kind, name)
    if key in _LOADED:
        return _LOADED[key]
    eps = _entry_points(kind)
    if name not in eps:
        known = names(kind)
        close = difflib.get_close_matches(name, known, n=1)
        hint = f" (did you mean {close[0]!r}?)" if close else ""
        raise ConfigError(f"unknown {kind[:-1]} {name!r}{hint}; registered: {', '.join(known)}")
    ep = eps[name]
    if ep.dist is None or ep.dist.name != "nsbench":  # a plug-in: its first import is tried apart
        from nsbench.import_probe import check_import

        check_import(f"{kind[:-1]} {name!r}", ep.value)  # PluginLoadError if it would end this process
    try:
        obj = ep.load()
    except Exception as exc:  # any import-time failure of a plug-in
        raise PluginLoadError(
            f"{kind[:-1]} {name!r} ({eps[name].value}) failed to import: {type(exc).__name__}: {exc}"
        ) from exc
    _LOADED[key] = obj
    return obj


def unavailable_reason(kind: Kind, name: str) -> str | None:
    """Why the registered ``name`` cannot run here, or ``None``.

    Either it fails to import (the :class:`PluginLoadError`'s message), or it imports but
    says what it runs on is missing: an optional backend not installed, with the command that
    installs it, or an external program (its class's ``unavailable()``; nsbench's engines
    behind a pip extra, :mod:`nsbench.integrators._optional`, and Siconos's).
    """
    try:
        obj = load(kind, name)
    except PluginLoadError as exc:
        return str(exc)
    missing = getattr(obj, "unavailable", None)
    why = missing() if callable(missing) else None
    return str(why) if why else None


def availability(kind: Kind) -> list[tuple[Entry, str | None]]:
    """Each entry with ``None`` if it can run here, else the reason it cannot (:func:`unavailable_reason`)."""
    return [(entry, unavailable_reason(kind, entry.name)) for entry in entries(kind)]


def register(kind: Kind, name: str, obj: Any) -> None:
    """Register ``obj`` under ``name`` for this process only (tests, notebooks)."""
    _group(kind)
    _RUNTIME[kind][name] = obj


def runtime_components() -> dict[str, dict[str, Any]]:
    """A copy of what :func:`register` added in this process (to re-register it in workers)."""
    return {kind: dict(objs) for kind, objs in _RUNTIME.items()}


def unregister(kind: Kind, name: str) -> None:
    """Remove a component registered with :func:`register`."""
    _RUNTIME[kind].pop(name, None)
