"""The calling conventions of the compiled core: named bundles, the arc kernel's signature, codes and slots.

Three parties meet here, none importing another: a problem's *law* (the
vector field, guards and resets of its modes: :mod:`nsbench.model.law`), an
integrator's *arc kernel* (advances one frozen mode to its first guard zero,
``t_end``, a section stop or a failure) and the *core* (:mod:`.loop`,
:mod:`.rules`) that calls both through function tables
(:mod:`nsbench.model.functions`).

Arrays travel in named bundles (``NamedTuple`` classes below, typed by numba as
named tuples), never as long positional lists: an arc kernel is::

    status, t_stop, t_lo, fired = arc(kd, fo, prob, arc, sec, hits, dense, si, y_out, cnt)

- ``kd``: the kernel's data (:class:`KernelData`, the same fields for every
  kernel; each kernel names its own views of them); ``fo``: its float options
  (a vector with a named layout of the integrator's).
- ``prob``: the problem's data, a named tuple ``(p,)`` of its law's own class
  (:func:`nsbench.model.law.data_class`), through which compiled code calls its law.
- ``arc``: :class:`Arc`, the mode, its guards, the start ``(t0 + t0_lo, y0)``,
  ``t_end`` and the step budget left.
- ``sec``: :class:`Sections` (linear state sections); ``hits``: :class:`Hits`,
  where a hit at ``t >= sec.hit_from`` is appended at ``si[SI_NHITS]``
  (:func:`nsbench.model.records.record_hit`). A full buffer returns
  :data:`K_HIT_FULL` at once; the core restores its counters, grows the
  buffer and runs the arc again. With ``sec.hit_stop >= 0`` the arc stops at
  the hit that makes ``si[SI_NHITS] == hit_stop`` (:data:`K_HIT_STOP`,
  ``y_out`` the state there).
- ``dense``: :class:`Dense`, requested times and their states (rows); the
  kernel fills every ``dense.t[i] <= t_stop`` from ``si[SI_IEVAL]`` on.
- ``y_out``: where the arc stopped (before any transition); ``fired``: the
  index of the guard that fired (-1 if none); ``t_lo``: the low part of a
  compensated stop time (0 if not computed).
- ``cnt``: counters :data:`NFEV`, :data:`NJEV`, :data:`NSTEPS`, then
  :data:`N_EXTRA` method-specific slots (their names are the integrator's).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import numba
from numba import types

# ---------------------------------------------------------------------- array types of the ABI
F1 = types.Array(types.float64, 1, "C")
F2 = types.Array(types.float64, 2, "C")
F3 = types.Array(types.float64, 3, "C")
I1 = types.Array(types.int64, 1, "C")
I2 = types.Array(types.int64, 2, "C")
B1 = types.Array(types.boolean, 1, "C")


# ---------------------------------------------------------------------- bundles
class Arc(NamedTuple):
    """One arc: integrate ``mode`` from ``(t0 + t0_lo, y0)`` to the first zero of a guard, or ``t_end``."""

    mode: np.ndarray  # int64, the mode vector
    guard_kind: np.ndarray  # int64, the guards of the mode (first n_guards entries)
    guard_index: np.ndarray  # int64
    guard_sign: np.ndarray  # int64, the sign each guard keeps inside the mode
    n_guards: int
    t0: float
    t0_lo: float
    y0: np.ndarray  # float64
    t_end: float
    max_steps: int


class Sections(NamedTuple):
    """Linear state sections ``coeffs . y = level`` crossed in ``direction`` (-1, 0, +1); which hits to keep."""

    coeffs: np.ndarray  # float64 (n_sections, n_states)
    levels: np.ndarray  # float64
    directions: np.ndarray  # int64
    hit_from: float  # hits at t >= hit_from are kept
    hit_stop: int  # the run stops at the hit_stop-th kept hit (-1: never)


class Hits(NamedTuple):
    """Buffer of section hits: section index, time, state."""

    index: np.ndarray  # type: ignore[assignment]  # int64; shadows tuple.index: the kernels read it by name
    t: np.ndarray  # float64
    y: np.ndarray  # float64 (capacity, n_states)


class Dense(NamedTuple):
    """Requested times (sorted) and the states there, one row per time."""

    t: np.ndarray  # float64
    y: np.ndarray  # float64 (n_times, n_states)


class Events(NamedTuple):
    """Buffer of events: time, event kind code, 0-based index of the guard's element, state and mode after,
    and the error estimate of an accumulation time (:func:`nsbench.model.rules.settle`)."""

    t: np.ndarray  # float64
    kind: np.ndarray  # int64
    index: np.ndarray  # type: ignore[assignment]  # int64; shadows tuple.index: the kernels read it by name
    y: np.ndarray  # float64 (capacity, n_states)
    mode: np.ndarray  # int64 (capacity, mode size)
    err: np.ndarray  # float64, an extrapolated accumulation's error estimate (NaN for every other event)


class KernelData(NamedTuple):
    """The data of an arc kernel, in fields every kernel shares (so the core calls any kernel through one
    signature). A kernel names its views of these in its own module; unused fields hold empty arrays."""

    u1: np.ndarray  # uint64 1-d
    i1: np.ndarray  # int64 1-d
    i2: np.ndarray  # int64 2-d
    f1a: np.ndarray  # float64 1-d
    f1b: np.ndarray  # float64 1-d
    f2a: np.ndarray  # float64 2-d
    f2b: np.ndarray  # float64 2-d
    f2c: np.ndarray  # float64 2-d
    f3a: np.ndarray  # float64 3-d
    f3b: np.ndarray  # float64 3-d
    c2a: np.ndarray  # complex128 2-d
    c2b: np.ndarray  # complex128 2-d


def kernel_data(**fields: np.ndarray) -> KernelData:
    """A :class:`KernelData` with the given fields, every other one empty (C-contiguous, right dtype and rank)."""
    empty = {
        "u1": np.zeros(0, np.uint64),
        "i1": np.zeros(0, np.int64),
        "i2": np.zeros((0, 0), np.int64),
        "f1a": np.zeros(0),
        "f1b": np.zeros(0),
        "f2a": np.zeros((0, 0)),
        "f2b": np.zeros((0, 0)),
        "f2c": np.zeros((0, 0)),
        "f3a": np.zeros((0, 0, 0)),
        "f3b": np.zeros((0, 0, 0)),
        "c2a": np.zeros((0, 0), np.complex128),
        "c2b": np.zeros((0, 0), np.complex128),
    }
    unknown = set(fields) - set(empty)
    if unknown:
        raise TypeError(f"KernelData has no field(s) {sorted(unknown)}")
    values = {}
    for name, default in empty.items():
        value = np.ascontiguousarray(fields.get(name, default), dtype=default.dtype)
        if value.ndim != default.ndim:
            raise TypeError(f"KernelData.{name} must have {default.ndim} dimension(s), not {value.ndim}")
        values[name] = value
    return KernelData(**values)


class RunLimits(NamedTuple):
    """The settings of one run through the loop."""

    t_end: float
    max_steps: int
    max_events: int
    zeno_span: float  # zeno ring size + 1 events within this span: an event storm
    record_from: float  # events at t >= record_from are stored
    stop_kind: int  # the run stops after stop_count stored events of this kind (-1: none)
    stop_count: int
    accumulation: float  # tolerance of an extrapolated accumulation time, relative to max(1, |t|) (0: never)


class RunState(NamedTuple):
    """Everything the loop keeps between calls, so a run stops and resumes at any arc boundary."""

    y: np.ndarray  # float64 state
    mode: np.ndarray  # int64 mode vector
    fresh: np.ndarray  # bool, per element index: its guard starts on its surface by construction
    gk: np.ndarray  # int64 guards of the current mode: kind,
    gi: np.ndarray  # element index,
    gs: np.ndarray  # expected sign
    ring: np.ndarray  # float64, times of the last events (storms)
    acc: np.ndarray  # float64, times of the current streak of events of one guard (a ring; accumulations)
    sf: np.ndarray  # float64 slots SF_*
    si: np.ndarray  # int64 slots SI_*
    cnt: np.ndarray  # int64 counters
    y_arc: np.ndarray  # float64, where the last arc stopped
    dy: np.ndarray  # float64 scratch: a state's derivative
    iw: np.ndarray  # int64 scratch: counters saved before an arc, then two slots for the clock


def _type_of(example) -> types.Type:
    return numba.typeof(example)


def _z(dtype, ndim: int) -> np.ndarray:
    return np.zeros((1,) * ndim, dtype)


ARC = _type_of(
    Arc(_z(np.int64, 1), _z(np.int64, 1), _z(np.int64, 1), _z(np.int64, 1), 0, 0.0, 0.0, _z(np.float64, 1), 0.0, 0)
)
SECTIONS = _type_of(Sections(_z(np.float64, 2), _z(np.float64, 1), _z(np.int64, 1), 0.0, 0))
HITS = _type_of(Hits(_z(np.int64, 1), _z(np.float64, 1), _z(np.float64, 2)))
DENSE = _type_of(Dense(_z(np.float64, 1), _z(np.float64, 2)))
KERNEL_DATA = _type_of(kernel_data())


def arc_signature(problem_data: types.Type):
    """The signature an arc kernel is compiled for, for problems whose data have this (numba) type."""
    return types.Tuple([types.int64, types.float64, types.float64, types.int64])(
        KERNEL_DATA, F1, problem_data, ARC, SECTIONS, HITS, DENSE, I1, F1, I1
    )


# ---------------------------------------------------------------------- codes and slots
# kernel statuses
K_OK, K_HIT_STOP, K_HIT_FULL, K_BUDGET, K_NONFINITE, K_NEED_MODE = 0, 1, 2, 3, 4, 5
#: first method-specific failure code (a kernel may define K_FAIL + 0, + 1, ...)
K_FAIL = 8

# counter slots
NFEV, NJEV, NSTEPS = 0, 1, 2
X0, X1, X2, X3 = 3, 4, 5, 6
N_EXTRA = 4
N_COUNTERS = 3 + N_EXTRA

# slots of the loop's integer state ``si``
SI_EVENTS = 0  # events applied in the whole run
SI_RECORDED = 1  # events stored in the event buffers
SI_RING = 2  # events pushed into the storm ring
SI_STOP_SEEN = 3  # events of the stop kind at t >= record_from
SI_NHITS = 4  # section hits stored
SI_IEVAL = 5  # dense states filled
SI_PHASE = 6  # where the loop resumes
SI_STATUS = 7  # outcome of the run (RUN_* codes)
SI_DETAIL = 8  # kernel failure code, or the index of the fired guard after an arc
SI_NG = 9  # number of guards of the current mode
SI_CLOCK = 10  # nanoseconds spent inside arc kernels
SI_STOPPED = 11  # 1 when a stop rule (hits or events) ended the run
SI_ARC_STATUS = 12  # status of an arc computed in Python (the loop's callback path)
SI_ACC_KEY = 13  # the guard and event kind of the current streak of events (accumulations)
SI_ACC_N = 14  # the streak's length
SI_ARC_IEVAL = 15  # the first dense state of the current arc (checked for missed events)
N_SI = 16

# slots of the loop's float state ``sf``
SF_T, SF_TLO, SF_ARC_T, SF_ARC_TLO = 0, 1, 2, 3
N_SF = 4

# outcomes of a run (nsbench.status.Status of each: nsbench.hybrid.run)
RUN_SUCCESS, RUN_STEP_BUDGET, RUN_EVENT_BUDGET, RUN_STORM, RUN_NONFINITE, RUN_FAILURE, RUN_MISSED = range(7)
