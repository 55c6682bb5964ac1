"""heyoka running the whole hybrid run of a friction problem itself (the whole-run protocol: ``loop = 'native'``).

One ``taylor_adaptive`` per structure, with the per-arc model's field and sections and two
guard events per block (:func:`nsbench.integrators._heyoka_model.native_guards`: the velocity
guard and the upper static limit share one, since a mode has one of them; the mode, the
coefficients and the sections are runtime parameters), whose terminal events carry callbacks:

- a guard's callback hands its crossing to the core's compiled step
  (:func:`nsbench.model.native.event`: the transition of the problem's law, the guards that
  fire at once, storms, the event budget, the Zeno rule, the stop rule), then writes the new
  mode into the runtime parameters and the reset velocities into the state, and returns
  ``True``: heyoka goes on within the same propagation. A new phase starts on its guard's
  surface, where heyoka would not look for the guard's roots in the first step at all (a
  zero where a step starts; heyoka 7.13 lets a ball thrown up from the floor in one Taylor
  step fall through it), so each guard's event is ``expected_sign * guard - NUDGE``: a
  phase starts 1e-300 below zero and rising, which the event direction ("decreasing")
  ignores, and its crossing is found in any step. No step is taken by hand. A phase that
  starts on a *double* zero (``fs = fr``) can start heading to the wrong side, which no
  event sees; such problems run per arc (``native_refusal``).
- a section's callback records the crossing (:func:`nsbench.model.native.hit`); sections are
  terminal events, so that a run can end at its ``hit_stop``-th hit where the per-arc path
  does (a non-terminal event cannot stop a propagation). They keep heyoka's automatic
  cooldown: an observation, it must not fire twice at one crossing.

One ``propagate_until`` covers the span (``propagate_grid`` when states are requested: heyoka
evaluates them on each step's Taylor polynomial, as the per-arc path does). A callback stops
the propagation (returns ``False``) only when the core says so: the run is over, a record
buffer is full (Python grows it and makes the same call again), the arc log of the
missed-crossing check is full, or an accumulation moved the time forward. The
missed-crossing check runs on the states of each stretch, arc by arc (the arc log keeps the
modes; :func:`nsbench.model.native.missed_over`); heyoka itself looks for every guard's sign
change on every step's polynomial.

In double precision a callback is one compiled call (the guard's crossing and the state in
heyoka's own arrays, by address: :class:`nsbench.model.native.Views`); in long double and
quad (numba has neither) the state crosses as doubles, and only the entries the transition
changed are written back, so the others keep every digit of the integrator's precision.
"""

from __future__ import annotations

import copy
import math
import threading
import time
from typing import Any

import heyoka as hy
import numba
import numpy as np
from numba import types

from nsbench.integrators import _heyoka_model as model
from nsbench.integrators.base import RunReport, RunRequest
from nsbench.model import abi, native
from nsbench.model.abi import SF_T, SF_TLO, SI_ARC_IEVAL, SI_EVENTS, SI_IEVAL, SI_NG, SI_NHITS, SI_RECORDED
from nsbench.model.abi import SI_STOP_SEEN
from nsbench.model.compile import jit
from nsbench.model.records import copy_into
from nsbench.problems.friction_spec import GUARD_KINDS, STICK

# the model's guard slots are the law's guard kind codes
assert all(model.GUARD_SLOT[name] == code for code, name in enumerate(GUARD_KINDS))
_SLOTS = len(model.GUARD_SLOT)
_VELOCITY, _UPPER = model.GUARD_SLOT["velocity"], model.GUARD_SLOT["upper"]

#: Slots of this run's arrays in its :class:`~nsbench.model.native.Views` table, after the core's.
S_HSTATE, S_PARS, S_LAYOUT, S_LOG_T, S_LOG_I, S_CTL, S_DPARS, S_MODES = range(native.S_OWN, native.S_OWN + 8)
#: Entries of the layout array: how the mode is written (:data:`FRICTION`, :data:`SELECTOR`), mechanical
#: states, blocks, offsets of the mode and of the guards' records.
L_KIND, L_N, L_NB, L_MODE, L_GUARD = range(5)
#: The friction model's mode (a stick flag and a slip sign per block, the guards' flags and signs), or a
#: selector per mode of a problem written symbolically (1 for the current mode, 0 for the others).
FRICTION, SELECTOR = 0, 1
#: Entries of the control array: the last code of a callback, arcs logged, whether to log them, a bad event.
C_CODE, C_NLOG, C_LOG_ON, C_EVENT = range(4)
#: Columns of the arc log before the mode: the arc's first dense state, events recorded, events applied,
#: hits and stop-kind events at its end (what the run keeps if a crossing inside the arc was stepped over).
LOG_FIRST, LOG_RECORDED, LOG_EVENTS, LOG_HITS, LOG_SEEN = range(5)
LOG_FIXED = 5
#: Arcs the log holds before a propagation stops for the check (a stop costs a few microseconds).
LOG_CAPACITY = 4096
#: Codes a callback leaves beside the core's (``native.GO_ON``, ``NEED_*``, ``RUN_*``).
NEED_LOG, BAD_EVENT, JUMPED, BAD_MODE = -10, -11, -12, -13

