"""heyoka's batch mode running several whole hybrid runs at once, one per SIMD lane (a sweep's values).

The batch form of :mod:`nsbench.integrators._heyoka_native` (read its docstring first): one
``taylor_adaptive_batch`` per structure, lanes are runs of problems that share the structure
and differ in their runtime parameters (coefficients such as ``v0`` or the forcing), each
lane with its own run state, record buffers and :class:`~nsbench.model.native.Views` table.
The field, the guards and the sections are the scalar native model's
(:func:`nsbench.integrators._heyoka_model.system`), so the rules and the nudge of the guards
are the same; the terminal-event callbacks of a batch receive the lane (heyoka moves that
lane's time and state to the crossing before the call) and make one compiled call on that
lane's table, which reads the lane's column of heyoka's state and time arrays by address.

Only a callback that returns ``False`` stops a batch propagation, and it stops every lane. A
callback goes on (``True``) while its lane's run goes on; it stops when the core ended the
lane's run (the event budget, a storm, the Zeno rule, the stop rule, the ``hit_stop``-th
hit, a missed crossing) or when Python must act (grow a record buffer, a jump of the time by
an accumulation). Python then *freezes* a finished lane: its guards, sections and sampling
event are switched off in its parameters and its end time is its current time, so heyoka
takes no more steps in it (a lane whose time is at its end stays there), and the other
lanes go on in the next propagation. Lanes beyond the runs are frozen copies of the first.

The states at the requested times (``t_eval`` and check points) are a terminal event of
their own per lane, ``t - p``, whose parameter ``p`` is the lane's next requested time: its
callback stores the lane's state there (heyoka's state at the located time) and moves ``p``
to the next time. The states are stored as the run goes, so the core's own missed-crossing
check of an arc (in :func:`nsbench.model.native.event`) sees them, and no arc log is kept
(the scalar path gets its grid only after a stretch of arcs).

Double precision only (numba has no wider type; long double and quad run value by value).
"""

from __future__ import annotations

import copy
import math
import threading
import time
from typing import Any, Sequence

import heyoka as hy
import numba
import numpy as np
from numba import types

from nsbench.integrators import _heyoka_model as model
from nsbench.integrators import _heyoka_native as scalar
from nsbench.integrators._heyoka_native import C_CODE, C_EVENT, JUMPED, BAD_EVENT, BAD_MODE, NUDGE
from nsbench.integrators._heyoka_native import S_CTL, S_DPARS, S_HSTATE, S_PARS
from nsbench.integrators.base import RunReport, RunRequest
from nsbench.model import abi, native
from nsbench.model.abi import SF_T, SF_TLO, SI_ARC_IEVAL, SI_IEVAL
from nsbench.model.compile import jit
from nsbench.model.records import copy_into

_SLOTS = len(model.GUARD_SLOT)
#: Slots of a lane's table after the scalar run's (:data:`~nsbench.integrators._heyoka_native.S_MODES`):
#: the lane's facts (:data:`B_LANE` ...), heyoka's times (high and low parts, one per lane).
S_LANE, S_TIME, S_TIME_LO = native.S_OWN + 8, native.S_OWN + 9, native.S_OWN + 10
#: Entries of the lane array: the lane, the batch size, the states heyoka integrates, the span of the
#: parameters that hold the mode and guards, the parameter of the next requested time.
B_LANE, B_SIZE, B_STATES, B_MODE_LO, B_MODE_HI, B_TIME_PAR = range(6)
#: What a compiled callback returns: go on, or stop the batch for Python.
GO, STOP = 1, 0
#: The sampling event's parameter when a lane has no more requested times (never reached).
FAR = 1e50
#: The sampling event is ``SAMPLE_SCALE * (t - p)``: at most ``1e-50`` in size, nothing beside a state.
SAMPLE_SCALE = 1e-100


# ---------------------------------------------------------------------- compiled: the lanes' callbacks
@jit
def _lane_state(table, y):
    """The lane's state out of heyoka's ``(states, lanes)`` array into ``y``."""
    b = native.i1(table, S_LANE)
    h = native.f1(table, S_HSTATE)
    lane, size = b[B_LANE], b[B_SIZE]
    for j in range(y.shape[0]):
        y[j] = h[j * size + lane]


