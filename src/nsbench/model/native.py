"""The core's steps for an integrator that runs the event loop itself (a *native* run), compiled.

:func:`nsbench.model.loop.hybrid_loop` owns the loop and calls an integrator once per arc.
An integrator with a whole-run path (:meth:`nsbench.integrators.base.Integrator.run`)
owns the loop instead and calls these steps, which do what ``hybrid_loop`` does
between arcs, with the same rules (:mod:`nsbench.model.rules`) on the same
bundles (:class:`~nsbench.model.abi.RunState`, the record buffers of
:mod:`nsbench.model.records`), so the run leaves exactly what ``hybrid_loop``
would have left and :func:`nsbench.hybrid.run.run_hybrid` reads it the same way:

- :func:`begin`: the start (the rule that follows a transition, at ``t0``);
  the core calls it before it hands the run over;
- :func:`event`: an arc ended at a guard's crossing: the missed-crossing check
  over the arc's dense states, the transition and every guard that fires at
  once (:func:`~nsbench.model.rules.settle`: the law's ``transition``, pending
  guards, storms, the event budget, the Zeno rule), the stop rule;
- :func:`hit`: a section crossing (kept from ``hit_from`` on; the run ends at
  the ``hit_stop``-th);
- :func:`dense_row`: a state at the next requested time;
- :func:`arrive`, :func:`fail`: the run reached ``t_end``, or the integrator
  stopped (its step budget, a non-finite state, a failure of its own);
- :func:`missed_over`: the missed-crossing check for an integrator that gets its
  dense states only after a stretch of several arcs (it keeps the modes of
  those arcs).

Each returns :data:`GO_ON` (the integrator continues in ``st.mode`` from ``st.y``
at ``st.sf[SF_T]``), a need (:data:`NEED_EVENTS`, :data:`NEED_HITS`: grow the
buffer with :class:`~nsbench.model.records.Records`, then make the same call
again; nothing was applied), or the run's outcome: a ``RUN_*`` code of
:mod:`~nsbench.model.abi`, also in ``st.si[SI_STATUS]``, after which the run is over.

An integrator whose loop is in Python (heyoka's event callbacks) reaches these
through :class:`Views`: one int64 table of the addresses and shapes of the run's
arrays, from which compiled code rebuilds the bundles (:func:`run_state`, ...)
without unboxing forty arrays per call. Those views are made and returned by functions compiled with
numba's reference counting (``jit``: a function compiled without it may return only an array it was
given); the core's steps above take them as arguments.
"""

from __future__ import annotations

import numpy as np
from llvmlite import ir
from numba import carray, types
from numba.extending import intrinsic

from nsbench.model import law
from nsbench.model.abi import (
    NSTEPS,
    RUN_EVENT_BUDGET,
    RUN_FAILURE,
    RUN_MISSED,
    RUN_NONFINITE,
    RUN_STEP_BUDGET,
    RUN_STORM,
    RUN_SUCCESS,
    SF_ARC_T,
    SF_T,
    SF_TLO,
    SI_ARC_IEVAL,
    SI_DETAIL,
    SI_IEVAL,
    SI_NG,
    SI_NHITS,
    SI_PHASE,
    SI_RECORDED,
    SI_STATUS,
    SI_STOP_SEEN,
    SI_STOPPED,
    Dense,
    Events,
    Hits,
    RunLimits,
    RunState,
    Sections,
)
from nsbench.model.compile import hot, inline, jit
from nsbench.model.loop import EXTRA_EVENTS, P_TOP, _missed
from nsbench.model.records import copy_into
from nsbench.model.rules import EVENT_BUDGET, STORM, pending_guard, settle, settle_fired

#: The integrator goes on (in ``st.mode``, from ``st.y`` at ``st.sf[SF_T] + st.sf[SF_TLO]``).
GO_ON = -1
#: The event buffers have no room for a settle step: grow them (``Records.grow_events``), then call again.
NEED_EVENTS = -2
#: The section-hit buffer is full: grow it (``Records.grow_hits``), then call again.
NEED_HITS = -3


@hot
def _finish(st, status):
    st.si[SI_STATUS] = status
    return status


@hot
def _top(prob, lim, st):
    """What ``hybrid_loop`` checks before each arc: the stop rule and ``t_end``; the guards of the mode."""
    si = st.si
    if lim.stop_count > 0 and si[SI_STOP_SEEN] >= lim.stop_count:
        si[SI_STOPPED] = 1
        return _finish(st, RUN_SUCCESS)
    if st.sf[SF_T] >= lim.t_end:
        return _finish(st, RUN_SUCCESS)
    si[SI_NG] = law.guards_of(prob, st.mode, st.gk, st.gi, st.gs)
    si[SI_ARC_IEVAL] = si[SI_IEVAL]  # the first dense state of the next arc
    return GO_ON