#: Subtracted from every guard's event function (see the module docstring): heyoka does not look for the
#: roots of an event function that is exactly zero where a step starts, and every phase starts on its
#: guard's surface. A located crossing moves by ``NUDGE / |rate|``, nothing in any precision used here.
NUDGE = 1e-300

_OUTCOME = hy.taylor_outcome
_TIME_LIMIT, _STEP_LIMIT, _NONFINITE = int(_OUTCOME.time_limit), int(_OUTCOME.step_limit), int(_OUTCOME.err_nf_state)
_DIRECTIONS = {-1: hy.event_direction.negative, 0: hy.event_direction.any, 1: hy.event_direction.positive}


# ---------------------------------------------------------------------- compiled: the callbacks' work
@jit
def _write_mode(table, pars):
    """The mode and its guards (``st.mode``, ``st.gk/gi/gs``) into the runtime parameters ``pars`` (doubles);
    whether the model has that mode (a selector model knows the modes it was built with)."""
    st = native.run_state(table)
    lay = native.i1(table, S_LAYOUT)
    if lay[L_KIND] == SELECTOR:
        modes = native.i2(table, S_MODES)
        found = False
        for m in range(modes.shape[0]):
            same = True
            for j in range(st.mode.shape[0]):
                same = same and modes[m, j] == st.mode[j]
            if lay[L_MODE] + m < pars.shape[0]:  # heyoka keeps only the selectors its expressions use
                pars[lay[L_MODE] + m] = 1.0 if same and not found else 0.0
            found = found or same
        return found
    nb, mo, go = lay[L_NB], lay[L_MODE], lay[L_GUARD]
    for i in range(nb):
        phase = st.mode[i]
        pars[mo + i] = 1.0 if phase == STICK else 0.0
        pars[mo + nb + i] = float(phase)
    for e in range(_SLOTS * nb):
        pars[go + model.GUARD_RECORD * e + model.GUARD_ACTIVE] = 0.0
    for q in range(st.si[SI_NG]):
        e = go + model.GUARD_RECORD * (_SLOTS * st.gi[q] + st.gk[q])
        pars[e + model.GUARD_ACTIVE] = 1.0
        pars[e + model.GUARD_SIGN] = float(st.gs[q])
    return True


@jit
def _guard_event(prob, table, kind, index, t, t_lo, y):
    """Guard ``(kind, index)`` of the mode fired at ``(t + t_lo, y)``: log the arc, apply the core's step.

    Returns whether heyoka goes on; the code is left in ``ctl[C_CODE]``.
    """
    st = native.run_state(table)
    ctl = native.i1(table, S_CTL)
    if kind == model.VELOCITY_OR_UPPER:  # one event for both (model.native_guards): the mode has one of them
        q = native.guard_at(st, _VELOCITY, index)
        if q < 0:
            q = native.guard_at(st, _UPPER, index)
    else:
        q = native.guard_at(st, kind, index)
    if q < 0:  # an inactive guard is the constant 1: this cannot happen unless the parameters are wrong
        ctl[C_CODE], ctl[C_EVENT] = BAD_EVENT, (_SLOTS + 1) * index + kind + 1
        return False
    log_t = native.f1(table, S_LOG_T)
    log_i = native.i2(table, S_LOG_I)
    n_log = ctl[C_NLOG]
    logging = ctl[C_LOG_ON] != 0
    if logging:
        if n_log >= log_t.shape[0]:
            ctl[C_CODE] = NEED_LOG
            return False
        si = st.si
        row = log_i[n_log]
        row[LOG_FIRST], row[LOG_RECORDED], row[LOG_EVENTS] = si[SI_ARC_IEVAL], si[SI_RECORDED], si[SI_EVENTS]
        row[LOG_HITS], row[LOG_SEEN] = si[SI_NHITS], si[SI_STOP_SEEN]
        for j in range(st.mode.shape[0]):
            row[LOG_FIXED + j] = st.mode[j]
        log_t[n_log] = t
    lim = native.limits(table)
    code = native.event(prob, lim, native.dense_states(table), native.events(table), st, q, t, t_lo, y)
    ctl[C_CODE] = code
    if code == native.NEED_EVENTS:
        return False
    if logging:
        ctl[C_NLOG] = n_log + 1
    if code != native.GO_ON:
        return False
    if st.sf[SF_T] != t or st.sf[SF_TLO] != t_lo:  # an accumulation: heyoka's time is set again in Python
        ctl[C_CODE] = JUMPED
        return False
    return True