@jit
def guard_lane(prob, table, kind, index):
    """Guard ``(kind, index)`` fired in this table's lane: the core's step (as the scalar
    :func:`~nsbench.integrators._heyoka_native.guard_double`), the new state and mode written
    into the lane's columns. Returns :data:`GO` or :data:`STOP` (the code in ``ctl[C_CODE]``)."""
    b = native.i1(table, S_LANE)
    lane, size = b[B_LANE], b[B_SIZE]
    t = native.f1(table, S_TIME)[lane]
    t_lo = native.f1(table, S_TIME_LO)[lane]
    st = native.run_state(table)
    y = st.y_arc
    _lane_state(table, y)
    go = scalar._guard_event(prob, table, kind, index, t, t_lo, y)
    ctl = native.i1(table, S_CTL)
    if go or ctl[C_CODE] == JUMPED:
        h = native.f1(table, S_HSTATE)
        for j in range(st.y.shape[0]):
            h[j * size + lane] = st.y[j]
        dpars = native.f1(table, S_DPARS)
        if not scalar._write_mode(table, dpars):
            ctl[C_CODE] = BAD_MODE
            return STOP
        pars = native.f1(table, S_PARS)
        for j in range(b[B_MODE_LO], b[B_MODE_HI]):
            pars[j * size + lane] = dpars[j]
    return GO if go else STOP


@jit
def section_lane(table, k, d_sgn):
    """Section ``k`` crossed in this table's lane: the core's hit step (``ctl[C_CODE]``)."""
    b = native.i1(table, S_LANE)
    st = native.run_state(table)
    y = st.y_arc
    _lane_state(table, y)
    t = native.f1(table, S_TIME)[b[B_LANE]]
    return GO if scalar.section_hit(table, k, d_sgn, t, y) else STOP


@jit
def sample_lane(table):
    """The lane reached its next requested time: its state stored there (every request of that time), the
    sampling event's parameter moved to the next time (:data:`FAR` after the last)."""
    b = native.i1(table, S_LANE)
    st = native.run_state(table)
    dense = native.dense_states(table)
    y = st.y_arc
    _lane_state(table, y)
    i = st.si[SI_IEVAL]
    n = dense.t.shape[0]
    if i < n:
        target = dense.t[i]
        while i < n and dense.t[i] <= target:
            copy_into(dense.y[i], y)
            i += 1
        st.si[SI_IEVAL] = i
    pars = native.f1(table, S_PARS)
    pars[b[B_TIME_PAR] * b[B_SIZE] + b[B_LANE]] = dense.t[i] if i < n else FAR
    return GO


_TABLE = types.Array(types.int64, 2, "C")
_ENTRIES: dict[type, tuple] = {}


def entries(problem) -> tuple:
    """``(guard, section, sample)``: the compiled callbacks' entries for ``problem``'s family (loaded, or
    compiled once per install, on first use)."""
    key = type(problem.data)
    found = _ENTRIES.get(key)
    if found is None:
        prob = numba.typeof(problem.data)
        i64 = types.int64
        found = _ENTRIES[key] = (
            scalar._entry(guard_lane, prob, _TABLE, i64, i64),
            scalar._entry(section_lane, _TABLE, i64, i64),
            scalar._entry(sample_lane, _TABLE),
        )
    return found


# ---------------------------------------------------------------------- the callbacks heyoka calls
class _Event:
    """A terminal event's callback in batch mode, ``(ta, d_sgn, lane)``: one compiled call on the lane's table.
    Bound to a batch by :class:`_Batch` (heyoka copies it with the integrator: set on the copy, per batch)."""

    __slots__ = ("kind", "index", "call", "probs", "tables", "batch")

    def __init__(self, kind: int, index: int) -> None:
        self.kind, self.index = kind, index
        self.call: Any = None
        self.probs: Any = None
        self.tables: Any = None
        self.batch: Any = None

    def __call__(self, ta, d_sgn, lane) -> bool:
        if self.call(self.probs[lane], self.tables[lane], self.kind, self.index) == GO:
            return True
        self.batch.stopped.append((self, int(d_sgn), int(lane)))
        return False

    def again(self, d_sgn: int, lane: int) -> bool:
        """The same call once more (after Python grew a buffer): whether the lane goes on."""
        return self.call(self.probs[lane], self.tables[lane], self.kind, self.index) == GO

    def __deepcopy__(self, memo):
        return type(self)(self.kind, self.index)

    def __reduce__(self):
        return type(self), (self.kind, self.index)


