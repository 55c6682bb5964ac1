"""The kit on a plug-in integrator in supervised workers: one job per check, each under a hard limit.

A plug-in's ``setup`` or ``advance`` that never returns cannot be stopped inside
Python, and one that calls ``os._exit`` ends the process it runs in: run in the
command's own process, either left ``nsbench check`` hanging or ended without a
verdict. Here the first-call measurement and then each check are jobs of
:class:`nsbench.workers.jobs.JobPool` (one worker, so the checks run one after another as in
process and the first call is the worker's first use of the integrator). Each job
announces its set-up under ``setup_limit`` and its check under ``time_limit``; a job
past its limit or whose worker dies is a *failed* check with that reason
(``time limit (2 s) in check protocol``, ``crashed (exit code 3) in first call``),
the worker is replaced and the next check runs: one hang costs one check.
"""

from __future__ import annotations

import time
from typing import Any, Callable

from nsbench.integrators.base import Integrator
from nsbench.testing._checks import CHECKS, Check, checking_on, checking_with
from nsbench.testing._kit import FAILED, CheckResult, run_check
from nsbench.status import OutcomeKind

#: The stages a job announces (and a failure names).
SETUP_STAGE, FIRST_CALL_STAGE = "integrator set-up", "first call"

#: The configuration the worker has set up (``repr`` of its config), so that each check's job
#: sets it up once per worker, not once per check.
_SET_UP: dict[str, str] = {}


def is_plugin(integ: Integrator) -> bool:
    """Whether ``integ``'s class lives outside ``nsbench.`` (a plug-in's: run it in supervised workers)."""
    module = type(integ).__module__ or ""
    return not (module == "nsbench" or module.startswith("nsbench."))


def _stage_of(stage: Callable[[str, float | None], None], setup_limit: float, time_limit: float):
    return lambda what: stage(what, setup_limit if what == SETUP_STAGE else time_limit)


def first_call_job(
    config: dict[str, Any],
    problem: dict[str, Any],
    given: dict[str, Any],
    setup_limit: float,
    time_limit: float,
    *,
    stage: Callable,
    emit: Callable,
):
    """In a worker: :func:`~nsbench.testing.first_call_cost` (its set-up and calls each under its limit)."""
    from nsbench.integrators import integrator_from_config
    from nsbench.testing._first_call import first_call_cost

    stage(SETUP_STAGE, setup_limit)
    integ = integrator_from_config(config)
    cost = first_call_cost(integ, problem, given, stage=_stage_of(stage, setup_limit, time_limit))
    _SET_UP["key"] = repr(config)
    return cost


def check_job(
    config: dict[str, Any],
    given: dict[str, Any],
    check: str,
    problem: dict[str, Any],
    setup_limit: float,
    time_limit: float,
    *,
    stage: Callable,
    emit: Callable,
) -> CheckResult:
    """In a worker: check ``check`` (a name of :data:`CHECKS`) on the integrator of ``config``.

    The integrator is set up once per worker first (on the kit's case 2) under
    ``setup_limit``, so that a set-up that loops is named as such, and a check's
    limit is not spent compiling; the check itself runs under ``time_limit``. A check
    that does not run the integrator skips that set-up.
    """
    from nsbench.integrators import integrator_from_config
    from nsbench.testing._checks import _problem

    found = {c.name: c for c in CHECKS}[check]
    integ = integrator_from_config(config)
    with checking_on(problem), checking_with(given):
        # a check that does not run the integrator (a skipped one, config-round-trip) needs no set-up
        runs = found.runs and found.skip_reason(type(integ).capabilities) is None
        if runs and _SET_UP.get("key") != repr(config):
            stage(SETUP_STAGE, setup_limit)
            try:
                integ.setup(_problem(2))
            except Exception:  # the check's own run reports it, with the kit's words
                pass
            _SET_UP["key"] = repr(config)
    stage(f"check {check}", time_limit)
    return run_check(integ, found, problem, given)


def supervised_checks(
    integ: Integrator,
    given: dict[str, Any],
    checks: list[Check],
    problem: dict[str, Any],
    time_limit: float,
    setup_limit: float,
) -> tuple[Any, list[CheckResult]]:
    """The first call's cost and each check of ``checks`` on ``integ``, in supervised workers.

    Returns
    -------
    first, results
        The :class:`~nsbench.testing.FirstCall`, or a one-line reason it was not measured;
        and one :class:`~nsbench.testing.CheckResult` per check, in order.
    """
    from nsbench.workers.jobs import Job, JobPool

    config = integ.config()
    module = __name__
    with JobPool(1) as pool:
        pool.submit(Job("first call", f"{module}:first_call_job", (config, problem, given, setup_limit, time_limit)))
        first: Any = None
        for o in pool.outcomes():
            first = o.value if o.kind is OutcomeKind.DONE else _reason(o, setup_limit, time_limit)
        # a set-up that hung or crashed would do so again in every check that runs the integrator (at the
        # set-up limit each, half an hour by default): those fail at once with its reason, the others still run
        setup_fault = first if isinstance(first, str) and first.endswith(f"in {SETUP_STAGE}") else None
        results: dict[str, CheckResult] = {}
        caps = type(integ).capabilities
        with checking_on(problem):
            for check in checks:
                if setup_fault and check.runs and check.skip_reason(caps) is None:
                    note = f"not run: the integrator's set-up failed before the checks ({setup_fault})"
                    results[check.name] = CheckResult(type(integ).name, check.name, FAILED, note, 0.0, check.runs)
                else:
                    args = (config, given, check.name, problem, setup_limit, time_limit)
                    pool.submit(Job(check.name, f"{module}:check_job", args))
        tic = time.monotonic()
        for o in pool.outcomes():
            name = str(o.key)
            if o.kind is OutcomeKind.DONE:
                results[name] = o.value
            elif o.final:
                runs = next(c.runs for c in checks if c.name == name)
                reason = _reason(o, setup_limit, time_limit)
                results[name] = CheckResult(type(integ).name, name, FAILED, reason, time.monotonic() - tic, runs)
            tic = time.monotonic()  # one worker: the next check starts now
    return first, [results[c.name] for c in checks]


def _reason(o: Any, setup_limit: float, time_limit: float) -> str:
    """A job's end other than ``done`` in one line: ``time limit (2 s) in check protocol``,
    ``crashed (exit code 3) in first call``, or the exception of a job that raised."""
    stage = o.stage or "worker start"
    if o.kind is OutcomeKind.TIME_LIMIT:
        limit = setup_limit if stage == SETUP_STAGE else time_limit
        return f"time limit ({limit:g} s) in {stage}"
    if o.kind is OutcomeKind.CRASHED:
        head, sep, rest = o.reason.partition("(")
        return f"crashed ({rest.split(')')[0] if sep else o.reason}) in {stage}"
    return f"{o.reason} (in {stage})"