@jit
def guard_double(prob, table, kind, index, t, t_lo):
    """The callback of a guard in double precision: the state read from heyoka's own array, the
    transition's changes and the new mode written back into it and into the parameters."""
    st = native.run_state(table)
    hstate = native.f1(table, S_HSTATE)
    n = st.y.shape[0]
    y = st.y_arc
    for j in range(n):
        y[j] = hstate[j]
    go = _guard_event(prob, table, kind, index, t, t_lo, y)
    ctl = native.i1(table, S_CTL)
    if go or ctl[C_CODE] == JUMPED:
        for j in range(n):
            hstate[j] = st.y[j]
        if not _write_mode(table, native.f1(table, S_PARS)):
            ctl[C_CODE] = BAD_MODE
            return False
    return go


@jit
def guard_wide(prob, table, kind, index, t, t_lo, y):
    """The callback of a guard in a wider precision, on the state ``y`` rounded to doubles: the new mode
    goes into the double parameters ``dpars``; the caller writes both back in its precision."""
    go = _guard_event(prob, table, kind, index, t, t_lo, y)
    ctl = native.i1(table, S_CTL)
    if go or ctl[C_CODE] == JUMPED:
        if not _write_mode(table, native.f1(table, S_DPARS)):
            ctl[C_CODE] = BAD_MODE
            return False
    return go


@jit
def section_hit(table, k, d_sgn, t, y):
    """Section ``k`` crossed at ``(t, y)`` in direction ``d_sgn``: the core's hit step (``ctl[C_CODE]``)."""
    st = native.run_state(table)
    ctl = native.i1(table, S_CTL)
    sec = native.sections(table)
    direction = sec.directions[k]
    if d_sgn == 0 or (direction != 0 and direction != d_sgn):  # a touch, or the other way: no hit
        ctl[C_CODE] = native.GO_ON
        return True
    code = native.hit(sec, native.hit_buffer(table), native.dense_states(table), st, k, t, y)
    ctl[C_CODE] = code
    return code == native.GO_ON


@jit
def section_double(table, k, d_sgn, t):
    """The callback of a section in double precision (the state from heyoka's own array)."""
    st = native.run_state(table)
    hstate = native.f1(table, S_HSTATE)
    y = st.y_arc
    for j in range(y.shape[0]):
        y[j] = hstate[j]
    return section_hit(table, k, d_sgn, t, y)


@jit
def after_stretch(prob, table, scratch, i1):
    """The dense states up to ``i1`` are stored: check each logged arc for a crossing stepped over.

    The logged arc ``j`` holds the states from its first (the log's ``LOG_FIRST`` for the first arc
    of the stretch, else where the previous one ended) up to its end time. The states after the
    last logged arc belong to the current arc (``si[SI_ARC_IEVAL]``), which the next event's step
    (or :func:`~nsbench.model.native.arrive`) checks. A crossing stepped over ends the run as in
    the per-arc path, at the first state on the wrong side, keeping the events, hits and states
    of the arcs before (``RUN_MISSED``); otherwise ``GO_ON``. Empties the log.
    """
    st = native.run_state(table)
    dense = native.dense_states(table)
    ctl = native.i1(table, S_CTL)
    log_t = native.f1(table, S_LOG_T)
    log_i = native.i2(table, S_LOG_I)
    si, sf = st.si, st.sf
    n_log = ctl[C_NLOG]
    ctl[C_NLOG] = 0
    last = si[SI_ARC_IEVAL]
    for j in range(n_log):
        first = log_i[j, LOG_FIRST] if j == 0 else last
        last = first
        while last < i1 and dense.t[last] <= log_t[j]:
            last += 1
        wrong = native.missed_over(prob, scratch, dense, log_i[j, LOG_FIXED:], first, last)
        if not np.isnan(wrong):
            row = log_i[j]
            si[SI_RECORDED], si[SI_EVENTS], si[SI_NHITS], si[SI_STOP_SEEN] = (
                row[LOG_RECORDED],
                row[LOG_EVENTS],
                row[LOG_HITS],
                row[LOG_SEEN],
            )
            si[SI_IEVAL] = last
            for i in range(st.mode.shape[0]):
                st.mode[i] = row[LOG_FIXED + i]
            at = first
            while at < last and dense.t[at] < wrong:
                at += 1
            copy_into(st.y, dense.y[at])
            sf[SF_T], sf[SF_TLO] = wrong, 0.0
            si[abi.SI_STATUS] = abi.RUN_MISSED
            return abi.RUN_MISSED
    if n_log:
        si[SI_ARC_IEVAL] = last
    si[SI_IEVAL] = i1
    return native.GO_ON