class _SectionEvent(_Event):
    __slots__ = ()

    def __call__(self, ta, d_sgn, lane) -> bool:
        if self.call(self.tables[lane], self.index, int(d_sgn)) == GO:
            return True
        self.batch.stopped.append((self, int(d_sgn), int(lane)))
        return False

    def again(self, d_sgn: int, lane: int) -> bool:
        return self.call(self.tables[lane], self.index, d_sgn) == GO


class _SampleEvent(_Event):
    __slots__ = ()

    def __call__(self, ta, d_sgn, lane) -> bool:
        return self.call(self.tables[lane]) == GO

    def again(self, d_sgn: int, lane: int) -> bool:  # pragma: no cover - a sample never stops
        return True


# ---------------------------------------------------------------------- the compiled integrators
_CACHE: dict[tuple, tuple[Any, float]] = {}
_LOCK = threading.Lock()


def lanes() -> int:
    """The batch size: heyoka's recommended SIMD width for doubles on this machine (at least 2)."""
    return max(2, int(hy.recommended_simd_size()))


def time_parameter(st: model.Structure) -> int:
    """The runtime parameter of the next requested time (after the scalar model's)."""
    return st.n_pars


def compiled(
    st: model.Structure, directions: tuple[int, ...], tol: float | None, high_accuracy: bool, compact_mode: bool
) -> tuple[Any, float]:
    """A fresh copy of the batch integrator of ``st`` (double precision, :func:`lanes` lanes) and the seconds
    its compilation took (0 on a cache hit)."""
    size = lanes()
    key = (st, directions, tol, high_accuracy, compact_mode, size)
    with _LOCK:
        hit = _CACHE.get(key)
        if hit is None:
            tic = time.perf_counter()
            sys, guards, sections = model.native_guards(st)
            neg = hy.event_direction.negative
            events = [
                hy.t_event_batch(g - NUDGE, callback=_Event(code, block), direction=neg, cooldown=0.0)
                for g, code, block in guards
            ]
            events += [
                hy.t_event_batch(s, callback=_SectionEvent(0, q), direction=scalar._DIRECTIONS[d])
                for q, (s, d) in enumerate(zip(sections, directions))
            ]
            # scaled down: heyoka sizes its steps on the norm of the event functions' Taylor coefficients
            # too, and ``t - p`` (p up to FAR) would lengthen them (seen: 1e-12 off in a step of 2)
            sample = SAMPLE_SCALE * (hy.time - hy.par[time_parameter(st)])
            events.append(
                hy.t_event_batch(
                    sample, callback=_SampleEvent(0, 0), direction=hy.event_direction.positive, cooldown=0.0
                )
            )
            kwargs = {} if tol is None else {"tol": float(tol)}
            ta = hy.taylor_adaptive_batch(
                sys,
                np.zeros((st.n_states, size)),
                pars=np.zeros((st.n_pars + 1, size)),
                t_events=events,
                high_accuracy=high_accuracy,
                compact_mode=compact_mode,
                **kwargs,
            )
            hit = _CACHE[key] = (ta, time.perf_counter() - tic)
            return copy.deepcopy(ta), hit[1]
    return copy.deepcopy(hit[0]), 0.0


class BatchModel:
    """A batch integrator with its structure and its arrays (read once, viewed by address)."""

    def __init__(self, st: model.Structure, ta) -> None:
        self.st, self.ta = st, ta
        self.size = int(ta.batch_size)
        self.state, self.pars = ta.state, ta.pars
        self.flat_state, self.flat_pars = self.state.reshape(-1), self.pars.reshape(-1)
        self.t_hi, self.t_lo = ta.time, ta.dtime[1]
        self.order = int(ta.order)
        self.callbacks = [ev.callback for ev in ta.t_events]


