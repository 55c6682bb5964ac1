"""The compiled hybrid loop: arcs, the settle step, stop rules, budgets, with no Python per event.

:func:`hybrid_loop` advances a run held entirely in arrays (state, mode, records,
counters), so it can stop and resume at any arc boundary. It returns to Python
only when Python has work to do:

- :data:`R_DONE`: the run is over (``si[SI_STATUS]`` says how);
- :data:`R_GROW_EVENTS`, :data:`R_GROW_HITS`: a record buffer is full (grow it, call again);
- :data:`R_NEED_MODE`: the arc kernel needs tables for a mode it has not seen
  (``exact`` builds them lazily; call again);
- :data:`R_NEED_ARC`: the integrator has no compiled kernel: Python runs its
  ``advance`` for the current arc, stores the outcome in the arc slots and calls
  again with ``si[SI_PHASE] = P_ARC_DONE`` (once per arc).

Compiled kernels are dispatched by a method code (:data:`M_EXACT`, ...): a
function argument would make numba compile the loop again in every process,
since its on-disk cache cannot key on function objects. The kernels' data come
in one tuple ``kd = (exact tables, (), picard operators)``; each reads its part.
"""

from __future__ import annotations


from nsbench.hybrid.abi import (
    K_BUDGET,
    K_FAIL,
    K_HIT_FULL,
    K_HIT_STOP,
    K_NEED_MODE,
    K_NONFINITE,
    NSTEPS,
    SI_ARC_STATUS,
    SI_CLOCK,
    SI_DETAIL,
    SI_IEVAL,
    SI_NG,
    SI_NHITS,
    SI_PHASE,
    SI_STATUS,
    SI_STOPPED,
    copy_into,
    hot,
)
from nsbench.hybrid.clock import monotonic_ns
from nsbench.hybrid.rules import (
    EVENT_BUDGET,
    SI_RECORDED,
    SI_STOP_SEEN,
    STORM,
    guards_of,
    pending_guard,
    settle,
    start_fresh,
)
from nsbench.integrators._exact_kernel import exact_arc
from nsbench.integrators._henon_kernel import henon_arc
from nsbench.integrators._picard_arc import picard_arc

#: Kernel codes; :func:`arc` runs one arc of a compiled kernel (also the ``advance`` of kernel integrators).
M_PYTHON, M_EXACT, M_HENON, M_PICARD = 0, 1, 2, 3
P_INIT, P_TOP, P_ARC_DONE = 0, 1, 2
R_DONE, R_GROW_EVENTS, R_GROW_HITS, R_NEED_MODE, R_NEED_ARC = 0, 1, 2, 3, 4
RUN_SUCCESS, RUN_STEP_BUDGET, RUN_EVENT_BUDGET, RUN_STORM, RUN_NONFINITE, RUN_FAILURE = 0, 1, 2, 3, 4, 5
# float state
SF_T, SF_TLO, SF_ARC_T, SF_ARC_TLO = 0, 1, 2, 3
N_SF = 4


@hot
def arc(method, kd, fo, p, mode, gk, gb, gs, ng, t, t_lo, y, t_end, max_steps, sc, sl, sd, hit_from,
         hit_stop, hk, ht, hy, si, t_eval, y_eval, y_out, cnt):
    if method == M_EXACT:
        return exact_arc(kd[0], fo, p, mode, gk, gb, gs, ng, t, t_lo, y, t_end, max_steps, sc, sl, sd,
                         hit_from, hit_stop, hk, ht, hy, si, t_eval, y_eval, y_out, cnt)
    if method == M_HENON:
        return henon_arc(kd[1], fo, p, mode, gk, gb, gs, ng, t, t_lo, y, t_end, max_steps, sc, sl, sd,
                         hit_from, hit_stop, hk, ht, hy, si, t_eval, y_eval, y_out, cnt)
    return picard_arc(kd[2], fo, p, mode, gk, gb, gs, ng, t, t_lo, y, t_end, max_steps, sc, sl, sd,
                      hit_from, hit_stop, hk, ht, hy, si, t_eval, y_eval, y_out, cnt)


@hot
def _finish(si, status):
    si[SI_STATUS] = status
    return R_DONE