# ---------------------------------------------------------------------- the callbacks heyoka calls
_clock = time.perf_counter


class _Guard:
    """A guard's terminal-event callback (double precision). Bound to a run by :class:`_Run`; heyoka copies
    it with the integrator, so what it reaches is set on the integrator's own copy, per run."""

    __slots__ = ("kind", "index", "call", "prob", "table", "run")

    def __init__(self, kind: int, index: int) -> None:
        self.kind, self.index = kind, index
        self.call: Any = None
        self.prob: Any = None
        self.table: Any = None
        self.run: Any = None

    def __call__(self, ta, d_sgn) -> bool:
        tic = _clock()
        hi, lo = ta.dtime
        go = self.call(self.prob, self.table, self.kind, self.index, hi, lo)
        run = self.run
        if not go:
            run.stopped_by = (self, d_sgn)
        run.glue += _clock() - tic
        return go

    def __deepcopy__(self, memo):
        return type(self)(self.kind, self.index)

    def __reduce__(self):
        return type(self), (self.kind, self.index)


class _GuardWide(_Guard):
    """A guard's callback in long double or quad precision: the state as doubles for the core's step, the
    changed entries and the mode written back in the integrator's precision."""

    __slots__ = ()

    def __call__(self, ta, d_sgn) -> bool:
        tic = _clock()
        run = self.run
        fp = run.fp
        hi, lo = ta.dtime
        t = float(hi)
        t_lo = float((hi - fp(t)) + lo)
        state = run.hstate
        y = state[: run.n].astype(float)
        go = self.call(self.prob, self.table, self.kind, self.index, t, t_lo, y)
        if go or run.ctl[C_CODE] == JUMPED:
            new = run.state.y
            changed = np.flatnonzero(new != y)
            if changed.size:
                state[changed] = new[changed].astype(fp)
            run.pars[run.mode_part] = run.dpars[run.mode_part].astype(fp)
        if not go:
            run.stopped_by = (self, d_sgn)
        run.glue += _clock() - tic
        return go


class _Section(_Guard):
    """A section's terminal-event callback (``kind``: unused; ``index``: the section slot)."""

    __slots__ = ()

    def __call__(self, ta, d_sgn) -> bool:
        tic = _clock()
        run = self.run
        if run.fp is float:
            go = self.call(self.table, self.index, int(d_sgn), ta.time)
        else:
            y = run.hstate[: run.n].astype(float)
            go = self.call(self.table, self.index, int(d_sgn), float(ta.dtime[0]), y)
        if not go:
            run.stopped_by = (self, d_sgn)
        run.glue += _clock() - tic
        return go


# ---------------------------------------------------------------------- the compiled integrators
_CACHE: dict[tuple, tuple[Any, float]] = {}
_LOCK = threading.Lock()


def compiled(
    st: model.Structure,
    directions: tuple[int, ...],
    precision: str,
    tol: float | None,
    high_accuracy: bool,
    compact_mode: bool,
) -> tuple[Any, float]:
    """A fresh copy of the native integrator of ``st`` (its sections crossed in ``directions``) and the
    seconds its compilation took (0 on a cache hit: a copy, about a millisecond)."""
    key = (st, directions, precision, tol, high_accuracy, compact_mode)
    with _LOCK:
        hit = _CACHE.get(key)
        if hit is None:
            fp = model.FP_TYPES[precision]
            tic = time.perf_counter()
            sys, guards, sections = model.native_guards(st)
            kind = _Guard if precision == "double" else _GuardWide
            neg = hy.event_direction.negative
            # no cooldown on a guard (MODEL.md: it could only hide a genuine event)
            events = [
                hy.t_event(g - NUDGE, callback=kind(code, block), direction=neg, cooldown=fp(0.0), fp_type=fp)
                for g, code, block in guards
            ]
            events += [
                hy.t_event(s, callback=_Section(0, q), direction=_DIRECTIONS[d], fp_type=fp)
                for q, (s, d) in enumerate(zip(sections, directions))
            ]
            kwargs = {} if tol is None else {"tol": fp(tol)}
            ta = hy.taylor_adaptive(
                sys,
                np.zeros(st.n_states, dtype=fp),
                pars=np.zeros(st.n_pars, dtype=fp),
                fp_type=fp,
                t_events=events,
                high_accuracy=high_accuracy,
                compact_mode=compact_mode,
                **kwargs,
            )
            hit = _CACHE[key] = (ta, time.perf_counter() - tic)
            return copy.deepcopy(ta), hit[1]
    return copy.deepcopy(hit[0]), 0.0