# ---------------------------------------------------------------------- one batch
class _Lane:
    """One lane's run: its request, table and what the driver knows of it."""

    def __init__(self, bm: BatchModel, lane: int, request: RunRequest, coefficients: np.ndarray) -> None:
        st, s = bm.st, request.state
        problem = request.problem
        self.lane, self.request, self.state, self.prob = lane, request, s, problem.data
        self.n = problem.n_states
        self.dpars = np.zeros(st.n_pars)
        self.dpars[: coefficients.size] = coefficients
        self.ctl = np.zeros(4, np.int64)
        layout = np.array([scalar.FRICTION, self.n, st.n_blocks, st.mode_offset, st.guard_offset], np.int64)
        info = np.array([lane, bm.size, st.n_states, st.mode_offset, st.section_offset(0), time_parameter(st)])
        own = [
            bm.flat_state,
            bm.flat_pars,
            layout,
            np.zeros(1),
            np.zeros((1, 1), np.int64),
            self.ctl,
            self.dpars,
            np.zeros((0, problem.mode_size), np.int64),
            info.astype(np.int64),
            bm.t_hi,
            bm.t_lo,
        ]
        self.views = native.Views(request.records, s, request.section_bundle, request.limits, own)
        self.t_end = float(request.limits.t_end)
        self.hit_from = float(request.section_bundle.hit_from)
        self.quiet = bool(request.sections) and float(s.sf[SF_T]) < self.hit_from < self.t_end
        self.done = False
        self.steps = 0
        self.message = ""

    @property
    def target(self) -> float:
        return self.hit_from if self.quiet else self.t_end


class _Batch:
    """What the callbacks of one batch share: the lanes' tables and problems, the lanes that stopped."""

    def __init__(self, bm: BatchModel, requests: Sequence[RunRequest], coefficients: Sequence[np.ndarray]) -> None:
        self.bm = bm
        self.lanes = [_Lane(bm, k, r, c) for k, r, c in zip(range(bm.size), requests, coefficients)]
        self.stopped: list[tuple[_Event, int, int]] = []
        self.scratch = scalar._scratch(requests[0].state.y, requests[0].state.mode, requests[0].problem.max_guards)
        tables = [lane.views.table for lane in self.lanes]
        probs = [lane.prob for lane in self.lanes]
        tables += [tables[0]] * (bm.size - len(tables))  # padding lanes are frozen: never called
        probs += [probs[0]] * (bm.size - len(probs))
        guard, section, sample = entries(requests[0].problem)
        for cb in bm.callbacks:
            cb.batch, cb.tables, cb.probs = self, tables, probs
            cb.call = section if isinstance(cb, _SectionEvent) else sample if isinstance(cb, _SampleEvent) else guard

    def unbind(self) -> None:
        for cb in self.bm.callbacks:
            cb.call = cb.probs = cb.tables = cb.batch = None

    def load(self, lane: _Lane) -> bool:
        """The lane's time, state, mode, guards, sections and next requested time into its columns."""
        bm, st, s = self.bm, lane.state, self.bm.st
        k = lane.lane
        if not scalar._entry(scalar._write_mode, scalar._TABLE, scalar._F1)(lane.views.table, lane.dpars):
            return False
        hi, lo = np.array(bm.ta.dtime[0]), np.array(bm.ta.dtime[1])
        hi[k], lo[k] = float(st.sf[SF_T]), float(st.sf[SF_TLO])
        bm.ta.set_dtime(hi, lo)
        bm.state[: lane.n, k] = st.y
        for q, sec in enumerate(lane.request.sections):
            off = s.section_offset(q)
            lane.dpars[off + model.SECTION_ACTIVE] = 0.0 if lane.quiet else 1.0
            lane.dpars[off + model.SECTION_LEVEL] = sec.level
            lane.dpars[off + model.SECTION_COEFFS : off + model.SECTION_COEFFS + s.n_mech] = sec.coeffs
        bm.pars[: s.n_pars, k] = lane.dpars
        dense, i = lane.request.records.dense, int(st.si[SI_IEVAL])
        bm.pars[time_parameter(s), k] = dense.t[i] if i < dense.t.shape[0] else FAR
        if s.forced:
            phase = lane.dpars[s.coefficient("w")] * (float(st.sf[SF_T]) + float(st.sf[SF_TLO]))
            bm.state[lane.n, k], bm.state[lane.n + 1, k] = math.cos(phase), math.sin(phase)
        return True

    def sections(self, lane: _Lane, on: bool) -> None:
        s = self.bm.st
        for q in range(len(lane.request.sections)):
            self.bm.pars[s.section_offset(q) + model.SECTION_ACTIVE, lane.lane] = 1.0 if on else 0.0

    def freeze(self, k: int) -> None:
        """Lane ``k`` takes no more steps: every event off (the constant 1, or a time never reached), its
        state finite (a non-finite one would spoil every later step's check)."""
        bm, s = self.bm, self.bm.st
        for e in range(_SLOTS * s.n_blocks):
            bm.pars[s.guard_offset + model.GUARD_RECORD * e + model.GUARD_ACTIVE, k] = 0.0
        for q in range(s.n_sections):
            bm.pars[s.section_offset(q) + model.SECTION_ACTIVE, k] = 0.0
        bm.pars[time_parameter(s), k] = FAR
        if not np.all(np.isfinite(bm.state[:, k])):
            bm.state[:, k] = 0.0
            if s.forced:  # cos and sin of the phase
                bm.state[s.n_mech, k] = 1.0
        if k < len(self.lanes):
            self.lanes[k].done = True


