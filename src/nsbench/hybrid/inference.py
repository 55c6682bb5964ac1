"""Switching events of a whole-system method, inferred from its discrete trajectory.

A whole-system method (:mod:`nsbench.integrators.whole`) returns its steps
``(t_k, y_k)``. :func:`infer_events` turns them into the event log an event-driven
run records, by one rule for every method: the events depend on the trajectory,
the problem and the method's stick band alone, so two methods that produce the same
trajectory get the same event times (to the rounding of the trajectory). The rule
(the friction family; ``u_i = v_i - v_belt``, ``b`` the method's stick band,
:meth:`~nsbench.integrators.whole.WholeSystem.stick_band`):

1. **The phase of a block at a step** is read off the trajectory. The block is *at
   the belt speed* where ``|u_i| <= b``; with ``b = 0`` (a method that sticks
   exactly: time-stepping) where ``|u_i| <= z``, ``z`` = :data:`ZERO_SPEED` times the
   trajectory's largest ``|u|`` (at least 1), a rounding tolerance (Siconos's relay
   leaves ``|u| ~ 1e-15`` where the enumeration of ``moreau-jean`` sets ``u = 0``).
   At the belt speed it is *stuck* if its static limit holds there (both stick-mode
   guards of the event-driven model, ``R_i - fr_i <= 0 <= R_i + fr_i`` with
   ``v_i = v_belt``, MODEL.md's rule for a block reaching the belt speed); if the limit
   is exceeded it slips: on in the direction it moved, with the sign of ``u_i``, if it
   was slipping at the step before (a pass through the belt speed: where ``u_i``
   changes sign that is a ``reverse``, as in the event-driven model, however many
   steps the pass lasts), else in the direction its load drives it (a break-away).
   Away from the belt speed it slips with the sign of ``u_i``. The first step's phase
   is the model's start rule (``problem.initial_mode``). The method's own labels
   (``SystemResult.modes``) are not read: two methods' labels of one state may differ
   (a relay at its bound where an enumeration reports a stuck step).
2. **An event** is a change of a block's phase between two consecutive steps ``k``
   and ``k+1``: ``stick`` (slip to stick), ``slip`` (stick to slip) or ``reverse``
   (slip+ to slip- or back).
3. **Its time** is where a guard, interpolated linearly between the two steps,
   crosses zero: ``u_i`` for a reversal; ``|u_i| - b`` for entering stick (with
   ``b = 0``, where the block is at the belt speed at step ``k+1``, which says
   nothing of when it got there: the line through the last two slipping steps) and,
   with ``b > 0``, ``b - |u_i|`` for leaving it; with ``b = 0``, leaving stick is
   placed where the stick mode's guard (``R_i - fr_i`` for slip-, ``R_i + fr_i`` for
   slip+, with ``v_i = v_belt``) crosses zero. A guard already past zero at step
   ``k`` places the event at ``t_k``, one not yet at zero at step ``k+1`` at
   ``t_{k+1}``: an event never leaves the step where the phase changed.
4. **Its state** is the linear interpolation of the two steps at that time, with
   ``v_i = v_belt`` set at a ``stick`` and a ``reverse`` (MODEL.md's convention);
   its mode is the mode before with block ``i``'s new phase. Several blocks
   changing in one step give one event each, in time order (ties: lower block first).

5. **Impact problems** (the bouncing ball, one contact): the method reports the impulse
   of each step and its resting contact (the mode). An ``impact`` is a step with a
   positive impulse while the ball approaches (``v < 0`` at the step's start), placed
   at the zero of the height's line between the two steps, with ``x = 0`` and the
   post-impact velocity; a change of the method's mode to resting is a ``rest`` event
   at that step (``v = 0``), after which its impulses are resting contact, not impacts.
   (The two time-stepping methods label a step resting by one rule of their
   trajectory and impulses: a positive impulse while ``e |v_k| <= g h``.)

6. **Relay problems** (family ``relay``, one switching surface: the relay feedback
   system): the method labels each step with its mode (``SystemResult.modes``: a side
   of the surface, or sliding on it; without labels each step takes the model's start
   rule at its state). An event is a change of label between steps ``k`` and ``k+1``:
   ``cross`` (side to side), ``slide`` (a side to sliding), ``exit`` (sliding to a
   side), placed at the zero of the line between the two steps of the guard of the
   mode before that is nearest to firing at step ``k+1`` (the switching function
   ``C x`` off the surface, a sliding limit ``1 -+ u_eq`` on it), kept within the step
   (an entry into sliding: on the line through the last two steps before it, since
   sliding holds ``C x`` at zero at step ``k+1`` whenever it began);
   its state is the linear interpolation there, its mode the label after. A touch
   (the surface reached tangentially, no change of side) changes no label and is not
   inferred.

**Switches a method locates itself** (``SystemResult.switch_times``, an FESD-type
method or an event-driven scheme run through this protocol) are not used to place
the events: each inferred event is paired with the nearest located switch of its
element within the steps around its phase change (``t_{k-1}`` to ``t_{k+2}``; each
located switch paired once), and that time is reported beside the inferred one
(:attr:`InferredEvents.located`, the event log's ``t_located`` column; NaN where
none is paired).

The interpolation is first order, as are the methods: it adds an error of at
most one step to a switching time, and none where the guard is linear in time
over the step (a stuck block's force under a constant load). :func:`run_whole`
runs a method and packs all of it into the records of an event-driven run.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Sequence

import numpy as np

from nsbench.model.records import Records
from nsbench.results import Counters
from nsbench.status import Status

if TYPE_CHECKING:  # pragma: no cover
    from nsbench.hybrid.run import RawRun
    from nsbench.integrators.whole import WholeSystem
    from nsbench.problems.base import HybridProblem
    from nsbench.sections import StateSection

STICK = 0
#: ``z`` of rule 1: a block of a method without a stick band is at the belt speed where ``|u|`` is within
#: this fraction of the trajectory's largest ``|u|`` (at least 1). Far above the rounding a stuck step of a
#: time-stepping method shows (1e-15 relative), far below any slipping step's ``|u|`` that the rule would
#: misread (a slip passing within 1e-10 of the belt speed at a step is, to that precision, at it).
ZERO_SPEED = 1e-10


@dataclass
class InferredEvents:
    """Events inferred from a trajectory, as arrays (one row per event, in time order)."""

    t: np.ndarray
    kind: np.ndarray  # codes into problem.event_kinds
    block: np.ndarray  # 0-based element index
    y: np.ndarray  # (n_events, n_states): state after the event
    mode: np.ndarray  # (n_events, mode_size): mode after the event
    start_mode: np.ndarray  # mode of the first step
    #: index ``k`` of the step pair ``(k, k+1)`` in which each event's phase changed
    step: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    #: the method's own time of each event (``SystemResult.switch_times`` paired with it), NaN where none
    located: np.ndarray | None = None

    def __len__(self) -> int:
        return int(self.t.size)


def zero_speed(problem: "HybridProblem", y: np.ndarray, band: float) -> float:
    """Rule 1's half-width of "at the belt speed": ``band``, or for ``band = 0`` the tolerance ``z``."""
    if band > 0.0:
        return float(band)
    u = np.asarray(y, dtype=float)[:, 1::2] - problem.v0
    return ZERO_SPEED * max(1.0, float(np.max(np.abs(u))) if u.size else 0.0)


