"""A plug-in problem's factory, run first in a supervised worker under the set-up limit.

``get_problem(name, ...)`` calls the factory of a registered problem; for a plug-in's
problem that is foreign code, and the commands called it in their own process before
any worker ran: a factory that loops hung ``bench``, ``bifurcation``, ``check`` and
``continuation``, one that raised printed a traceback. Each of them first builds the
problems it will need in a worker of :mod:`nsbench.workers.jobs` (a *probe*), so that a loop is
ended at the set-up limit and a fault is one line naming the problem, and goes on as
before once the probe has built them all. A built-in problem (its factory's module is
under ``nsbench.``) is the project's own tested code and needs no probe.
"""

from __future__ import annotations

import dataclasses
from typing import Any, Callable, Hashable

from nsbench.errors import ConfigError, NsbenchError
from nsbench.status import OutcomeKind

#: The stage a probe runs in, named by the failure lines.
STAGE = "the problem's factory"


def is_plugin_problem(name: object) -> bool:
    """Whether ``name`` is a registered problem whose factory lives outside ``nsbench.`` (a plug-in's).

    An unknown name or one that cannot be loaded is not probed: ``get_problem`` then says so in one line.
    """
    from nsbench import registry

    if not isinstance(name, str):
        return False
    try:
        factory = registry.load("problems", name)
    except NsbenchError:
        return False
    module = str(getattr(factory, "__module__", "") or "")
    return not (module == "nsbench" or module.startswith("nsbench."))


def build_job(
    name: str, calls: list[dict[str, Any]], limit: float | None, *, stage: Callable, emit: Callable
) -> tuple[str, str]:
    """In a worker: ``get_problem(name, **kwargs)`` for each of ``calls``.

    Returns ``('ok', '')``, ``('refused', message)`` (the factory refused a value with
    a ``ConfigError``: bad input, as without the probe) or ``('raised', 'Type: message')``.
    """
    from nsbench.problems import get_problem

    stage(STAGE, limit)
    return _guarded(lambda: [get_problem(name, **kwargs) for kwargs in calls])


def suite_table_job(suite: Any, limit: float | None, *, stage: Callable, emit: Callable) -> tuple[str, str]:
    """In a worker: every problem of ``suite`` (a suite of one problem table) built as the suite builds them."""
    stage(STAGE, limit)
    return _guarded(suite.problem_spans)


def _guarded(build: Callable[[], Any]) -> tuple[str, str]:
    try:
        build()
    except NsbenchError as exc:
        return "refused", str(exc)
    except Exception as exc:  # the plug-in's fault: one line, its traceback is of no use to the user
        return "raised", f"{type(exc).__name__}: {exc}"
    return "ok", ""


def run_probes(jobs: dict[Hashable, tuple[str, tuple]], limit: float | None, pool: Any = None) -> dict[Hashable, tuple]:
    """Run each probe job (``key: (target, args)``) in ``pool`` (default a new pool of one worker).

    Returns ``key: (kind, text)``: ``kind`` ``'ok'``, ``'refused'`` or ``'raised'``
    (as :func:`build_job`), ``'time limit'`` or ``'crashed'`` (``text``: the exit code or signal).
    """
    from nsbench.workers.jobs import Job, JobPool

    if not jobs:
        return {}
    own = pool is None
    pool = JobPool(1) if own else pool
    found: dict[Hashable, tuple] = {}
    try:
        for key, (target, args) in jobs.items():
            pool.submit(Job(key, target, args))
        for o in pool.outcomes():
            if o.kind is OutcomeKind.DONE:
                found[o.key] = tuple(o.value)
            elif o.kind is OutcomeKind.FAILED:  # the job's own guard let it through (it should not)
                found[o.key] = ("raised", o.reason)
            elif o.kind is OutcomeKind.TIME_LIMIT:
                found[o.key] = ("time limit", f"{limit:g} s")
            elif o.kind is OutcomeKind.CRASHED:
                found[o.key] = ("crashed", _exit_of(o.reason))
    finally:
        if own:
            pool.close()
    return found


def _exit_of(reason: str) -> str:
    """``'exit code 3'`` from the pool's ``'worker process ended (exit code 3) during ...'``."""
    head, sep, rest = reason.partition("(")
    return rest.split(")")[0] if sep else reason


def failure_line(name: str, kind: str, text: str) -> str:
    """One line: what became of problem ``name``'s factory in its probe."""
    if kind == "time limit":
        return f"problem {name}: its factory ran past the set-up limit of {text} (time limit; worker ended)"
    if kind == "crashed":
        return f"problem {name}: its factory crashed ({text})"
    return f"problem {name}: its factory raised {text}"


def probe_problem(name: str, calls: list[dict[str, Any]], limit: float | None, pool: Any = None) -> str | None:
    """Build a plug-in problem at ``calls`` (``get_problem`` keyword arguments) in a supervised worker.

    Parameters
    ----------
    name
        The registered problem; a built-in one is not probed.
    calls
        The keyword arguments of each ``get_problem(name, ...)`` the command will make first.
    limit
        Seconds the factory may take for all of them (the command's set-up limit).
    pool
        A :class:`nsbench.workers.jobs.JobPool` to run in (default a new pool of one worker).

    Returns
    -------
    str or None
        ``None`` if every call built (or ``name`` is built-in), else one line naming the
        problem and its fault (a time limit, a crash, an exception).

    Raises
    ------
    ConfigError
        The factory refused a value (a bad parameter: refused input, as without the probe).
    """
    if not is_plugin_problem(name):
        return None
    found = run_probes({name: (f"{__name__}:build_job", (name, calls, limit))}, limit, pool)
    kind, text = found.get(name, ("raised", "no outcome"))
    if kind == "ok":
        return None
    if kind == "refused":
        raise ConfigError(text)
    return failure_line(name, kind, text)


def probe_suite(suite: Any) -> tuple[Any, list[str]]:
    """The suite without its plug-in problem tables whose factory fails, and one line for each left out.

    Each table of a plug-in problem is built in a worker under the suite's ``setup_limit``
    (all cases and grid values of it, as the suite expands them); a table whose factory
    loops, crashes or raises costs only its own rows. A refused value (``ConfigError``) is
    raised, as the suite's own expansion raises it.
    """
    tables = {i: t for i, t in enumerate(suite.problems) if isinstance(t, dict) and is_plugin_problem(t.get("name"))}
    jobs: dict[Hashable, tuple[str, tuple]] = {
        i: (f"{__name__}:suite_table_job", (dataclasses.replace(suite, problems=[t]), suite.setup_limit))
        for i, t in tables.items()
    }
    found = run_probes(jobs, suite.setup_limit)
    lines, dropped = [], set()
    for i, table in tables.items():
        kind, text = found.get(i, ("raised", "no outcome"))
        if kind == "refused":
            raise ConfigError(text)
        if kind != "ok":
            dropped.add(i)
            lines.append(f"{failure_line(table['name'], kind, text)}; its rows (problem table {i + 1}) are left out")
    if not dropped:
        return suite, []
    kept = [t for i, t in enumerate(suite.problems) if i not in dropped]
    return dataclasses.replace(suite, problems=kept), lines