@hot
def begin(prob, lim, dense, ev, st):
    """The start of a run at ``st.sf[SF_T]`` from ``st.y`` in ``st.mode``: ``hybrid_loop``'s first phase.

    A state may start on a surface: the rule that follows a transition (guards already on
    their wrong side fire at once). States requested at or before the start are the
    settled start state.
    """
    si, sf = st.si, st.sf
    if ev.t.shape[0] - si[SI_RECORDED] < st.ring.shape[0] + EXTRA_EVENTS:
        return NEED_EVENTS
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
        return _finish(st, RUN_STORM)
    if outcome == EVENT_BUDGET:
        return _finish(st, RUN_EVENT_BUDGET)
    return _top(prob, lim, st)


@hot
def guard_at(st, kind, index):
    """Index into the guards of ``st.mode`` of the guard ``(kind, index)``, or -1 if the mode has none such."""
    for q in range(st.si[SI_NG]):
        if st.gk[q] == kind and st.gi[q] == index:
            return q
    return -1


@hot
def event(prob, lim, dense, ev, st, fired, t, t_lo, y):
    """The arc in ``st.mode`` ended at guard ``fired`` (an index into ``st.gk, st.gi, st.gs``) at
    ``(t + t_lo, y)``, ``y`` the state *before* the transition: ``hybrid_loop``'s step between two arcs.

    The dense states the integrator stored during the arc (``dense.y[si[SI_ARC_IEVAL]:si[SI_IEVAL]]``)
    are checked for a crossing it stepped over (:data:`~nsbench.model.abi.RUN_MISSED`); then the
    transition and the guards that follow at once are applied (:func:`~nsbench.model.rules.settle_fired`),
    recorded, and checked for storms, the event budget and the stop rule. Afterwards ``st.mode``,
    ``st.y``, ``st.sf[SF_T]`` (an accumulation moves it forward) and the guards of the new mode
    (``st.gk, st.gi, st.gs``, ``si[SI_NG]``) are where the integrator goes on.
    """
    si, sf = st.si, st.sf
    if ev.t.shape[0] - si[SI_RECORDED] < st.ring.shape[0] + EXTRA_EVENTS:
        return NEED_EVENTS
    if _missed(prob, st, dense, si[SI_ARC_IEVAL], si[SI_IEVAL]):
        sf[SF_T], sf[SF_TLO] = sf[SF_ARC_T], 0.0
        return _finish(st, RUN_MISSED)
    sf[SF_T], sf[SF_TLO] = t, t_lo
    copy_into(st.y, y)
    budget_spent = st.cnt[NSTEPS] >= lim.max_steps
    outcome = settle_fired(prob, st, lim, ev, fired)
    if outcome == STORM:
        return _finish(st, RUN_STORM)
    if outcome == EVENT_BUDGET:
        return _finish(st, RUN_EVENT_BUDGET)
    if budget_spent:
        return _finish(st, RUN_STEP_BUDGET)
    return _top(prob, lim, st)


@hot
def hit(sec, hits, dense, st, k, t, y):
    """A crossing of section ``k`` (in its direction) at ``(t, y)``: kept if ``t >= sec.hit_from``.

    Returns :data:`GO_ON`, :data:`NEED_HITS`, or ``RUN_SUCCESS`` when it is the ``hit_stop``-th kept
    hit: the run then ends there, as the per-arc path's does (the state and time of the hit;
    the dense states up to it must already be stored).
    """
    si = st.si
    if t < sec.hit_from:
        return GO_ON
    j = si[SI_NHITS]
    if j >= hits.t.shape[0]:
        return NEED_HITS
    hits.index[j] = k
    hits.t[j] = t
    for i in range(y.shape[0]):
        hits.y[j, i] = y[i]
    si[SI_NHITS] = j + 1
    if 0 <= sec.hit_stop <= j + 1:
        st.sf[SF_T], st.sf[SF_TLO] = t, 0.0
        copy_into(st.y, y)
        si[SI_STOPPED] = 1
        return _finish(st, RUN_SUCCESS)
    return GO_ON


@inline
def dense_row(dense, st, y):
    """Store ``y`` as the state at the next requested time ``dense.t[st.si[SI_IEVAL]]``."""
    i = st.si[SI_IEVAL]
    copy_into(dense.y[i], y)
    st.si[SI_IEVAL] = i + 1