def compiled_symbolic(
    problem, precision: str, tol: float | None, high_accuracy: bool, compact_mode: bool
) -> tuple[Any, float]:
    """A fresh copy of the native integrator of a problem written symbolically (``symbolic_field``, its
    modes ``symbolic_modes``), and the seconds its compilation took.

    One runtime parameter per mode selects it (1 for the current mode, 0 for the others): the field is
    the selected mode's (one field when every mode has the same), and each guard of each mode is a
    terminal event ``s_m * (expected_sign * guard) + (1 - s_m)``, the constant 1 in the other modes.
    """
    modes = tuple(tuple(int(v) for v in m) for m in problem.symbolic_modes)
    key = ("symbolic", problem.name, problem.packed.tobytes(), modes, precision, tol, high_accuracy, compact_mode)
    with _LOCK:
        hit = _CACHE.get(key)
        if hit is None:
            fp = model.FP_TYPES[precision]
            tic = time.perf_counter()
            y = hy.make_vars(*problem.state_names)
            fields = [problem.symbolic_field(m, hy.time, y) for m in modes]
            same = all(all(a == b for a, b in zip(f, fields[0])) for f in fields[1:])
            if same:
                field = fields[0]
            else:
                field = [sum((hy.par[k] * f[j] for k, f in enumerate(fields)), 0.0 * y[0]) for j in range(len(y))]
            kind = _Guard if precision == "double" else _GuardWide
            neg = hy.event_direction.negative
            events = []
            for k, m in enumerate(modes):
                for g in problem.guards(m):
                    expr = float(g.expected_sign) * problem.symbolic_guard(m, g.code, g.block - 1, hy.time, y)
                    events.append(
                        hy.t_event(
                            hy.par[k] * expr + (1.0 - hy.par[k]) - NUDGE,
                            callback=kind(g.code, g.block - 1),
                            direction=neg,
                            cooldown=fp(0.0),
                            fp_type=fp,
                        )
                    )
            kwargs = {} if tol is None else {"tol": fp(tol)}
            ta = hy.taylor_adaptive(
                list(zip(y, field)),
                np.zeros(len(y), dtype=fp),
                fp_type=fp,
                t_events=events,
                high_accuracy=high_accuracy,
                compact_mode=compact_mode,
                **kwargs,
            )
            hit = _CACHE[key] = (ta, time.perf_counter() - tic)
            return copy.deepcopy(ta), hit[1]
    return copy.deepcopy(hit[0]), 0.0


class NativeModel:
    """A native integrator with its structure, its arrays (read once: heyoka hands a new view per read) and
    its callbacks. ``st``: the friction model's structure; ``None`` with ``modes``, the modes of a
    selector model (:func:`compiled_symbolic`)."""

    def __init__(self, st: model.Structure | None, ta, precision: str, modes: tuple = ()) -> None:
        self.st, self.ta, self.precision, self.modes = st, ta, precision, modes
        self.fp = model.FP_TYPES[precision]
        self.state, self.pars = ta.state, ta.pars
        self.order = int(ta.order)
        self.callbacks = [ev.callback for ev in ta.t_events]
        self.scratch: abi.RunState | None = None

    def __reduce__(self):
        return NativeModel, (self.st, self.ta, self.precision, self.modes)


_ENTRIES: dict[tuple, Any] = {}


def _entry(fn, *arg_types):
    """The compiled entry of ``fn`` for these argument types (loaded from numba's cache, or compiled): called
    directly, it skips the dispatcher's look-up of the types (about half of a call's cost)."""
    key = (fn, arg_types)
    entry = _ENTRIES.get(key)
    if entry is None:
        fn.compile(arg_types)
        entry = _ENTRIES[key] = fn.overloads[arg_types].entry_point
    return entry


_TABLE = types.Array(types.int64, 2, "C")
_F1 = types.Array(types.float64, 1, "C")


_BY_FAMILY: dict[tuple, tuple] = {}


def entries(problem, precision: str) -> tuple:
    """``(guard, section, after_stretch)``: the compiled callbacks' entries for ``problem``'s family in this
    precision, loaded (or compiled, once per install) on first use and kept for the process."""
    data_class = type(problem.data)
    key = (data_class, precision)
    found = _BY_FAMILY.get(key)
    if found is None:
        prob = numba.typeof(problem.data)
        if precision == "double":
            guard = _entry(guard_double, prob, _TABLE, types.int64, types.int64, types.float64, types.float64)
            section = _entry(section_double, _TABLE, types.int64, types.int64, types.float64)
        else:
            guard = _entry(guard_wide, prob, _TABLE, types.int64, types.int64, types.float64, types.float64, _F1)
            section = _entry(section_hit, _TABLE, types.int64, types.int64, types.float64, _F1)
        scratch = numba.typeof(_scratch(np.zeros(1), np.zeros(1, np.int64), 1))
        after = _entry(after_stretch, prob, _TABLE, scratch, types.int64)
        found = _BY_FAMILY[key] = (guard, section, after)
    return found


