"""The compiled hybrid loop: arcs, the settle step, stop rules, budgets, for any problem and any kernel.

:func:`hybrid_loop` advances a run held entirely in arrays (the bundles of
:mod:`nsbench.model.abi`), so it can stop and resume at any arc boundary. It
returns to Python only when Python has work to do:

- :data:`R_DONE`: the run is over (``si[SI_STATUS]`` says how);
- :data:`R_GROW_EVENTS`, :data:`R_GROW_HITS`: a record buffer is full (grow it, call again);
- :data:`R_NEED_MODE`: the arc kernel needs data for a mode it has not seen
  (``exact`` builds them lazily; call again);
- :data:`R_RESUME`: an arc run in Python replaced a record buffer (it grew one):
  call again (the loop resumes at ``si[SI_PHASE] = P_ARC_DONE``).

An integrator without a compiled kernel has its arcs run in Python without
leaving the loop: the loop calls back (:func:`nsbench.model.callback.python_arc`),
and Python runs the integrator's ``advance`` and stores the outcome in the arc
slots (``sf[SF_ARC_T]``, ``st.y_arc``, ``si[SI_ARC_STATUS]``, ``si[SI_DETAIL]``).

The problem's law and the integrator's kernel come as address tables
(:mod:`nsbench.model.functions`): this module imports neither, and one compiled
loop serves every problem and every kernel.

After each arc the loop checks the states the integrator returned inside it
(its dense output at the requested times): a guard of the mode seen on its
wrong side and then back on its own side is a crossing the integrator stepped
over, and the run ends with :data:`~nsbench.model.abi.RUN_MISSED` at the time of
the first such state.
"""

from __future__ import annotations

import numpy as np
from numba.extending import overload

from nsbench.model import functions, law
from nsbench.model.callback import ARC_STORED, python_arc
from nsbench.model.abi import (
    arc_signature,
    K_BUDGET,
    K_FAIL,
    K_HIT_FULL,
    K_HIT_STOP,
    K_NEED_MODE,
    K_NONFINITE,
    K_OK,
    NSTEPS,
    RUN_EVENT_BUDGET,
    RUN_FAILURE,
    RUN_MISSED,
    RUN_NONFINITE,
    RUN_STEP_BUDGET,
    RUN_STORM,
    RUN_SUCCESS,
    SF_ARC_T,
    SF_ARC_TLO,
    SF_T,
    SF_TLO,
    SI_ARC_STATUS,
    SI_CLOCK,
    SI_DETAIL,
    SI_IEVAL,
    SI_ARC_IEVAL,
    SI_NG,
    SI_NHITS,
    SI_PHASE,
    SI_RECORDED,
    SI_STATUS,
    SI_STOP_SEEN,
    SI_STOPPED,
    Arc,
)
from nsbench.model.clock import monotonic_ns
from nsbench.model.compile import hot
from nsbench.model.records import copy_into
from nsbench.model.rules import EVENT_BUDGET, STORM, pending_guard, settle, settle_fired

P_INIT, P_TOP, P_ARC_DONE = 0, 1, 2
R_DONE, R_GROW_EVENTS, R_GROW_HITS, R_NEED_MODE, R_RESUME = 0, 1, 2, 3, 4
#: Room the settle step needs in the event buffers beyond the storm ring: the fired event and an accumulation.
EXTRA_EVENTS = 2
_EPS = np.finfo(np.float64).eps

_CALLERS: dict = {}


def _arc_caller(problem_data):
    """The call of an arc kernel at an address, for problems whose data have this type (built once)."""
    if problem_data not in _CALLERS:
        _CALLERS[problem_data] = functions.caller(arc_signature(problem_data))
    return _CALLERS[problem_data]


def arc_at(address, kd, fo, prob, arc, sec, hits, dense, si, y_out, cnt):
    """One arc of the kernel whose direct entry is at ``address`` (compiled code only)."""
    raise NotImplementedError("compiled code only")


@overload(arc_at, inline="always")
def _arc_at(address, kd, fo, prob, arc, sec, hits, dense, si, y_out, cnt):
    call = _arc_caller(prob)
    return lambda address, kd, fo, prob, arc, sec, hits, dense, si, y_out, cnt: call(
        address, (kd, fo, prob, arc, sec, hits, dense, si, y_out, cnt)
    )


@hot
def call_arc(kernel, kd, fo, prob, arc, sec, hits, dense, si, y_out, cnt):
    """One arc of the kernel whose addresses are ``kernel[0:2]`` (its direct entry is the second)."""
    return arc_at(kernel[1], kd, fo, prob, arc, sec, hits, dense, si, y_out, cnt)


@hot
def _finish(si, status):
    si[SI_STATUS] = status
    return R_DONE


@hot
def _finite(t, y):
    """Whether the time and every component of the state an arc run in Python returned are finite."""
    if not np.isfinite(t):
        return False
    for j in range(y.shape[0]):
        if not np.isfinite(y[j]):
            return False
    return True


@hot
def _missed(prob, st, dense, first, last):
    """Whether a guard of the mode is on its wrong side at a state in ``dense.y[first:last]`` and back on its
    own side at a later one (a crossing the arc stepped over); its time goes into ``st.sf[SF_ARC_T]``."""
    mode, gk, gi, gs = st.mode, st.gk, st.gi, st.gs
    ng = st.si[SI_NG]
    for q in range(ng):
        wrong_at = -1.0
        for i in range(first, last):
            y = dense.y[i]
            g = gs[q] * law.guard_value(prob, mode, gk[q], gi[q], dense.t[i], y)
            ymax = 0.0
            for j in range(y.shape[0]):
                ymax = max(ymax, abs(y[j]))
            tol = 64.0 * _EPS * max(1.0, ymax)
            if g < -tol:
                if wrong_at < 0.0:
                    wrong_at = dense.t[i]
            elif g > tol and wrong_at >= 0.0:
                st.sf[SF_ARC_T] = wrong_at
                return True
    return False


