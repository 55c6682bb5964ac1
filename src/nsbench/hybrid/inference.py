"""Switching events of a whole-system method, inferred from its discrete trajectory.

A whole-system method (:mod:`nsbench.integrators.whole`) returns its steps
``(t_k, y_k)`` and, where it knows it, the mode of each step. :func:`infer_events`
turns them into the event log an event-driven run records, by this rule (the
friction family; ``u_i = v_i - v_belt``, ``b`` the method's stick band,
:meth:`~nsbench.integrators.whole.WholeSystem.stick_band`):

1. **The mode of a step** is the method's own (Moreau-Jean's status, the switch
   model's stick set); a method that does not know it (smoothing) has each block
   stuck where ``|u_i| <= b`` and slipping with the sign of ``u_i`` elsewhere.
2. **An event** is a change of a block's phase between two consecutive steps
   ``k`` and ``k+1``: ``stick`` (slip to stick), ``slip`` (stick to slip) or
   ``reverse`` (slip+ to slip- or back, without a stuck step between). A
   stuck phase of a single step, between two slipping ones, at which the
   static limit is already exceeded (the stick mode's guard of rule 3 is past
   zero there) is how a time-stepping method passes through the belt speed
   (its impulse absorbs the momentum of one step): it is read as slipping on,
   so the two changes make one ``reverse``, as in the event-driven model.
3. **Its time** is where a guard, interpolated linearly between the two steps,
   crosses zero: ``u_i`` for a reversal; ``|u_i| - b`` for entering stick (with
   ``b = 0`` that is the step where the method set ``u_i = 0``) and, with ``b > 0``,
   for leaving it; with ``b = 0``, leaving stick is placed where the stick mode's
   guard of the event-driven model (``R_i - fr_i`` for slip-, ``R_i + fr_i`` for
   slip+, evaluated with ``v_i = v_belt``) crosses zero. A guard already past
   zero at step ``k`` places the event at ``t_k``, one not yet at zero at step
   ``k+1`` at ``t_{k+1}``: an event never leaves the step where the phase changed.
4. **Its state** is the linear interpolation of the two steps at that time, with
   ``v_i = v_belt`` set at a ``stick`` and a ``reverse`` (MODEL.md's convention);
   its mode is the mode before with block ``i``'s new phase. Several blocks
   changing in one step give one event each, in time order (ties: lower block first).

5. **Impact problems** (the bouncing ball, one contact): the method reports the impulse
   of each step. An ``impact`` is a step with a positive impulse while the ball
   approaches (``v < 0`` at the step's start), placed at the zero of the height's line
   between the two steps, with ``x = 0`` and the post-impact velocity; a change of the
   method's mode to resting is a ``rest`` event at that step (``v = 0``), after which
   its impulses are resting contact, not impacts.

The interpolation is first order, as are the methods: it adds an error of at
most one step to a switching time, and none where the guard is linear in time
over the step (a stuck block's force under a constant load). :func:`run_whole`
runs a method and packs all of it into the records of an event-driven run.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
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


@dataclass
class InferredEvents:
    """Events inferred from a trajectory, as arrays (one row per event, in time order)."""

    t: np.ndarray
    kind: np.ndarray  # codes into problem.event_kinds
    block: np.ndarray  # 0-based element index
    y: np.ndarray  # (n_events, n_states): state after the event
    mode: np.ndarray  # (n_events, mode_size): mode after the event
    start_mode: np.ndarray  # mode of the first step

    def __len__(self) -> int:
        return int(self.t.size)


def band_modes(problem: "HybridProblem", y: np.ndarray, band: float) -> np.ndarray:
    """Rule 1 without the method's modes: per step and block, 0 where ``|v_i - v_belt| <= band``, else its sign."""
    u = np.asarray(y)[:, 1::2] - problem.v0
    out = np.sign(u).astype(np.int64)
    out[np.abs(u) <= band] = STICK
    return out


def _line_zero(ta: float, a: float, tb: float, b: float, lo: float, hi: float) -> float:
    """Zero of the line through ``(ta, a)`` and ``(tb, b)``, kept within ``[lo, hi]`` (``hi`` if the line is flat)."""
    if a == b:
        return hi
    return min(max(ta + a / (a - b) * (tb - ta), lo), hi)


def _stick_guard(problem, mode_before: np.ndarray, block: int, new: int, t: float, y: np.ndarray) -> float:
    """The stick mode's guard of ``block`` towards phase ``new`` (rule 3, ``b = 0``), positive while stuck."""
    kind = "upper" if new < 0 else "lower"  # R reaches +fr: slip backwards (slip-); -fr: slip+
    guards = problem.guards(tuple(int(v) for v in mode_before))
    guard = next((g for g in guards if g.block == block + 1 and g.kind == kind), None)
    if guard is None:
        return 0.0
    state = np.array(y, dtype=float)
    state[2 * block + 1] = problem.v0
    return guard.expected_sign * float(guard.value(t, state))


