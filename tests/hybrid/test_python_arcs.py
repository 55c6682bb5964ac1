"""Arcs run in Python: the requests, the loop's call back, and what crosses it.

``_PythonArcs`` fills each request's fields directly (not through the frozen dataclass's
``__init__``, which costs a few microseconds per arc). Here a real integrator
(``heyoka``) runs 2-DOF case 1 through ``nsbench.simulate`` while its ``advance`` keeps
the requests; each must have every field of the dataclass, equal what the constructor
builds from the same values, and describe the arc the loop was at (the state read-only).

The compiled loop calls Python back for each arc (:mod:`nsbench.model.callback`) through
a per-thread stack of runners: an interrupt inside an arc leaves the run and the stack
clean, a run started inside another run's arc reaches its own runner, runs on two
threads each reach theirs, and a record buffer grown by Python inside an arc is the one
the loop goes on with. Each is compared with the same run made alone.
"""

from __future__ import annotations

import dataclasses
import threading

import numpy as np
import pytest

import nsbench
from nsbench.integrators import get_integrator
from nsbench.integrators.base import ArcRequest
from nsbench.model import callback
from nsbench.sections import StateSection

pytest.importorskip("heyoka")


def test_every_request_is_a_whole_arc_request():
    problem = nsbench.get_problem("two-dof", case=1)
    integ = get_integrator("heyoka", loop="per-arc")  # heyoka's own loop would call no advance
    seen: list[ArcRequest] = []
    advance = integ.advance

    def keep(request):
        seen.append(request)
        return advance(request)

    integ.advance = keep
    res = nsbench.simulate(problem, integ, 40.0, t_eval=np.linspace(0.0, 40.0, 9))
    assert res.ok and len(seen) > 10
    names = [f.name for f in dataclasses.fields(ArcRequest)]
    for k, request in enumerate(seen):
        assert type(request) is ArcRequest
        built = ArcRequest(**{name: getattr(request, name) for name in names})
        assert dataclasses.replace(request).__dict__.keys() == built.__dict__.keys()
        assert request.guards == problem.guards(request.mode)
        assert not request.y0.flags.writeable
        assert request.t_end == 40.0 and request.sections == ()
        assert np.all(request.t_eval > request.t0) or request.t_eval.size == 0
        if k:  # each arc starts where the loop left the last one (the event, or its transition)
            assert request.t0 >= seen[k - 1].t0
        with pytest.raises(dataclasses.FrozenInstanceError):
            request.t0 = 0.0  # type: ignore[misc]


def _same_run(a, b) -> None:
    assert a.status == b.status and a.message == b.message
    assert np.array_equal(a.events.t.to_numpy(), b.events.t.to_numpy())
    assert np.array_equal(a.y_final, b.y_final)
    assert a.trajectory.equals(b.trajectory)


def test_an_interrupt_inside_an_arc_ends_the_run_and_leaves_the_next_one_alone():
    problem = nsbench.get_problem("two-dof", case=1)
    integ = get_integrator("scipy-dop853")
    advance, calls = integ.advance, []

    def interrupted(request):
        calls.append(request.t0)
        if len(calls) == 5:
            raise KeyboardInterrupt
        return advance(request)

    integ.advance = interrupted
    with pytest.raises(KeyboardInterrupt):
        nsbench.simulate(problem, integ, 40.0)
    assert len(calls) == 5 and not getattr(callback._LOCAL, "stack", [])
    del integ.advance
    _same_run(nsbench.simulate(problem, integ, 40.0), nsbench.simulate(problem, get_integrator("scipy-dop853"), 40.0))


def test_a_run_inside_an_arc_reaches_its_own_runner():
    outer_problem = nsbench.get_problem("two-dof", case=1)
    inner_problem = nsbench.get_problem("one-dof", case=1)
    integ = get_integrator("scipy-dop853")
    advance, inner = integ.advance, []

    def nesting(request):
        if len(inner) < 2:  # the first two arcs each run a whole other problem first
            inner.append(nsbench.simulate(inner_problem, get_integrator("scipy-dop853"), 30.0))
        return advance(request)

    integ.advance = nesting
    outer = nsbench.simulate(outer_problem, integ, 40.0)
    alone = nsbench.simulate(outer_problem, get_integrator("scipy-dop853"), 40.0)
    _same_run(outer, alone)
    inner_alone = nsbench.simulate(inner_problem, get_integrator("scipy-dop853"), 30.0)
    assert len(inner) == 2 and len(inner_alone.events) > 3
    for run in inner:
        _same_run(run, inner_alone)