@hot
def hybrid_loop(kernel, kd, fo, prob, lim, sec, hits, dense, ev, st):
    """Advance the run held in ``st`` (:class:`~nsbench.model.abi.RunState`) and the record buffers.

    Parameters
    ----------
    kernel, kd, fo
        The arc kernel's address table (empty: arcs run in Python), its data and float options.
    prob
        The problem's data (:func:`nsbench.model.law.data_class`): the loop is compiled once per
        problem family.
    lim
        :class:`~nsbench.model.abi.RunLimits`.
    sec, hits, dense, ev
        Sections and the buffers of section hits, dense states and events.
    """
    si, sf, cnt = st.si, st.sf, st.cnt
    saved = st.iw[: cnt.shape[0]]
    clock = st.iw[cnt.shape[0] :]
    room = st.ring.shape[0] + EXTRA_EVENTS
    if si[SI_PHASE] == P_INIT:
        # At t0 the state may sit on a surface: the rule that follows a transition.
        if ev.t.shape[0] - si[SI_RECORDED] < room:
            return R_GROW_EVENTS
        law.start_fresh(prob, st.mode, sf[SF_T], st.y, st.fresh)
        q = pending_guard(prob, st, sf[SF_T])
        outcome = settle(prob, st, lim, ev, q)
        i = si[SI_IEVAL]
        while i < dense.t.shape[0] and dense.t[i] <= sf[SF_T]:
            copy_into(dense.y[i], st.y)
            i += 1
        si[SI_IEVAL] = i
        si[SI_PHASE] = P_TOP
        if outcome == STORM:
            return _finish(si, RUN_STORM)
        if outcome == EVENT_BUDGET:
            return _finish(si, RUN_EVENT_BUDGET)
    while True:
        if si[SI_PHASE] == P_TOP:
            if lim.stop_count > 0 and si[SI_STOP_SEEN] >= lim.stop_count:
                si[SI_STOPPED] = 1
                return _finish(si, RUN_SUCCESS)
            if sf[SF_T] >= lim.t_end:
                return _finish(si, RUN_SUCCESS)
            if ev.t.shape[0] - si[SI_RECORDED] < room:
                return R_GROW_EVENTS
            ng = law.guards_of(prob, st.mode, st.gk, st.gi, st.gs)
            si[SI_NG] = ng
            si[SI_ARC_IEVAL] = si[SI_IEVAL]  # the first dense state of this arc
            if kernel.shape[0] == 0:
                if python_arc() != ARC_STORED:
                    return R_RESUME
            else:
                copy_into(saved, cnt)
                n_hits, i_eval = si[SI_NHITS], si[SI_IEVAL]
                tic = monotonic_ns(clock)
                arc = Arc(
                    st.mode, st.gk, st.gi, st.gs, ng, sf[SF_T], sf[SF_TLO], st.y, lim.t_end, lim.max_steps - cnt[NSTEPS]
                )
                status, t1, t_lo1, fired = call_arc(kernel, kd, fo, prob, arc, sec, hits, dense, si, st.y_arc, cnt)
                si[SI_CLOCK] += monotonic_ns(clock) - tic
                if status == K_HIT_FULL or status == K_NEED_MODE:
                    copy_into(cnt, saved)  # the arc runs again from its start once Python has done its part
                    si[SI_NHITS], si[SI_IEVAL] = n_hits, i_eval
                    return R_GROW_HITS if status == K_HIT_FULL else R_NEED_MODE
                sf[SF_ARC_T], sf[SF_ARC_TLO] = t1, t_lo1
                si[SI_ARC_STATUS], si[SI_DETAIL] = status, fired
        # ---- the outcome of the arc (compiled, or stored by Python)
        si[SI_PHASE] = P_TOP
        status = si[SI_ARC_STATUS]
        if kernel.shape[0] == 0 and status == K_OK and not _finite(sf[SF_ARC_T], st.y_arc):
            status = si[SI_ARC_STATUS] = K_NONFINITE  # Python checked the arc's shape, not its values
        if status == K_NONFINITE:
            sf[SF_T] = sf[SF_ARC_T]
            return _finish(si, RUN_NONFINITE)
        if status == K_BUDGET or status >= K_FAIL:
            sf[SF_T], sf[SF_TLO] = sf[SF_ARC_T], 0.0
            copy_into(st.y, st.y_arc)
            if status >= K_FAIL:
                si[SI_DETAIL] = status
                return _finish(si, RUN_FAILURE)
            return _finish(si, RUN_STEP_BUDGET)
        if _missed(prob, st, dense, si[SI_ARC_IEVAL], si[SI_IEVAL]):
            sf[SF_T], sf[SF_TLO] = sf[SF_ARC_T], 0.0
            return _finish(si, RUN_MISSED)
        sf[SF_T], sf[SF_TLO] = sf[SF_ARC_T], sf[SF_ARC_TLO]
        copy_into(st.y, st.y_arc)
        if status == K_HIT_STOP:
            si[SI_STOPPED] = 1
            return _finish(si, RUN_SUCCESS)
        fired = si[SI_DETAIL]
        if fired < 0:
            return _finish(si, RUN_SUCCESS)  # reached t_end
        budget_spent = cnt[NSTEPS] >= lim.max_steps
        outcome = settle_fired(prob, st, lim, ev, fired)
        if outcome == STORM:
            return _finish(si, RUN_STORM)
        if outcome == EVENT_BUDGET:
            return _finish(si, RUN_EVENT_BUDGET)
        if budget_spent:
            return _finish(si, RUN_STEP_BUDGET)