def warm_up(problem, precision: str) -> None:
    """Load (or compile, once per install) the compiled callbacks for ``problem``'s family, untimed."""
    entries(problem, precision)
    _entry(_write_mode, _TABLE, _F1)


def _scratch(y: np.ndarray, mode: np.ndarray, n_guards: int) -> abi.RunState:
    """A :class:`~nsbench.model.abi.RunState` of its own for :func:`nsbench.model.native.missed_over`."""
    g = max(n_guards, 1)
    return abi.RunState(
        y=np.zeros_like(y),
        mode=np.zeros_like(mode),
        fresh=np.zeros(1, np.bool_),
        gk=np.zeros(g, np.int64),
        gi=np.zeros(g, np.int64),
        gs=np.zeros(g, np.int64),
        ring=np.zeros(1),
        acc=np.zeros(1),
        sf=np.zeros(abi.N_SF),
        si=np.zeros(abi.N_SI, np.int64),
        cnt=np.zeros(abi.N_COUNTERS, np.int64),
        y_arc=np.zeros_like(y),
        dy=np.zeros_like(y),
        iw=np.zeros(abi.N_COUNTERS + 2, np.int64),
    )


# ---------------------------------------------------------------------- one run
class _Run:
    """What the callbacks of one run share: the table, the arrays, the glue's clock, where it stopped."""

    def __init__(self, m: NativeModel, request: RunRequest, coefficients: np.ndarray) -> None:
        problem, st = request.problem, request.state
        self.m, self.request, self.fp, self.state = m, request, m.fp, st
        self.n = problem.n_states
        self.hstate, self.pars = m.state, m.pars
        s = m.st
        if s is None:  # a selector per mode
            self.layout = np.array([SELECTOR, self.n, 0, 0, 0], np.int64)
            self.dpars = np.zeros(len(m.modes))
            self.mode_part = slice(0, min(len(m.modes), self.pars.shape[0]))
            modes = np.array(m.modes, np.int64).reshape(len(m.modes), problem.mode_size)
        else:
            self.layout = np.array([FRICTION, self.n, s.n_blocks, s.mode_offset, s.guard_offset], np.int64)
            self.dpars = np.zeros(s.n_pars)
            self.dpars[: coefficients.size] = coefficients
            self.mode_part = slice(s.mode_offset, s.section_offset(0))
            modes = np.zeros((0, problem.mode_size), np.int64)
        self.log_t = np.zeros(LOG_CAPACITY)
        self.log_i = np.zeros((LOG_CAPACITY, LOG_FIXED + problem.mode_size), np.int64)
        self.ctl = np.zeros(4, np.int64)
        double = m.fp is float
        own = [
            self.hstate if double else np.zeros(1),
            self.pars if double else np.zeros(1),
            self.layout,
            self.log_t,
            self.log_i,
            self.ctl,
            self.dpars,
            modes,
        ]
        self.views = native.Views(request.records, st, request.section_bundle, request.limits, own)
        scratch = getattr(m, "scratch", None)  # overwritten by each check: one per model, kept across runs
        if scratch is None or scratch.y.shape != st.y.shape or scratch.mode.shape != st.mode.shape:
            scratch = m.scratch = _scratch(st.y, st.mode, problem.max_guards)
        self.scratch = scratch
        self.glue = 0.0
        self.stopped_by: tuple | None = None
        self.prob = problem.data
        guard, section, self.after = entries(problem, m.precision)
        for cb in m.callbacks:
            cb.run, cb.table, cb.prob = self, self.views.table, self.prob
            cb.call = section if isinstance(cb, _Section) else guard

    def unbind(self) -> None:
        for cb in self.m.callbacks:
            cb.call = cb.prob = cb.table = cb.run = None

    def refresh(self) -> None:
        """After a record buffer was replaced: the table again (the callbacks hold the table itself)."""
        self.views.records = self.request.records
        self.views.refresh()

    def load(self, sections_on: bool) -> bool:
        """Time, state, mode, guards and sections into the integrator (at the start, and after a jump);
        whether the model has the mode."""
        m, st, fp = self.m, self.state, self.fp
        s = m.st
        ta = m.ta
        if not _write_mode_py(self):
            return False
        t, t_lo = float(st.sf[SF_T]), float(st.sf[SF_TLO])
        ta.dtime = (fp(t), fp(t_lo))
        state = self.hstate
        state[: self.n] = st.y if fp is float else st.y.astype(fp)
        if s is None:
            used = self.pars.shape[0]  # the selectors heyoka's expressions use (a mode without guards may not)
            self.pars[:] = self.dpars[:used] if fp is float else self.dpars[:used].astype(fp)
            return True
        for q, sec in enumerate(self.request.sections):
            off = s.section_offset(q)
            self.dpars[off + model.SECTION_ACTIVE] = 1.0 if sections_on else 0.0
            self.dpars[off + model.SECTION_LEVEL] = sec.level
            coeffs = off + model.SECTION_COEFFS
            self.dpars[coeffs : coeffs + s.n_mech] = sec.coeffs
        self.pars[:] = self.dpars if fp is float else self.dpars.astype(fp)
        if s.forced:
            w = np.array([self.dpars[s.coefficient("w")]], dtype=float).astype(fp)
            phase = w * (fp(t) + fp(t_lo))
            state[self.n] = np.cos(phase)[0]
            state[self.n + 1] = np.sin(phase)[0]
        return True

    def sections(self, on: bool) -> None:
        s = self.m.st
        assert s is not None  # a selector model runs no sections (native_refusal)
        for q in range(len(self.request.sections)):
            self.pars[s.section_offset(q) + model.SECTION_ACTIVE] = self.fp(1.0 if on else 0.0)