@hot
def arrive(prob, dense, st, t, t_lo, y):
    """The run reached its end ``t`` (no guard fired after the last event): ``RUN_SUCCESS``, or
    ``RUN_MISSED`` if the last arc's dense states show a crossing the integrator stepped over."""
    si, sf = st.si, st.sf
    if _missed(prob, st, dense, si[SI_ARC_IEVAL], si[SI_IEVAL]):
        sf[SF_T], sf[SF_TLO] = sf[SF_ARC_T], 0.0
        return _finish(st, RUN_MISSED)
    sf[SF_T], sf[SF_TLO] = t, t_lo
    copy_into(st.y, y)
    return _finish(st, RUN_SUCCESS)


@hot
def fail(st, status, t, y, detail):
    """The integrator stopped at ``(t, y)``: ``status`` ``RUN_STEP_BUDGET``, ``RUN_NONFINITE`` (``y`` is
    not kept: it is not finite) or ``RUN_FAILURE`` (``detail``: the integrator's failure code,
    ``abi.K_FAIL`` or more, or its own code that the run's message explains)."""
    st.sf[SF_T], st.sf[SF_TLO] = t, 0.0
    if status != RUN_NONFINITE:
        copy_into(st.y, y)
    if status == RUN_FAILURE:
        st.si[SI_DETAIL] = detail
    return _finish(st, status)


@hot
def missed_over(prob, scratch, dense, mode, first, last):
    """The time of the first state of ``dense.y[first:last]`` at which a guard of ``mode`` is on its
    wrong side and back on its own side later (the core's missed-crossing check), or NaN.

    For an integrator that stores a stretch of several arcs' dense states at once: it calls this
    per arc with the arc's mode. ``scratch`` is a :class:`~nsbench.model.abi.RunState` of its own
    (its mode and guard slots are overwritten), not the run's.
    """
    copy_into(scratch.mode, mode)
    scratch.si[SI_NG] = law.guards_of(prob, scratch.mode, scratch.gk, scratch.gi, scratch.gs)
    if _missed(prob, scratch, dense, first, last):
        return scratch.sf[SF_ARC_T]
    return np.nan


# ---------------------------------------------------------------------- the run's arrays by address
@intrinsic
def _pointer(typingctx, address):
    """The integer ``address`` as a ``void*`` (for :func:`numba.carray`)."""
    sig = types.voidptr(types.int64)

    def codegen(context, builder, signature, args):
        return builder.inttoptr(args[0], ir.IntType(8).as_pointer())

    return sig, codegen


@jit
def f1(table, k):
    """The float64 1-d array of slot ``k`` of a :class:`Views` table."""
    return carray(_pointer(table[k, 0]), (table[k, 1],), np.float64)


@jit
def f2(table, k):
    return carray(_pointer(table[k, 0]), (table[k, 1], table[k, 2]), np.float64)


@jit
def i1(table, k):
    return carray(_pointer(table[k, 0]), (table[k, 1],), np.int64)


@jit
def i2(table, k):
    return carray(_pointer(table[k, 0]), (table[k, 1], table[k, 2]), np.int64)


@jit
def b1(table, k):
    return carray(_pointer(table[k, 0]), (table[k, 1],), np.bool_)


#: Slots of a :class:`Views` table: the run state's 14 arrays, then the events' 6 (with the accumulation
#: error estimates), the dense states' 2, the hits' 3, the sections' 3 arrays, and the limits with the
#: sections' ``hit_from``, ``hit_stop`` (float and integer halves: the accumulation tolerance is a float).
S_STATE, S_EVENTS, S_DENSE, S_HITS, S_SECTIONS, S_LIMITS_F, S_LIMITS_I = 0, 14, 20, 22, 25, 28, 29
#: The first slot an integrator may use for arrays of its own.
S_OWN = 30


@jit
def run_state(table):
    """The run's :class:`~nsbench.model.abi.RunState` from a :class:`Views` table."""
    k = S_STATE
    return RunState(
        f1(table, k),
        i1(table, k + 1),
        b1(table, k + 2),
        i1(table, k + 3),
        i1(table, k + 4),
        i1(table, k + 5),
        f1(table, k + 6),
        f1(table, k + 7),
        f1(table, k + 8),
        i1(table, k + 9),
        i1(table, k + 10),
        f1(table, k + 11),
        f1(table, k + 12),
        i1(table, k + 13),
    )


@jit
def events(table):
    k = S_EVENTS
    return Events(
        f1(table, k), i1(table, k + 1), i1(table, k + 2), f2(table, k + 3), i2(table, k + 4), f1(table, k + 5)
    )


@jit
def dense_states(table):
    return Dense(f1(table, S_DENSE), f2(table, S_DENSE + 1))


@jit
def hit_buffer(table):
    k = S_HITS
    return Hits(i1(table, k), f1(table, k + 1), f2(table, k + 2))