def _pass_through(problem, t: np.ndarray, y: np.ndarray, m: np.ndarray) -> None:
    """Rule 2's exception, in place: a one-step stick past its static limit, between slips, becomes a slip."""
    if len(t) < 3:
        return
    one = (m[1:-1] == STICK) & (m[:-2] != STICK) & (m[2:] != STICK)
    for j, i in zip(*np.nonzero(one)):
        k = j + 1
        if _stick_guard(problem, m[k], int(i), int(m[k + 1, i]), t[k], y[k]) < 0.0:
            m[k, i] = m[k + 1, i]


def _impact_events(
    problem, t: np.ndarray, y: np.ndarray, modes: np.ndarray | None, impulses: np.ndarray | None
) -> InferredEvents:
    """Rule 5 (impact problems, one contact: the bouncing ball): see the module docstring."""
    k = len(t)
    m = np.zeros((k, 1), np.int64) if modes is None else np.asarray(modes, dtype=np.int64)
    p = np.zeros((k, 1)) if impulses is None else np.asarray(impulses, dtype=float).reshape(k, -1)
    impact, rest = problem.event_kinds.index("impact"), problem.event_kinds.index("rest")
    out_t, out_k, out_y, out_m = [], [], [], []
    for j in range(1, k):
        if m[j, 0] != m[j - 1, 0]:
            out_t.append(float(t[j]))
            out_k.append(rest)
            out_y.append(np.array([y[j, 0], 0.0]))
            out_m.append(m[j].copy())
        elif m[j, 0] == 0 and p[j, 0] > 0.0 and y[j - 1, 1] < 0.0:
            out_t.append(_line_zero(t[j - 1], y[j - 1, 0], t[j], y[j, 0], t[j - 1], t[j]))
            out_k.append(impact)
            out_y.append(np.array([0.0, y[j, 1]]))
            out_m.append(m[j].copy())
    n = len(out_t)
    return InferredEvents(
        t=np.array(out_t, dtype=float),
        kind=np.array(out_k, dtype=np.int64),
        block=np.zeros(n, np.int64),
        y=np.array(out_y, dtype=float).reshape(-1, 2),
        mode=np.array(out_m, dtype=np.int64).reshape(-1, 1),
        start_mode=m[0].copy(),
    )


def infer_events(
    problem: "HybridProblem",
    t: np.ndarray,
    y: np.ndarray,
    modes: np.ndarray | None,
    band: float = 0.0,
    impulses: np.ndarray | None = None,
) -> InferredEvents:
    """The events of the discrete trajectory ``(t, y)`` by the rule of this module's docstring.

    Parameters
    ----------
    problem
        A problem of the friction family.
    t, y
        Step times ``(k,)`` and states ``(k, n_states)``.
    modes
        The method's mode of each step ``(k, mode_size)``, or ``None`` (read off the band).
    band
        The method's stick band ``b >= 0``.
    impulses
        Impact problems: the impulse of each step (rule 5).
    """
    t = np.asarray(t, dtype=float)
    y = np.asarray(y, dtype=float)
    if not band >= 0.0:
        raise ValueError(f"stick band {band!r} must be >= 0")
    if problem.family == "impact":
        return _impact_events(problem, t, y, modes, impulses)
    if modes is None:
        m = band_modes(problem, y, band)
    else:
        m = np.array(modes, dtype=np.int64)
        _pass_through(problem, t, y, m)
    kinds = problem.event_kinds
    code = {name: kinds.index(name) for name in ("stick", "slip", "reverse")}
    v0 = problem.v0
    changed = np.flatnonzero(np.any(m[1:] != m[:-1], axis=1)) if len(t) > 1 else np.zeros(0, np.int64)
    running = m[0].copy()
    out_t, out_k, out_b, out_y, out_m = [], [], [], [], []
    for k in changed:
        t0, t1 = t[k], t[k + 1]
        step = []
        lo = t[k - 1] if k > 0 else t0
        for i in np.flatnonzero(m[k] != m[k + 1]):
            p, q = int(m[k, i]), int(m[k + 1, i])
            u0, u1 = y[k, 2 * i + 1] - v0, y[k + 1, 2 * i + 1] - v0
            if p != STICK and q != STICK:
                kind = "reverse"
                te = _line_zero(t0, u0, t1, u1, t0, t1)
            elif q == STICK:
                kind = "stick"
                if band == 0.0 and u1 == 0.0 and k > 0 and m[k - 1, i] == p:
                    # the method pinned u = 0 at step k+1, which says nothing of when it got there:
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
                    a = _stick_guard(problem, m[k], int(i), q, t0, y[k])
                    b = _stick_guard(problem, m[k], int(i), q, t1, y[k + 1])
                    te = _line_zero(t0, a, t1, b, lo, t1)
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
    n, ms = y.shape[1], m.shape[1]
    return InferredEvents(
        t=np.array(out_t, dtype=float),
        kind=np.array(out_k, dtype=np.int64),
        block=np.array(out_b, dtype=np.int64),
        y=np.array(out_y, dtype=float).reshape(-1, n),
        mode=np.array(out_m, dtype=np.int64).reshape(-1, ms),
        start_mode=m[0].copy(),
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
    ev = infer_events(problem, t, ys, modes, float(integ.stick_band(problem)), impulses)
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
    )
