"""A continuation in a supervised worker: the flow's set-up and the whole trace, each under a hard limit.

The flow runs an integrator, a plug-in's possibly: one whose ``setup`` or ``advance``
never returns cannot be stopped inside Python, and one that calls ``os._exit`` ends
its process. ``nsbench continuation`` therefore runs :func:`continuation_job` in a
worker of :mod:`nsbench.workers.jobs`: the flow is built under the set-up limit, the trace
under the time limit, and each branch is sent on (with its section points) as soon
as it is complete, so that a time limit or a crash keeps what was computed before.
"""

from __future__ import annotations

from typing import Any, Callable

from nsbench.errors import NsbenchError

#: The stages the job announces (and a stopped run names).
SETUP_STAGE, TRACE_STAGE = "flow set-up", "continuation"


def continuation_job(
    run: dict[str, Any], setup_limit: float, time_limit: float, *, stage: Callable, emit: Callable
) -> tuple[str, Any]:
    """In a worker: the flow of ``run['integrator']`` on the problem, then :func:`nsbench.periodic.trace`.

    ``run`` holds ``problem``, ``case``, ``params``, ``name``, ``start``, ``stop``,
    ``steps``, ``transient``, ``doubling``, ``origin``, ``integrator`` and ``section``.
    Emits ``('flow', integrator name)``, ``('step', value)`` for each accepted step and
    ``('branches', branches, points, gaps)`` as branches are complete. Returns
    ``('done', gaps)``, or ``('refused', message)`` (bad input: an unknown or refusing
    integrator), ``('no orbit', message)`` (the flow from rest stopped before any orbit
    was sought) or ``('set-up failed', 'Type: message')`` (the plug-in's own fault).
    """
    from nsbench.periodic import HybridFlow, trace
    from nsbench.periodic.continuation import Continuation
    from nsbench.periodic.output import points_frame
    from nsbench.problems import get_problem

    name = run["name"]

    def problem_at(value: float):
        return get_problem(run["problem"], case=run["case"], **{**run["params"], name: float(value)})

    stage(SETUP_STAGE, setup_limit)
    try:
        flow = HybridFlow(problem_at(run["start"]), run["integrator"])
    except NsbenchError as exc:
        return "refused", str(exc)
    except Exception as exc:  # a plug-in's fault in its own set-up: one line for the command
        return "set-up failed", f"{type(exc).__name__}: {exc}"
    emit(("flow", flow.integrator_name))
    stage(TRACE_STAGE, time_limit)
    sent = [0]

    def send(result: Continuation) -> None:
        new = result.branches[sent[0] :]
        sent[0] = len(result.branches)
        part = Continuation(result.param, result.start, result.stop, new)
        emit(("branches", new, points_frame(flow, part, problem_at, run["section"]), list(result.gaps)))

    try:
        result = trace(
            problem_at,
            name,
            run["start"],
            run["stop"],
            steps=run["steps"],
            transient=run["transient"],
            doubling=run["doubling"],
            on_step=lambda value: emit(("step", value)),
            origin=run["origin"],
            flow=flow,
            on_branch=send,
        )
    except NsbenchError as exc:
        return "refused", str(exc)
    except ArithmeticError as exc:  # the flow from rest stopped (a budget) before any orbit was sought
        return "no orbit", str(exc)
    return "done", list(result.gaps)