@hot
def hybrid_loop(method, kd, fo, p, t_end, max_steps, max_events, zeno_span, sc, sl, sd, hit_from, hit_stop,
                hk, ht, hy, t_eval, y_eval, record_from, stop_kind, stop_count, ev_t, ev_kind, ev_block, ev_y,
                ev_mode, y, mode, fresh, gk, gb, gs, ring, sf, si, cnt, y_arc, dy, iw):
    """Advance the run held in ``y, mode, fresh, sf, si, cnt`` and the record buffers; see the module docstring.

    Parameters
    ----------
    method, kd, fo
        Kernel (``M_*``), its data and float options.
    t_end, max_steps, max_events, zeno_span
        End of the run and its budgets; ``ring.size + 1`` events within ``zeno_span`` are a storm.
    sc, sl, sd, hit_from, hit_stop
        Linear sections; hits at ``t >= hit_from`` are stored; the run stops when
        ``hit_stop`` hits are stored (``-1``: never).
    t_eval, y_eval
        Requested times and their states (rows).
    record_from, stop_kind, stop_count
        Events at ``t >= record_from`` are stored; the run stops after ``stop_count``
        of them of kind ``stop_kind`` (``stop_count = 0``: never).
    dy, iw
        Scratch: a state's derivative; counters saved before an arc (restored if it must
        run again) followed by two slots for the clock.
    """
    saved = iw[: cnt.shape[0]]
    clock = iw[cnt.shape[0]:]
    phase = si[SI_PHASE]
    if phase == P_INIT:
        # At t0 the state may sit on a surface: the rule that follows a transition.
        if ev_t.shape[0] - si[SI_RECORDED] < ring.shape[0] + 1:
            return R_GROW_EVENTS
        start_fresh(p, mode, y, fresh)
        q = pending_guard(p, mode, sf[SF_T], y, fresh, gk, gb, gs, dy)
        outcome = settle(p, mode, sf[SF_T], y, q, fresh, gk, gb, gs, dy, ring, zeno_span, max_events,
                         record_from, stop_kind, ev_t, ev_kind, ev_block, ev_y, ev_mode, si)
        i = si[SI_IEVAL]
        while i < t_eval.shape[0] and t_eval[i] <= sf[SF_T]:
            copy_into(y_eval[i], y)
            i += 1
        si[SI_IEVAL] = i
        si[SI_PHASE] = P_TOP
        if outcome == STORM:
            return _finish(si, RUN_STORM)
        if outcome == EVENT_BUDGET:
            return _finish(si, RUN_EVENT_BUDGET)
    while True:
        if si[SI_PHASE] == P_TOP:
            if stop_count > 0 and si[SI_STOP_SEEN] >= stop_count:
                si[SI_STOPPED] = 1
                return _finish(si, RUN_SUCCESS)
            if sf[SF_T] >= t_end:
                return _finish(si, RUN_SUCCESS)
            if ev_t.shape[0] - si[SI_RECORDED] < ring.shape[0] + 1:
                return R_GROW_EVENTS
            ng = guards_of(mode, gk, gb, gs)
            si[SI_NG] = ng
            if method == M_PYTHON:
                return R_NEED_ARC
            copy_into(saved, cnt)
            n_hits, i_eval = si[SI_NHITS], si[SI_IEVAL]
            tic = monotonic_ns(clock)
            status, t1, t_lo1, fired = arc(method, kd, fo, p, mode, gk, gb, gs, ng, sf[SF_T], sf[SF_TLO], y,
                                            t_end, max_steps - cnt[NSTEPS], sc, sl, sd, hit_from, hit_stop,
                                            hk, ht, hy, si, t_eval, y_eval, y_arc, cnt)
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
        if status == K_NONFINITE:
            sf[SF_T] = sf[SF_ARC_T]
            return _finish(si, RUN_NONFINITE)
        if status == K_BUDGET or status >= K_FAIL:
            sf[SF_T], sf[SF_TLO] = sf[SF_ARC_T], 0.0
            copy_into(y, y_arc)
            if status >= K_FAIL:
                si[SI_DETAIL] = status
                return _finish(si, RUN_FAILURE)
            return _finish(si, RUN_STEP_BUDGET)
        sf[SF_T], sf[SF_TLO] = sf[SF_ARC_T], sf[SF_ARC_TLO]
        copy_into(y, y_arc)
        if status == K_HIT_STOP:
            si[SI_STOPPED] = 1
            return _finish(si, RUN_SUCCESS)
        fired = si[SI_DETAIL]
        if fired < 0:
            return _finish(si, RUN_SUCCESS)  # reached t_end
        budget_spent = cnt[NSTEPS] >= max_steps
        for i in range(fresh.shape[0]):
            fresh[i] = False
        guards_of(mode, gk, gb, gs)
        outcome = settle(p, mode, sf[SF_T], y, fired, fresh, gk, gb, gs, dy, ring, zeno_span, max_events,
                         record_from, stop_kind, ev_t, ev_kind, ev_block, ev_y, ev_mode, si)
        if outcome == STORM:
            return _finish(si, RUN_STORM)
        if outcome == EVENT_BUDGET:
            return _finish(si, RUN_EVENT_BUDGET)
        if budget_spent:
            return _finish(si, RUN_STEP_BUDGET)