def band_modes(problem: "HybridProblem", y: np.ndarray, band: float) -> np.ndarray:
    """Per step and block: 0 where ``|v_i - v_belt| <= band``, else the sign of ``v_i - v_belt`` (no force test)."""
    u = np.asarray(y)[:, 1::2] - problem.v0
    out = np.sign(u).astype(np.int64)
    out[np.abs(u) <= band] = STICK
    return out


def _limit_guards(problem: "HybridProblem", block: int):
    """The stick mode's two guards of ``block`` (0-based): towards slip- (``R - fr``) and slip+ (``R + fr``);
    ``None`` for a side whose guard the problem does not have (a stuck block that never leaves that way)."""
    guards = problem.guards((STICK,) * problem.mode_size)
    upper = next((g for g in guards if g.block == block + 1 and g.kind == "upper"), None)
    lower = next((g for g in guards if g.block == block + 1 and g.kind == "lower"), None)
    return upper, lower


def _limit_margins(problem: "HybridProblem", block: int, t: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Both stick guards of ``block`` at steps ``(t, y)`` (rows) with ``v = v_belt``, positive while the limit holds."""
    state = np.array(y, dtype=float).T.copy()
    state[2 * block + 1] = problem.v0
    times = np.asarray(t, dtype=float)
    out = []
    for guard in _limit_guards(problem, block):
        if guard is None:
            out.append(np.full(times.size, np.inf))
        else:
            out.append(guard.expected_sign * np.asarray(guard.value(times, state), dtype=float).reshape(times.size))
    return out[0], out[1]


def trajectory_modes(problem: "HybridProblem", t: np.ndarray, y: np.ndarray, band: float) -> np.ndarray:
    """Rule 1: the phase of every block at every step, read off the trajectory ``(t, y)`` (shape ``(k, nb)``)."""
    t = np.asarray(t, dtype=float)
    y = np.asarray(y, dtype=float)
    u = y[:, 1::2] - problem.v0
    z = zero_speed(problem, y, band)
    m = np.sign(u).astype(np.int64)
    m[0] = problem.initial_mode(float(t[0]), y[0])
    at_belt = np.abs(u) <= z
    at_belt[0] = False
    for i in range(u.shape[1]):
        idx = np.flatnonzero(at_belt[:, i])
        if not idx.size:
            continue
        to_minus, to_plus = _limit_margins(problem, i, t[idx], y[idx])
        holds = (to_minus >= 0.0) & (to_plus >= 0.0)
        m[idx[holds], i] = STICK
        load = np.where(to_minus < to_plus, -1, 1)  # the side whose limit is exceeded (the nearer, if both)
        over = idx[~holds]
        if not over.size:
            continue
        # runs of consecutive steps at the belt speed past the limit: what precedes a run says which it is
        cuts = np.flatnonzero(np.diff(over) > 1) + 1
        for run, drive in zip(np.split(over, cuts), np.split(load[~holds], cuts)):
            if m[run[0] - 1, i] != STICK:  # slipping into it: a pass through the belt speed
                m[run, i] = np.where(u[run, i] != 0.0, np.sign(u[run, i]), drive).astype(np.int64)
            else:  # stuck before (or at the start): a break-away in the direction of the load
                m[run, i] = drive
    return m


def _line_zero(ta: float, a: float, tb: float, b: float, lo: float, hi: float) -> float:
    """Zero of the line through ``(ta, a)`` and ``(tb, b)``, kept within ``[lo, hi]`` (``hi`` if the line is flat)."""
    if a == b:
        return hi
    return min(max(ta + a / (a - b) * (tb - ta), lo), hi)


def _stick_guard(problem, block: int, new: int, t: float, y: np.ndarray) -> float:
    """The stick mode's guard of ``block`` towards phase ``new`` (rule 3, ``b = 0``), positive while stuck."""
    to_minus, to_plus = _limit_margins(problem, block, np.array([t]), np.asarray(y, dtype=float).reshape(1, -1))
    return float(to_minus[0] if new < 0 else to_plus[0])


def pair_located(
    ev_t: np.ndarray,
    ev_block: np.ndarray,
    ev_step: np.ndarray,
    t: np.ndarray,
    switch_times: np.ndarray,
    switch_elements: np.ndarray | None,
) -> np.ndarray:
    """The located switch paired with each inferred event (the module docstring), NaN where none.

    An event whose phase changed between steps ``k`` and ``k+1`` takes the nearest unpaired
    located switch of its element (any element if ``switch_elements`` is ``None``) within
    ``[t_{k-1}, t_{k+2}]``; events are served in time order.
    """
    out = np.full(ev_t.size, np.nan)
    loc = np.asarray(switch_times, dtype=float).ravel()
    el = None if switch_elements is None else np.asarray(switch_elements, dtype=np.int64).ravel()
    used = np.zeros(loc.size, dtype=bool)
    last = t.size - 1
    for j in np.argsort(ev_t, kind="stable"):
        k = int(ev_step[j])
        lo, hi = t[max(k - 1, 0)], t[min(k + 2, last)]
        ok = ~used & (loc >= lo) & (loc <= hi)
        if el is not None:
            ok &= el == ev_block[j]
        cand = np.flatnonzero(ok)
        if cand.size:
            best = cand[np.argmin(np.abs(loc[cand] - ev_t[j]))]
            used[best] = True
            out[j] = loc[best]
    return out


def _impact_events(
    problem, t: np.ndarray, y: np.ndarray, modes: np.ndarray | None, impulses: np.ndarray | None
) -> InferredEvents:
    """Rule 5 (impact problems, one contact: the bouncing ball): see the module docstring."""
    k = len(t)
    m = np.zeros((k, 1), np.int64) if modes is None else np.asarray(modes, dtype=np.int64)
    p = np.zeros((k, 1)) if impulses is None else np.asarray(impulses, dtype=float).reshape(k, -1)
    impact, rest = problem.event_kinds.index("impact"), problem.event_kinds.index("rest")
    out_t, out_k, out_y, out_m, out_s = [], [], [], [], []
    for j in range(1, k):
        if m[j, 0] != m[j - 1, 0]:
            out_t.append(float(t[j]))
            out_k.append(rest)
            out_y.append(np.array([y[j, 0], 0.0]))
            out_m.append(m[j].copy())
            out_s.append(j - 1)
        elif m[j, 0] == 0 and p[j, 0] > 0.0 and y[j - 1, 1] < 0.0:
            out_t.append(_line_zero(t[j - 1], y[j - 1, 0], t[j], y[j, 0], t[j - 1], t[j]))
            out_k.append(impact)
            out_y.append(np.array([0.0, y[j, 1]]))
            out_m.append(m[j].copy())
            out_s.append(j - 1)
    n = len(out_t)
    return InferredEvents(
        t=np.array(out_t, dtype=float),
        kind=np.array(out_k, dtype=np.int64),
        block=np.zeros(n, np.int64),
        y=np.array(out_y, dtype=float).reshape(-1, 2),
        mode=np.array(out_m, dtype=np.int64).reshape(-1, 1),
        start_mode=m[0].copy(),
        step=np.array(out_s, dtype=np.int64),
    )


def _sliding_code(problem: "HybridProblem") -> int | None:
    """The code of the problem's sliding mode (its mode named ``slide``), or ``None`` if it has none."""
    names = getattr(problem, "mode_names", {})
    return next((int(code) for code, name in names.items() if name == "slide"), None)


def _relay_events(problem: "HybridProblem", t: np.ndarray, y: np.ndarray, modes: np.ndarray | None) -> InferredEvents:
    """Rule 6 (the relay family, one switching surface): see the module docstring."""
    k = len(t)
    if modes is None:
        m = np.array([problem.initial_mode(float(t[j]), y[j]) for j in range(k)], dtype=np.int64).reshape(k, -1)
    else:
        m = np.asarray(modes, dtype=np.int64).reshape(k, -1)
    slide = _sliding_code(problem)
    kinds = problem.event_kinds
    out_t, out_k, out_y, out_m, out_s = [], [], [], [], []
    for j in np.flatnonzero(m[1:, 0] != m[:-1, 0]) if k > 1 else ():
        p, q = int(m[j, 0]), int(m[j + 1, 0])
        kind = "exit" if p == slide else "slide" if q == slide else "cross"
        t0, t1 = float(t[j]), float(t[j + 1])
        # the guard of the mode before nearest to firing at the step's end: the one the switch went through
        guards = problem.guards((p,))
        margins = [(g.expected_sign * float(g.value(t1, y[j + 1])), g) for g in guards]
        if margins:
            guard = min(margins, key=lambda row: row[0])[1]
            # sliding keeps the switching function at zero at step k+1, which says nothing of when it got
            # there: an entry is placed on the line through the last two steps before it
            ja = j - 1 if kind == "slide" and j > 0 and m[j - 1, 0] == p else j
            a = guard.expected_sign * float(guard.value(float(t[ja]), y[ja]))
            b = guard.expected_sign * float(guard.value(float(t[ja + 1]), y[ja + 1]))
            te = _line_zero(float(t[ja]), a, float(t[ja + 1]), b, t0, t1)
        else:
            te = t1
        frac = (te - t0) / (t1 - t0)
        out_t.append(te)
        out_k.append(kinds.index(kind))
        out_y.append((1.0 - frac) * y[j] + frac * y[j + 1])
        out_m.append(m[j + 1].copy())
        out_s.append(int(j))
    n, ms = y.shape[1], problem.mode_size
    return InferredEvents(
        t=np.array(out_t, dtype=float),
        kind=np.array(out_k, dtype=np.int64),
        block=np.zeros(len(out_t), np.int64),
        y=np.array(out_y, dtype=float).reshape(-1, n),
        mode=np.array(out_m, dtype=np.int64).reshape(-1, ms),
        start_mode=m[0].copy() if k else np.zeros(ms, np.int64),
        step=np.array(out_s, dtype=np.int64),
    )


def infer_events(
    problem: "HybridProblem",
    t: np.ndarray,
    y: np.ndarray,
    modes: np.ndarray | None = None,
    band: float = 0.0,
    impulses: np.ndarray | None = None,
    switch_times: np.ndarray | None = None,
    switch_elements: np.ndarray | None = None,
) -> InferredEvents:
    """The events of the discrete trajectory ``(t, y)`` by the rule of this module's docstring.

    Parameters
    ----------
    problem
        A problem of the friction family, an impact problem (the bouncing ball) or of the
        relay family (rule 6).
    t, y
        Step times ``(k,)`` and states ``(k, n_states)``.
    modes
        Impact problems: the method's mode of each step ``(k, 1)`` (its resting contact, rule 5);
        relay problems: its side of the surface or sliding (rule 6).
        Not read for the friction family (rule 1 reads the phases off the trajectory).
    band
        The method's stick band ``b >= 0``.
    impulses
        Impact problems: the impulse of each step (rule 5).
    switch_times, switch_elements
        Switches the method located itself and their elements (0-based), paired with the
        inferred events (:func:`pair_located`); ``None``: the method locates none.
    """
    t = np.asarray(t, dtype=float)
    y = np.asarray(y, dtype=float)
    if not band >= 0.0:
        raise ValueError(f"stick band {band!r} must be >= 0")
    if problem.traits.impacts:
        ev = _impact_events(problem, t, y, modes, impulses)
    elif problem.traits.sliding:
        ev = _relay_events(problem, t, y, modes)
    else:
        ev = _friction_events(problem, t, y, band)
    if switch_times is not None:
        ev.located = pair_located(ev.t, ev.block, ev.step, t, switch_times, switch_elements)
    return ev


def _friction_events(problem: "HybridProblem", t: np.ndarray, y: np.ndarray, band: float) -> InferredEvents:
    """Rules 1-4 (the friction family)."""
    m = trajectory_modes(problem, t, y, band) if len(t) else np.zeros((0, problem.mode_size), np.int64)
    kinds = problem.event_kinds
    code = {name: kinds.index(name) for name in ("stick", "slip", "reverse")}
    v0 = problem.v0
    changed = np.flatnonzero(np.any(m[1:] != m[:-1], axis=1)) if len(t) > 1 else np.zeros(0, np.int64)
    running = m[0].copy() if len(t) else np.zeros(problem.mode_size, np.int64)
    out_t, out_k, out_b, out_y, out_m, out_s = [], [], [], [], [], []
    for k in changed:
        t0, t1 = t[k], t[k + 1]
        step = []
        for i in np.flatnonzero(m[k] != m[k + 1]):
            p, q = int(m[k, i]), int(m[k + 1, i])
            u0, u1 = y[k, 2 * i + 1] - v0, y[k + 1, 2 * i + 1] - v0
            if p != STICK and q != STICK:
                kind = "reverse"
                te = _line_zero(t0, u0, t1, u1, t0, t1)
            elif q == STICK:
                kind = "stick"
                if band == 0.0 and k > 0 and m[k - 1, i] == p:
                    # at the belt speed at step k+1, which says nothing of when it got there:
                    # the line through the last two slipping steps
                    um = y[k - 1, 2 * i + 1] - v0
                    te = _line_zero(t[k - 1], abs(um), t0, abs(u0), t0, t1)
                else:
                    te = _line_zero(t0, abs(u0) - band, t1, abs(u1) - band, t0, t1)
            else:
                kind = "slip"
                if band > 0.0:
                    te = _line_zero(t0, band - abs(u0), t1, band - abs(u1), t0, t1)
                else:
                    a = _stick_guard(problem, int(i), q, t0, y[k])
                    b = _stick_guard(problem, int(i), q, t1, y[k + 1])
                    te = _line_zero(t0, a, t1, b, t0, t1)
            frac = (te - t0) / (t1 - t0)
            ye = (1.0 - frac) * y[k] + frac * y[k + 1]
            if kind != "slip":
                ye[2 * i + 1] = v0
            step.append((te, int(i), code[kind], q, ye))
        for te, i, kind_code, q, ye in sorted(step, key=lambda row: (row[0], row[1])):
            running[i] = q
            out_t.append(te)
            out_k.append(kind_code)
            out_b.append(i)
            out_y.append(ye)
            out_m.append(running.copy())
            out_s.append(int(k))
    n, ms = y.shape[1], problem.mode_size
    return InferredEvents(
        t=np.array(out_t, dtype=float),
        kind=np.array(out_k, dtype=np.int64),
        block=np.array(out_b, dtype=np.int64),
        y=np.array(out_y, dtype=float).reshape(-1, n),
        mode=np.array(out_m, dtype=np.int64).reshape(-1, ms),
        start_mode=m[0].copy() if len(t) else np.zeros(ms, np.int64),
        step=np.array(out_s, dtype=np.int64),
    )


def section_hits(sections: Sequence["StateSection"], t: np.ndarray, y: np.ndarray):
    """Crossings of ``sections`` by the steps, each placed by linear interpolation: ``(index, t, y)`` in time order."""
    hits = []
    for j, sec in enumerate(sections):
        value = y @ np.asarray(sec.coeffs, dtype=float) - sec.level
        for k in np.flatnonzero(np.diff(np.signbit(value)) | (value[:-1] == 0.0)):
            a, b = float(value[k]), float(value[k + 1])
            if not sec.crossed(a, b):
                continue
            frac = a / (a - b)
            hits.append((j, t[k] + frac * (t[k + 1] - t[k]), (1.0 - frac) * y[k] + frac * y[k + 1]))
    return sorted(hits, key=lambda h: h[1])


def run_whole(
    problem: "HybridProblem",
    integ: "WholeSystem",
    t_end: float,
    *,
    t0: float = 0.0,
    y0: np.ndarray | None = None,
    sections: Sequence["StateSection"] = (),
    t_eval: np.ndarray | None = None,
    max_steps: int = 5_000_000,
) -> "RawRun":
    """Run a whole-system method and record its inferred events, section hits and states as a :class:`RawRun`.

    The states at ``t_eval`` come from the method's own dense output if it gives
    one, else from linear interpolation of its steps. ``integrator_time`` is the
    time inside :meth:`~nsbench.integrators.whole.WholeSystem.integrate`.
    """
    from nsbench.hybrid.run import RawRun
    from nsbench.integrators.whole import SystemRequest, check_result

    n = problem.n_states
    y = problem.initial_state() if y0 is None else np.array(y0, dtype=float)
    y_in = np.ascontiguousarray(y, dtype=float).copy()
    y_in.flags.writeable = False
    grid = np.ascontiguousarray(np.empty(0) if t_eval is None else t_eval, dtype=float)
    request = SystemRequest(
        problem=problem, t0=float(t0), y0=y_in, t_end=float(t_end), max_steps=int(max_steps), t_eval=grid
    )
    tic = time.perf_counter()
    try:
        res = integ.integrate(request)
        broken = check_result(integ.name, request, res, n, problem.mode_size)
    except Exception as exc:  # a protocol violation or a bug of the method: a failure status, never a crash
        res, broken = None, f"{type(exc).__name__}: {exc}"
    seconds = time.perf_counter() - tic
    rec = Records(n, problem.mode_size, grid)
    start = problem.initial_mode(float(t0), y)
    if broken:
        return RawRun(
            status=Status.INTEGRATOR_FAILURE,
            message=broken,
            t=float(t0),
            t_lo=0.0,
            y=y.copy(),
            mode=start,
            records=rec,
            n_events=0,
            n_hits=0,
            n_dense=0,
            n_events_total=0,
            counters=Counters(),
            integrator_time=seconds,
            stopped=False,
            t0=float(t0),
            start_mode=start,
        )
    t = np.asarray(res.t, dtype=float)
    ys = np.asarray(res.y, dtype=float)
    if not np.all(np.isfinite(ys)):
        bad = int(np.argmax(~np.all(np.isfinite(ys), axis=1)))
        t, ys = t[:bad], ys[:bad]
        modes = None if res.modes is None else np.asarray(res.modes)[:bad]
        impulses = None if res.impulses is None else np.asarray(res.impulses)[:bad]
        status, message = Status.INTEGRATOR_FAILURE, f"non-finite state after t = {t[-1] if t.size else t0:.6g}"
        if t.size == 0:
            t, ys = np.array([float(t0)]), y.reshape(1, -1)
    else:
        modes, impulses, status, message = res.modes, res.impulses, res.status, res.message
    ev = infer_events(
        problem,
        t,
        ys,
        modes,
        float(integ.stick_band(problem)),
        impulses,
        switch_times=res.switch_times,
        switch_elements=res.switch_elements,
    )
    k = len(ev)
    while rec.events.t.shape[0] < k:
        rec.grow_events(0)
    rec.events.t[:k], rec.events.kind[:k], rec.events.index[:k] = ev.t, ev.kind, ev.block
    rec.events.y[:k], rec.events.mode[:k] = ev.y, ev.mode
    hits = section_hits(sections, t, ys)
    if len(hits) > rec.hits.t.shape[0]:
        rec.grow_hits(0, len(hits))
    for j, (index, th, yh) in enumerate(hits):
        rec.hits.index[j], rec.hits.t[j], rec.hits.y[j] = index, th, yh
    n_dense = int(np.searchsorted(grid, t[-1], side="right"))
    if n_dense:
        if res.y_eval is not None and status.ok:
            rec.dense.y[:n_dense] = np.asarray(res.y_eval, dtype=float)[:n_dense]
        else:
            for j in range(n):
                rec.dense.y[:n_dense, j] = np.interp(grid[:n_dense], t, ys[:, j])
    internal = None
    if res.internal is not None and len(res.internal_names):  # the method's own states, step by step
        import pandas as pd

        cols = np.asarray(res.internal, dtype=float)[: t.size]
        internal = pd.DataFrame({"t": t, **{name: cols[:, j] for j, name in enumerate(res.internal_names)}})
    counters = Counters(nfev=int(res.nfev), njev=int(res.njev), nsteps=int(res.nsteps), n_events=k)
    counters.extra.update({key: value for key, value in (res.extra or {}).items()})
    final_mode = tuple(int(v) for v in (ev.mode[-1] if k else ev.start_mode))
    if status is Status.BUDGET_EXHAUSTED and not message:
        message = f"{max_steps} steps used by t = {t[-1]:.6g}"
    return RawRun(
        status=status,
        message=message,
        t=float(t[-1]),
        t_lo=0.0,
        y=ys[-1].copy(),
        mode=final_mode,
        records=rec,
        n_events=k,
        n_hits=len(hits),
        n_dense=n_dense,
        n_events_total=k,
        counters=counters,
        integrator_time=seconds,
        stopped=False,
        t0=float(t0),
        start_mode=tuple(int(v) for v in ev.start_mode),
        internal=internal,
        located_t=ev.located,
    )