@jit
def limits(table):
    lf, li = f1(table, S_LIMITS_F), i1(table, S_LIMITS_I)
    return RunLimits(lf[0], li[0], li[1], lf[1], lf[2], li[2], li[3], lf[4])


@jit
def sections(table):
    lf, li = f1(table, S_LIMITS_F), i1(table, S_LIMITS_I)
    k = S_SECTIONS
    return Sections(f2(table, k), f1(table, k + 1), i1(table, k + 2), lf[3], li[4])


@hot
def _put1(table, k, a):
    table[k, 0], table[k, 1], table[k, 2] = a.ctypes.data, a.shape[0], 0


@hot
def _put2(table, k, a):
    table[k, 0], table[k, 1], table[k, 2] = a.ctypes.data, a.shape[0], a.shape[1]


@hot
def _fill_core(table, st, ev, dense, hits, coeffs, levels, directions, lf, li):
    """The core's slots of a :class:`Views` table (``S_STATE`` to ``S_LIMITS_I``), in one compiled call: the
    bundles unboxed once here cost a few microseconds, where forty ``ndarray.ctypes.data`` reads in Python
    cost about 65 (a native run's fixed cost, paid again on every run of a sweep). One call per slot, written
    out: the bundles' arrays differ in type, so numba cannot index them in a loop."""
    k = S_STATE
    _put1(table, k, st.y)
    _put1(table, k + 1, st.mode)
    _put1(table, k + 2, st.fresh)
    _put1(table, k + 3, st.gk)
    _put1(table, k + 4, st.gi)
    _put1(table, k + 5, st.gs)
    _put1(table, k + 6, st.ring)
    _put1(table, k + 7, st.acc)
    _put1(table, k + 8, st.sf)
    _put1(table, k + 9, st.si)
    _put1(table, k + 10, st.cnt)
    _put1(table, k + 11, st.y_arc)
    _put1(table, k + 12, st.dy)
    _put1(table, k + 13, st.iw)
    k = S_EVENTS
    _put1(table, k, ev[0])
    _put1(table, k + 1, ev[1])
    _put1(table, k + 2, ev[2])
    _put2(table, k + 3, ev[3])
    _put2(table, k + 4, ev[4])
    _put1(table, k + 5, ev[5])
    _put1(table, S_DENSE, dense[0])
    _put2(table, S_DENSE + 1, dense[1])
    _put1(table, S_HITS, hits[0])
    _put1(table, S_HITS + 1, hits[1])
    _put2(table, S_HITS + 2, hits[2])
    _put2(table, S_SECTIONS, coeffs)
    _put1(table, S_SECTIONS + 1, levels)
    _put1(table, S_SECTIONS + 2, directions)
    _put1(table, S_LIMITS_F, lf)
    _put1(table, S_LIMITS_I, li)


class Views:
    """An int64 table ``(address, rows, columns)`` of a native run's arrays, for compiled code to rebuild
    the run's bundles from (:func:`run_state`, :func:`events`, ...; slots ``S_*``), and the arrays
    themselves, kept alive here while the table is in use.

    ``own``: the integrator's arrays, from slot :data:`S_OWN` on. :meth:`refresh` writes the table
    again after a record buffer was replaced (grown).
    """

    def __init__(self, records, state, section_bundle, lim, own=()) -> None:
        self.records, self.state, self.sec = records, state, section_bundle
        self._lf = np.array(
            [lim.t_end, lim.zeno_span, lim.record_from, section_bundle.hit_from, lim.accumulation], dtype=np.float64
        )
        self._li = np.array(
            [lim.max_steps, lim.max_events, lim.stop_kind, lim.stop_count, section_bundle.hit_stop], dtype=np.int64
        )
        self.own = list(own)
        self.table = np.zeros((S_OWN + len(self.own), 3), np.int64)
        self.refresh()

    def arrays(self) -> list[np.ndarray]:
        rec, sec = self.records, self.sec
        return [
            *self.state,
            *rec.events,
            *rec.dense,
            *rec.hits,
            sec.coeffs,
            sec.levels,
            sec.directions,
            self._lf,
            self._li,
            *self.own,
        ]

    def refresh(self) -> None:
        """Write the addresses and shapes of every array into the table (after a buffer was grown)."""
        self._kept = kept = self.arrays()
        for k, a in enumerate(kept):
            if not a.flags.c_contiguous:
                raise ValueError(f"native run: array of slot {k} is not C-contiguous")
        rec = self.records
        _fill_core(self.table, self.state, rec.events, rec.dense, rec.hits, *kept[S_SECTIONS:S_OWN])
        for k in range(S_OWN, len(kept)):
            a = kept[k]
            shape = a.shape + (0,) * (2 - a.ndim)
            self.table[k] = (a.ctypes.data, shape[0], shape[1])