# ---------------------------------------------------------------------- the driver
def run(bm: BatchModel, requests: Sequence[RunRequest], coefficients: Sequence[np.ndarray]) -> list[RunReport]:
    """The whole runs of ``requests`` (at most ``bm.size``, one structure), one per lane; one report each."""
    if not 0 < len(requests) <= bm.size:
        raise ValueError(f"a batch of {bm.size} lanes takes 1 to {bm.size} runs, not {len(requests)}")
    b = _Batch(bm, requests, coefficients)
    try:
        return _drive(b)
    finally:
        b.unbind()


def _start(b: _Batch) -> list[RunReport | None]:
    """Every lane loaded (padding lanes: frozen copies of the first); reports of lanes that cannot start."""
    bm = b.bm
    out: list[RunReport | None] = [None] * len(b.lanes)
    for lane in b.lanes:
        if not b.load(lane):
            out[lane.lane] = _unknown_mode(lane)
    first = b.lanes[0].lane
    for k in range(len(b.lanes), bm.size):
        bm.pars[:, k] = bm.pars[:, first]
        bm.state[:, k] = bm.state[:, first]
        b.freeze(k)
    for lane in b.lanes:
        if out[lane.lane] is not None:
            b.freeze(lane.lane)
    bm.ta.reset_cooldowns()
    return out


def _drive(b: _Batch) -> list[RunReport]:
    bm, ta = b.bm, b.bm.ta
    reports = _start(b)
    while not all(lane.done for lane in b.lanes):
        targets = np.array(bm.t_hi, dtype=float)  # a finished lane stays where it is
        live = [lane for lane in b.lanes if not lane.done]
        for lane in live:
            targets[lane.lane] = lane.target
        budget = min(int(lane.request.limits.max_steps) - int(lane.state.cnt[abi.NSTEPS]) for lane in live)
        if budget <= 0:
            for lane in live:
                if int(lane.state.cnt[abi.NSTEPS]) >= int(lane.request.limits.max_steps):
                    _fail(b, lane, abi.RUN_STEP_BUDGET)
            continue
        b.stopped.clear()
        ta.propagate_until(targets, max_steps=budget)
        results = ta.propagate_res
        for lane in live:
            taken = int(results[lane.lane][3])
            lane.steps += taken
            lane.state.cnt[abi.NSTEPS] += taken
            lane.state.cnt[abi.NFEV] += taken
        stopped = {k: (cb, d_sgn) for cb, d_sgn, k in b.stopped}
        for lane in live:
            if lane.lane in stopped:
                _after_stop(b, lane, *stopped[lane.lane])
            else:
                _after_outcome(b, lane, int(results[lane.lane][0]))
    for lane in b.lanes:
        _last_arc(b, lane)
    # the lanes share every step: a lane's time inside heyoka is not its own (NaN: not measured)
    return [
        reports[lane.lane]
        or RunReport(
            integrator_time=math.nan, extra={"taylor_coefficients": lane.steps * bm.order}, message=lane.message
        )
        for lane in b.lanes
    ]


def _after_outcome(b: _Batch, lane: _Lane, outcome: int) -> None:
    """A lane whose callbacks did not stop the batch: at its end time, out of steps, non-finite, or on."""
    k, st = lane.lane, lane.state
    t = float(b.bm.t_hi[k])
    if t >= lane.target:
        if lane.quiet:
            lane.quiet = False
            b.sections(lane, True)
            return
        _fill_to(lane, lane.t_end, b.bm.state[: lane.n, k])
        native.arrive(lane.prob, lane.request.records.dense, st, lane.t_end, 0.0, np.array(b.bm.state[: lane.n, k]))
        b.freeze(k)
    elif outcome == scalar._NONFINITE:
        lane.message = f"non-finite state after t = {t:.6g}"
        _fail(b, lane, abi.RUN_NONFINITE)
    elif outcome == scalar._STEP_LIMIT and int(st.cnt[abi.NSTEPS]) >= int(lane.request.limits.max_steps):
        _fail(b, lane, abi.RUN_STEP_BUDGET)
    # otherwise the lane is on its way: another lane stopped the batch, or the budget of a lane with fewer
    # steps left ended the propagation