def test_runs_on_two_threads_each_reach_their_own_runner():
    problems = [nsbench.get_problem("two-dof", case=1), nsbench.get_problem("one-dof", case=2)]
    alone = [nsbench.simulate(p, get_integrator("scipy-dop853"), 60.0) for p in problems]
    got: dict[int, list] = {0: [], 1: []}

    def work(k: int) -> None:
        for _ in range(3):
            got[k].append(nsbench.simulate(problems[k], get_integrator("scipy-dop853"), 60.0))

    threads = [threading.Thread(target=work, args=(k,)) for k in (0, 1)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    for k in (0, 1):
        assert len(got[k]) == 3
        for run in got[k]:
            _same_run(run, alone[k])


def test_section_hits_that_grow_the_buffer_inside_an_arc_are_all_kept():
    # v1 = 0 is crossed twice per forcing period: over [0, 600] far more often than the 64
    # hits the buffer starts with, so Python grows it inside arcs and the loop resumes.
    problem = nsbench.get_problem("two-dof", case=1)
    section = StateSection("v1-zero", (0.0, 1.0, 0.0, 0.0))
    assert problem.n_states == len(section.coeffs)
    res = nsbench.simulate(problem, "scipy-dop853", 600.0, sections=[section])
    ref = nsbench.simulate(problem, "exact", 600.0, sections=[section])
    assert res.ok and len(ref.sections) > 64
    assert len(res.sections) == len(ref.sections) and len(res.events) == len(ref.events)
    # every hit is on the section, and off exact's by no more than the run's own event times are
    assert np.max(np.abs(res.sections.v1.to_numpy())) < 1e-12
    hit_error = np.max(np.abs(res.sections.t.to_numpy() - ref.sections.t.to_numpy()))
    event_error = np.max(np.abs(res.events.t.to_numpy() - ref.events.t.to_numpy()))
    assert hit_error <= 10.0 * event_error + 1e-12


def _spoil(field: str):
    """How the third arc's result is spoiled, and the words its message must have."""

    def nan_state(res, request):
        y = res.y.copy()
        y[1] = np.nan
        return dataclasses.replace(res, y=y)

    return {
        "nan-state": (nan_state, "non-finite state"),
        "short-state": (lambda res, request: dataclasses.replace(res, y=res.y[:-1]), "the protocol wants (4,)"),
        "before-the-arc": (
            lambda res, request: dataclasses.replace(res, t=request.t0 - 1.0),
            "outside the arc",
        ),
        "unknown-guard": (lambda res, request: dataclasses.replace(res, fired=len(request.guards)), "reported guard"),
        "no-event": (lambda res, request: dataclasses.replace(res, fired=None), "< t_end without an event"),
        "dense-count": (
            lambda res, request: dataclasses.replace(res, y_eval=np.zeros((request.problem.n_states, 0))),
            "dense states for",
        ),
        "dense-shape": (
            lambda res, request: dataclasses.replace(res, y_eval=np.zeros((2, 1))),
            "the protocol wants (n_states, n_points)",
        ),
        "counters": (lambda res, request: dataclasses.replace(res, nsteps=None), "counters that are not integers"),
    }[field]


@pytest.mark.parametrize(
    "field",
    [
        "nan-state",
        "short-state",
        "before-the-arc",
        "unknown-guard",
        "no-event",
        "dense-count",
        "dense-shape",
        "counters",
    ],
)
def test_a_result_outside_the_protocol_ends_the_run_with_its_reason(field):
    problem = nsbench.get_problem("two-dof", case=1)
    integ = get_integrator("scipy-dop853")
    spoil, words = _spoil(field)
    advance, arcs = integ.advance, []

    def spoiled(request):
        arcs.append(request.t0)
        res = advance(request)
        return spoil(res, request) if len(arcs) == 3 else res

    integ.advance = spoiled
    # a dense time inside every arc, so that the third one has dense states to spoil
    res = nsbench.simulate(problem, integ, 40.0, t_eval=np.linspace(0.0, 40.0, 4001))
    assert res.status is nsbench.Status.INTEGRATOR_FAILURE, (res.status, res.message)
    assert words in res.message
    assert len(arcs) == 3 and len(res.events) == 2