def event_name(code: int) -> str:
    """What the event of ``ctl[C_EVENT]`` (a bad event: ``(kinds + 1) * block + kind + 1``) stands for."""
    block, kind = divmod(code, _SLOTS + 1)
    kind -= 1
    what = "velocity or upper" if kind == model.VELOCITY_OR_UPPER else GUARD_KINDS[kind]
    return f"the {what} guard of block {block + 1}"


def _write_mode_py(run: _Run) -> bool:
    return bool(_entry(_write_mode, _TABLE, _F1)(run.views.table, run.dpars))


def run(m: NativeModel, request: RunRequest, coefficients: np.ndarray) -> RunReport:
    """The whole run of ``request`` with the native integrator ``m`` (see the module docstring)."""
    r = _Run(m, request, coefficients)
    try:
        return _drive(r, request)
    finally:
        r.unbind()


def _drive(r: _Run, request: RunRequest) -> RunReport:
    st, lim, ta, fp = r.state, request.limits, r.m.ta, r.fp
    si, sf, cnt = st.si, st.sf, st.cnt
    rec = request.records
    prob, n = request.problem.data, r.n
    t_end = float(lim.t_end)
    hit_from = float(request.section_bundle.hit_from)
    quiet = bool(request.sections) and float(sf[SF_T]) < hit_from < t_end
    inside = 0.0
    if not r.load(sections_on=not quiet):
        return _unknown_mode(r, request)
    ta.reset_cooldowns()
    steps = 0
    message = ""
    while True:
        target = hit_from if quiet else t_end
        budget = int(lim.max_steps) - int(cnt[abi.NSTEPS])
        if budget <= 0:
            native.fail(st, abi.RUN_STEP_BUDGET, float(ta.time), r.hstate[:n].astype(float), 0)
            break
        i0 = int(si[SI_IEVAL])
        times = rec.dense.t[i0:]
        k = int(np.searchsorted(times, target, side="right"))
        r.ctl[C_CODE], r.ctl[C_NLOG], r.ctl[C_LOG_ON] = native.GO_ON, 0, 1 if k else 0
        r.stopped_by = None
        glue0 = r.glue
        tic = time.perf_counter()
        if k:
            # heyoka's grid starts at the current time and ends at the propagation's end; their states
            # are not requested ones unless they coincide
            now, wanted = ta.time, times[:k].astype(fp) if fp is not float else times[:k]
            drop = 0 if wanted[0] == now else 1
            tail = 0 if wanted[-1] == fp(target) else 1
            grid = np.concatenate(
                [np.array([now] * drop, dtype=wanted.dtype), wanted, np.array([fp(target)] * tail, dtype=wanted.dtype)]
            )
            outcome, _, _, taken, _, rows = ta.propagate_grid(grid, max_steps=budget)
        else:
            outcome, _, _, taken, _, _ = ta.propagate_until(fp(target), max_steps=budget)
        inside += time.perf_counter() - tic - (r.glue - glue0)
        taken = int(taken)
        steps += taken
        cnt[abi.NSTEPS] += taken
        cnt[abi.NFEV] += taken
        code = int(r.ctl[C_CODE])
        if k:
            rows = rows[drop : drop + k]
            i1 = i0 + rows.shape[0]
            if rows.shape[0]:
                rec.dense.y[i0:i1] = rows[:, :n] if fp is float else rows[:, :n].astype(float)
            if r.after(prob, r.views.table, r.scratch, i1) == abi.RUN_MISSED:
                break
        out = int(outcome)
        if code >= 0:  # the core ended the run (in a callback)
            break
        if out == _TIME_LIMIT:
            if quiet:
                quiet = False
                r.sections(True)
                continue
            native.arrive(prob, rec.dense, st, t_end, 0.0, np.array(r.hstate[:n], dtype=float))
            break
        if out == _STEP_LIMIT:
            native.fail(st, abi.RUN_STEP_BUDGET, float(ta.time), np.array(r.hstate[:n], dtype=float), 0)
            break
        if out == _NONFINITE:
            native.fail(st, abi.RUN_NONFINITE, float(ta.time), np.zeros(n), 0)
            message = f"non-finite state after t = {float(ta.time):.6g}"
            break
        if out >= 0 or r.stopped_by is None:  # heyoka stopped for a reason of its own
            native.fail(st, abi.RUN_FAILURE, float(ta.time), np.array(r.hstate[:n], dtype=float), abi.K_FAIL)
            message = f"heyoka stopped with {_OUTCOME(out)!r} at t = {float(ta.time):.17g}"
            break
        # a callback stopped heyoka for Python's part: do it, then make the same call again
        if code == BAD_EVENT:
            native.fail(st, abi.RUN_FAILURE, float(ta.time), np.array(r.hstate[:n], dtype=float), abi.K_FAIL)
            message = f"{event_name(int(r.ctl[C_EVENT]))}, inactive in its mode, fired at t = {float(ta.time):.17g}"
            break
        if code == native.NEED_EVENTS:
            rec.grow_events(int(si[SI_RECORDED]))
            r.refresh()
        elif code == native.NEED_HITS:
            rec.grow_hits(int(si[SI_NHITS]))
            r.refresh()
        elif code == JUMPED:
            if not r.load(sections_on=not quiet):
                return _unknown_mode(r, request)
            _skip_to(r, request)
            continue
        elif code == BAD_MODE:
            return _unknown_mode(r, request)
        cb, d_sgn = r.stopped_by
        if not cb(ta, d_sgn):
            code = int(r.ctl[C_CODE])
            if code >= 0:
                break
            if code == JUMPED:
                if not r.load(sections_on=not quiet):
                    return _unknown_mode(r, request)
                _skip_to(r, request)
                continue
            if code == BAD_MODE:
                return _unknown_mode(r, request)
            # another need at once (a full log after a grown buffer): the loop's next round deals with it
            raise RuntimeError(f"heyoka native run: the core asked twice in a row (code {code})")
    if si[abi.SI_STOPPED] and si[abi.SI_STATUS] == abi.RUN_SUCCESS and si[SI_ARC_IEVAL] < si[SI_IEVAL]:
        # a stop at a section hit ends the arc there: its states are checked as the per-arc path checks them
        first, last = int(si[SI_ARC_IEVAL]), int(si[SI_IEVAL])
        wrong = native.missed_over(prob, r.scratch, rec.dense, st.mode, first, last)
        if not math.isnan(wrong):
            native.fail(st, abi.RUN_MISSED, wrong, rec.dense.y[first], 0)
    extra: dict[str, float] = {"taylor_coefficients": steps * r.m.order}
    return RunReport(integrator_time=inside, extra=extra, message=message)