def _after_stop(b: _Batch, lane: _Lane, cb: _Event, d_sgn: int) -> None:
    """Lane's callback stopped the batch: its run ended (freeze it), or Python does its part and calls again."""
    k = lane.lane
    for _ in range(8):  # a grown buffer may be followed by another need (events, then hits)
        code = int(lane.ctl[C_CODE])
        if code >= 0:
            b.freeze(k)
            return
        if code == native.NEED_EVENTS:
            lane.request.records.grow_events(int(lane.state.si[abi.SI_RECORDED]))
        elif code == native.NEED_HITS:
            lane.request.records.grow_hits(int(lane.state.si[abi.SI_NHITS]))
        elif code == JUMPED:
            if not b.load(lane):
                lane.message = _unknown_mode(lane).message
                b.freeze(k)
                return
            _skip_to(b, lane)
            return
        elif code == BAD_MODE:
            lane.message = _unknown_mode(lane).message
            b.freeze(k)
            return
        elif code == BAD_EVENT:
            t = float(b.bm.t_hi[k])
            lane.message = f"{scalar.event_name(int(lane.ctl[C_EVENT]))}, inactive in its mode, fired at t = {t:.17g}"
            _fail(b, lane, abi.RUN_FAILURE, abi.K_FAIL)
            return
        else:  # pragma: no cover - a code the callbacks do not leave
            raise RuntimeError(f"heyoka batch run: unknown callback code {code}")
        lane.views.refresh()
        if cb.again(d_sgn, k):
            return
    raise RuntimeError("heyoka batch run: the core asked again and again for the same crossing")


def _fail(b: _Batch, lane: _Lane, status: int, detail: int = 0) -> None:
    k = lane.lane
    y = np.array(b.bm.state[: lane.n, k], dtype=float)
    native.fail(lane.state, status, float(b.bm.t_hi[k]), y if np.all(np.isfinite(y)) else np.zeros(lane.n), detail)
    b.freeze(k)


def _fill_to(lane: _Lane, t: float, y, strict: bool = False) -> None:
    """Requested times up to ``t`` (before it, if ``strict``) that the sampling event did not reach (one at
    the end time itself: heyoka need not see a root where a propagation ends)."""
    st, dense = lane.state, lane.request.records.dense
    i = int(st.si[SI_IEVAL])
    while i < dense.t.shape[0] and (dense.t[i] < t if strict else dense.t[i] <= t):
        dense.y[i] = y
        i += 1
    st.si[SI_IEVAL] = i


def _skip_to(b: _Batch, lane: _Lane) -> None:
    """After an accumulation moved the lane's time forward: the requested states before it are the state
    there, as in the scalar run."""
    st = lane.state
    _fill_to(lane, float(st.sf[SF_T]), st.y, strict=True)
    dense, i = lane.request.records.dense, int(st.si[SI_IEVAL])
    st.si[SI_ARC_IEVAL] = i
    b.bm.pars[time_parameter(b.bm.st), lane.lane] = dense.t[i] if i < dense.t.shape[0] else FAR


def _last_arc(b: _Batch, lane: _Lane) -> None:
    """A stop at a section hit ends the arc there: its states are checked as the per-arc path checks them."""
    st, dense = lane.state, lane.request.records.dense
    si = st.si
    if si[abi.SI_STOPPED] and si[abi.SI_STATUS] == abi.RUN_SUCCESS and si[SI_ARC_IEVAL] < si[SI_IEVAL]:
        first, last = int(si[SI_ARC_IEVAL]), int(si[SI_IEVAL])
        wrong = native.missed_over(lane.prob, b.scratch, dense, st.mode, first, last)
        if not math.isnan(wrong):
            native.fail(st, abi.RUN_MISSED, wrong, dense.y[first], 0)


def _unknown_mode(lane: _Lane) -> RunReport:
    st = lane.state
    native.fail(st, abi.RUN_FAILURE, float(st.sf[SF_T]), st.y.copy(), abi.K_FAIL)
    name = lane.request.problem.mode_name(tuple(int(v) for v in st.mode))
    return RunReport(message=f"the run entered mode {name}, which the batch model does not know", integrator_time=0.0)