def _unknown_mode(r: _Run, request: RunRequest) -> RunReport:
    """The run entered a mode the selector model was not built with (not in ``symbolic_modes``)."""
    st = r.state
    native.fail(st, abi.RUN_FAILURE, float(st.sf[SF_T]), st.y.copy(), abi.K_FAIL)
    name = request.problem.mode_name(tuple(int(v) for v in st.mode))
    return RunReport(
        message=f"the run entered mode {name}, which is not among {request.problem.name}'s symbolic_modes",
        integrator_time=0.0,
    )


def refuse(request: RunRequest, why: str) -> RunReport:
    """End the run at its start as an integrator failure, for ``why``."""
    st = request.state
    native.fail(st, abi.RUN_FAILURE, float(st.sf[SF_T]), st.y.copy(), abi.K_FAIL)
    return RunReport(message=why, integrator_time=0.0)


def _skip_to(r: _Run, request: RunRequest) -> None:
    """After an accumulation moved the time forward: the requested states before the new time are the state
    there (the limit behaviour's: the per-arc path has no arc over that stretch either)."""
    st, dense = r.state, request.records.dense
    i, t = int(st.si[SI_IEVAL]), float(st.sf[SF_T])
    while i < dense.t.shape[0] and dense.t[i] < t:
        dense.y[i] = st.y
        i += 1
    st.si[SI_IEVAL] = i
    st.si[SI_ARC_IEVAL] = i
