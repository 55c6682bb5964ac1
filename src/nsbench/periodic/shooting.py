"""Periodic orbits by single shooting across the events, and their Floquet multipliers.

An orbit is found by Newton's method on the map ``y0 -> y(t0 + T)`` of
:class:`~nsbench.periodic.flow.HybridFlow`:

- *forced* problems: ``T = p 2 pi / Omega`` is fixed and the unknowns are the
  free components of ``y0`` (a stuck block's velocity is ``v0``, not an unknown);
- *autonomous* problems: ``T`` is an unknown too, and the phase condition
  ``f(y_ref) . (y0 - y_ref) = 0`` (a plane through the previous solution,
  across the flow) removes the shift along the orbit.

The start point lies in the middle of the orbit's longest arc, away from every
event, so the shooting map is smooth near the solution; after each solve the
orbit is re-anchored there (:func:`anchor`). The Jacobian is the product of
state-transition and saltation matrices (:meth:`HybridFlow.jacobian`).

Multipliers: forced, the eigenvalues of the monodromy matrix on the free
components; autonomous, those of the Poincare map on the plane across the flow
(the monodromy projected along the flow onto the plane ``f(y0)^T dy = 0``),
which drops the trivial multiplier 1. A block stuck at the start contributes no
multiplier; a stick phase elsewhere on the orbit contributes a multiplier 0
(the saltation matrix of a stick erases that block's velocity perturbation).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from nsbench.errors import NsbenchError
from nsbench.periodic.flow import Crossing, HybridFlow, Pass, free_components, is_friction
from nsbench.problems.modes import Mode

if TYPE_CHECKING:  # pragma: no cover
    from nsbench.problems.base import HybridProblem


class ShootingError(NsbenchError, ArithmeticError):
    """No periodic orbit was found (Newton did not converge, or the motion has no events)."""


def canonical_pattern(pattern: tuple[str, ...]) -> tuple[str, ...]:
    """The lexicographically smallest rotation of a cyclic event pattern (independent of the start point)."""
    if not pattern:
        return pattern
    return min(pattern[k:] + pattern[:k] for k in range(len(pattern)))


@dataclass(frozen=True)
class PeriodicOrbit:
    """A converged periodic orbit.

    Attributes
    ----------
    problem
        The problem (its coefficient values are the orbit's parameter values).
    t0, y0, mode0
        The start point (mid-arc) and its mode.
    period
        Period in time.
    forced
        Whether the problem is forced (``period`` is then a multiple of ``2 pi / Omega``).
    events
        The events of one period from ``t0``.
    pattern
        The cyclic event pattern, rotated to its smallest form (``('slip2', 'stick2')``).
    monodromy
        ``d y(t0 + T) / d y0`` on the free components.
    multipliers
        Floquet multipliers, largest modulus first (the trivial 1 of an autonomous orbit removed).
    residual, iterations
        Final periodicity residual (max norm) and Newton iterations.
    """

    problem: HybridProblem
    t0: float
    y0: np.ndarray
    mode0: Mode
    period: float
    forced: bool
    events: tuple[Crossing, ...]
    pattern: tuple[str, ...]
    monodromy: np.ndarray
    multipliers: np.ndarray
    residual: float
    iterations: int
    free: np.ndarray = field(repr=False, default_factory=lambda: np.empty(0, int))

    @property
    def max_multiplier(self) -> float:
        """Largest multiplier modulus (0 for an orbit without free directions)."""
        return float(np.max(np.abs(self.multipliers))) if self.multipliers.size else 0.0

    @property
    def stable(self) -> bool:
        return self.max_multiplier < 1.0

    @property
    def unstable_count(self) -> int:
        """Multipliers outside the unit circle."""
        return int(np.count_nonzero(np.abs(self.multipliers) > 1.0))

    @property
    def forcing_periods(self) -> int | None:
        """``p`` of a forced orbit: its period in forcing periods."""
        if not self.forced:
            return None
        return int(round(self.period * self.problem.forcing_frequency / (2.0 * math.pi)))

    def pattern_text(self) -> str:
        return " ".join(self.pattern)

    def pattern_brief(self, shown: int = 8) -> str:
        """The pattern for messages: in full up to ``shown`` events, else its start and its length."""
        if len(self.pattern) <= shown:
            return self.pattern_text()
        return f"{' '.join(self.pattern[:shown])} ... ({len(self.pattern)} events)"


def _phase_normal(flow: HybridFlow, t0: float, y0: np.ndarray, mode0: Mode, free: np.ndarray) -> np.ndarray:
    return np.asarray(flow.problem.rhs(mode0, t0, y0), dtype=float)[free]


def multipliers(monodromy: np.ndarray, forced: bool, normal: np.ndarray | None = None) -> np.ndarray:
    """Floquet multipliers of a monodromy matrix (see the module docstring), largest modulus first."""
    m = np.asarray(monodromy, dtype=float)
    if m.size == 0:
        return np.empty(0, complex)
    if not forced:
        n = np.asarray(normal, dtype=float)
        nn = float(n @ n)
        if nn == 0.0:
            raise ShootingError("the start point is an equilibrium (zero vector field): no orbit to shoot")
        # Poincare map on the plane n^T dy = 0: project the image along the flow, restrict to the plane.
        f_end = m @ n  # the flow direction is carried to itself on a periodic orbit; m n = n up to rounding
        proj = np.eye(len(n)) - np.outer(f_end, n) / float(n @ f_end)
        q, _ = np.linalg.qr(np.column_stack([n, np.eye(len(n))]))
        basis = q[:, 1 : len(n)]
        m = basis.T @ proj @ m @ basis
    mu = np.linalg.eigvals(m) if m.size else np.empty(0, complex)
    return mu[np.argsort(-np.abs(mu), kind="stable")]


def shoot(
    flow: HybridFlow,
    t0: float,
    y0,
    mode0: Mode,
    period: float,
    *,
    forced: bool | None = None,
    tol: float = 1e-11,
    max_iter: int = 25,
) -> PeriodicOrbit:
    """Newton's method for a periodic orbit through (near) ``y0`` at ``t0`` with period (near) ``period``.

    Parameters
    ----------
    flow
        The hybrid flow of the problem.
    t0, y0, mode0
        Start guess; ``mode0`` is kept for the start point (pick it mid-arc, see :func:`anchor`).
    period
        Period guess (autonomous) or the exact period (forced: a multiple of the forcing period).
    forced
        Default: whether the problem is forced.
    tol
        Converged when the max-norm Newton update and periodicity residual fall below
        ``tol * (1 + |y0|)``.

    Raises
    ------
    ShootingError
        No convergence within ``max_iter`` iterations, or the flow failed.
    """
    problem = flow.problem
    forced = problem.is_forced if forced is None else forced
    mode0 = tuple(int(m) for m in mode0)
    free = free_components(problem, mode0)
    y = np.array(y0, dtype=float)
    if is_friction(problem):
        for i, phase in enumerate(mode0):
            if phase == 0:
                y[2 * i + 1] = problem.v0
    y_ref = y.copy()
    normal = _phase_normal(flow, t0, y_ref, mode0, free)
    T = float(period)
    scale = 1.0 + float(np.max(np.abs(y)))
    nf = free.size

    def residual(y_try, T_try) -> tuple[np.ndarray, Pass]:
        p = flow.run(t0, y_try, mode0, T_try)
        r = (p.y - y_try)[free]
        if not forced:
            r = np.append(r, normal @ (y_try - y_ref)[free])
        return r, p

    try:
        r, p = residual(y, T)
    except ArithmeticError as exc:
        raise ShootingError(f"the flow failed at the start guess: {exc}") from None
    for it in range(1, max_iter + 1):
        jac = flow.jacobian(p)[np.ix_(free, free)]
        a = jac - np.eye(nf)
        if not forced:
            f_end = np.asarray(problem.rhs(p.mode, t0 + T, p.y), dtype=float)[free]
            a = np.block([[a, f_end[:, None]], [normal[None, :], np.zeros((1, 1))]])
        try:
            step = np.linalg.solve(a, -r)
        except np.linalg.LinAlgError:
            raise ShootingError(f"singular shooting Jacobian at iteration {it}") from None
        norm0 = float(np.max(np.abs(r)))
        lam = 1.0
        for _ in range(8):  # backtracking: a full step may cross into another event pattern
            y_new = y.copy()
            y_new[free] += lam * step[:nf]
            T_new = T + (lam * step[nf] if not forced else 0.0)
            if T_new > 0:
                try:
                    r_new, p_new = residual(y_new, T_new)
                except ArithmeticError:
                    r_new = None
                if r_new is not None and (float(np.max(np.abs(r_new))) < norm0 or norm0 < tol * scale):
                    break
            lam *= 0.5
        else:
            raise ShootingError(f"Newton stalled at iteration {it} (residual {norm0:.3g})")
        y, T, r, p = y_new, T_new, r_new, p_new
        done = float(np.max(np.abs(lam * step))) <= tol * scale and float(np.max(np.abs(r))) <= 10 * tol * scale
        if done:
            shorter = _shorter_period(flow.problem, p, T, forced, scale)
            if shorter is None and forced and not p.events:
                shorter = _shorter_eventless(flow, t0, y, mode0, T, scale)
            if shorter is not None:  # converged to a repetition of a shorter orbit: solve that one
                return shoot(flow, t0, y, mode0, shorter, forced=forced, tol=tol, max_iter=max_iter)
            return _orbit(flow, t0, y, mode0, T, forced, p, free, float(np.max(np.abs(r))), it)
    raise ShootingError(f"Newton did not converge in {max_iter} iterations (residual {float(np.max(np.abs(r))):.3g})")


def _shorter_period(problem, p: Pass, T: float, forced: bool, scale: float) -> float | None:
    """The shortest period ``T / d`` (``d > 1``) the converged pass repeats with, if any."""
    ev = p.events
    n = len(ev)
    tf = 2.0 * math.pi / problem.forcing_frequency if forced else None
    for d in range(n, 1, -1) if n else ():
        if n % d:
            continue
        q = n // d
        if tf is not None and abs(T / d / tf - round(T / d / tf)) > 1e-9:
            continue
        if all(
            ev[k].kind == ev[k + q].kind
            and ev[k].block == ev[k + q].block
            and float(np.max(np.abs(ev[k].y - ev[k + q].y))) <= 1e-8 * scale
            for k in range(n - q)
        ):
            return T / d
    return None


def _shorter_eventless(flow: HybridFlow, t0: float, y: np.ndarray, mode0: Mode, T: float, scale: float):
    """One forcing period, if a forced orbit without events (nothing for :func:`_shorter_period` to
    compare) already returns to its start after it."""
    tf = 2.0 * math.pi / flow.problem.forcing_frequency
    if T < 1.5 * tf:
        return None
    p = flow.run(t0, y, mode0, tf)
    return tf if not p.events and float(np.max(np.abs(p.y - y))) <= 1e-8 * scale else None


def _orbit(flow, t0, y, mode0, T, forced, p: Pass, free, res, it) -> PeriodicOrbit:
    if p.mode != mode0:
        raise ShootingError(f"the orbit returns in mode {p.mode}, not its start mode {mode0}")
    jac = flow.jacobian(p)[np.ix_(free, free)]
    normal = None if forced else _phase_normal(flow, t0, y, mode0, free)
    mu = multipliers(jac, forced, normal)
    return PeriodicOrbit(
        flow.problem,
        float(t0),
        y.copy(),
        mode0,
        float(T),
        forced,
        p.events,
        canonical_pattern(p.pattern),
        jac,
        mu,
        res,
        it,
        free,
    )


def restart(flow: HybridFlow, orbit: PeriodicOrbit, t0: float, y0: np.ndarray, mode0: Mode) -> PeriodicOrbit:
    """``orbit`` seen from another of its points ``(t0, y0, mode0)``: one period's events and monodromy."""
    p = flow.run(t0, y0, mode0, orbit.period)
    free = free_components(flow.problem, mode0)
    scale = 1.0 + float(np.max(np.abs(y0)))
    res = float(np.max(np.abs((p.y - np.asarray(y0))[free])))
    if res > 1e-8 * scale:  # pragma: no cover - a point of a converged orbit returns to itself
        return shoot(flow, t0, y0, mode0, orbit.period, forced=orbit.forced)
    return _orbit(
        flow, t0, np.asarray(y0, dtype=float), mode0, orbit.period, orbit.forced, p, free, res, orbit.iterations
    )


def anchor(flow: HybridFlow, orbit: PeriodicOrbit) -> tuple[float, np.ndarray, Mode]:
    """A start point in the middle of the orbit's longest arc: ``(t, y, mode)``.

    A start point far from every event keeps the shooting map smooth while the
    parameter moves; for a forced orbit the time moves with it (the period does not).
    """
    return _anchor(flow, orbit.t0, orbit.y0, orbit.mode0, orbit.period, orbit.events)


def _anchor(flow, t0, y0, mode0, period, events, at_event: bool = False) -> tuple[float, np.ndarray, Mode]:
    """The middle of the longest arc of one period from ``(t0, y0, mode0)``: a start off every guard.

    ``at_event`` says that ``t0`` is itself an event (a guess starts at one): then the arcs before the
    first event and after the last are two arcs, not the two halves of one arc through ``t0``. Joined,
    their middle would be that event whenever they are equally long (the two half-periods of a
    symmetric relay orbit), and a start on a switching surface makes the return map jump under any
    change of the parameter (Newton stalls at every continuation step).
    """
    if not events:
        return t0, y0, mode0
    t_end = t0 + period
    starts = [t0] + [e.t for e in events]
    ends = [e.t for e in events] + [t_end]
    k = int(np.argmax(np.subtract(ends, starts)))
    if at_event and k == 0:
        p = flow.run(t0, y0, mode0, 0.5 * (ends[0] - t0))
        return t0 + 0.5 * (ends[0] - t0), p.y, p.mode
    if not at_event and (k == 0 or k == len(events)):  # the arc through t0 wraps around the period
        first, last = events[0].t - t0, t_end - events[-1].t
        half = 0.5 * (first + last)
        if half <= last:
            p = flow.run(events[-1].t, events[-1].y, events[-1].mode_after, half)
            return events[-1].t + half, p.y, p.mode
        p = flow.run(t0, y0, mode0, half - last)
        return t0 + (half - last), p.y, p.mode
    e = events[k - 1]
    half = 0.5 * (ends[k] - starts[k])
    p = flow.run(e.t, e.y, e.mode_after, half)
    return e.t + half, p.y, p.mode


def resolve(flow: HybridFlow, orbit: PeriodicOrbit) -> PeriodicOrbit | None:
    """``orbit`` re-solved from its own start point on the flow's current problem, or ``None``.

    The period of a forced orbit follows the forcing period of the new problem.
    """
    period = orbit.period
    p = orbit.forcing_periods
    if p is not None:  # a forced orbit
        period = p * 2.0 * math.pi / flow.problem.forcing_frequency
    try:
        return shoot(flow, orbit.t0, orbit.y0, orbit.mode0, period, forced=orbit.forced)
    except ShootingError:
        return None


def _recurrence(events: tuple[Crossing, ...], tol: float) -> int:
    """Smallest ``q`` such that the last events repeat every ``q`` (kind, block and state within ``tol``)."""
    n = len(events)
    for q in range(1, n // 3 + 1):
        if all(
            events[k].kind == events[k + q].kind
            and events[k].block == events[k + q].block
            and float(np.max(np.abs(events[k].y - events[k + q].y))) <= tol
            for k in range(n - 2 * q, n - q)
        ):
            return q
    return 0


def guess(
    flow: HybridFlow,
    *,
    transient: float = 1500.0,
    window: float = 1000.0,
    y0=None,
    t0: float = 0.0,
    max_periods: int = 64,
    tol: float = 1e-6,
) -> tuple[float, np.ndarray, Mode, float]:
    """A start guess ``(t, y, mode, period)`` for :func:`shoot` from a simulation.

    Integrates from ``y0`` (default: rest at the origin) through ``transient``.
    Autonomous problems: the smallest repeating block of the events within the
    next ``window`` time units gives the period. Forced problems: the
    stroboscopic state is compared after each forcing period, up to
    ``max_periods``. The start is the middle of the longest arc of that period.

    Raises
    ------
    ShootingError
        No event after the transient (steady sliding: no orbit to shoot) or no
        repetition within ``tol`` (aperiodic, or longer than the window).
    """
    problem = flow.problem
    y = problem.initial_state() if y0 is None else np.asarray(y0, dtype=float)
    mode = problem.initial_mode(t0, y)
    if problem.is_forced:
        tf = 2.0 * math.pi / problem.forcing_frequency
        t = tf * math.ceil((t0 + transient) / tf - 1e-12)
        start = flow.run(t0, y, mode, t - t0)
        cur, cur_mode = start.y, start.mode
        for k in range(1, max_periods + 1):
            step = flow.run(t + (k - 1) * tf, cur, cur_mode, tf)
            cur, cur_mode = step.y, step.mode
            if float(np.max(np.abs(cur - start.y))) <= tol and cur_mode == start.mode:
                whole = flow.run(t, start.y, start.mode, k * tf)
                return (*_anchor(flow, t, start.y, start.mode, k * tf, whole.events), k * tf)
        raise ShootingError(
            f"the stroboscopic point does not repeat within {max_periods} forcing periods "
            f"(tolerance {tol:g}): aperiodic, or a longer period"
        )
    first = flow.run(t0, y, mode, transient)
    seen = flow.run(t0 + transient, first.y, first.mode, window)
    if not seen.events:
        raise ShootingError(
            f"no event between t = {t0 + transient:g} and {t0 + transient + window:g}: "
            "the motion settles to steady sliding, which has no periodic orbit to shoot"
        )
    q = _recurrence(seen.events, tol)
    if q == 0:
        raise ShootingError(
            f"the {len(seen.events)} events after the transient do not repeat (tolerance {tol:g}): "
            "aperiodic, or a period longer than a third of the window"
        )
    last = seen.events[-1]
    begin = seen.events[-1 - q]
    period = last.t - begin.t
    whole = flow.run(begin.t, begin.y, begin.mode_after, period)
    return (*_anchor(flow, begin.t, begin.y, begin.mode_after, period, whole.events, at_event=True), period)


def find_orbit(flow: HybridFlow, **kwargs) -> PeriodicOrbit:
    """The periodic orbit the motion from rest (or ``y0``) settles on: :func:`guess`, then :func:`shoot`."""
    shoot_keys = {"tol", "max_iter"}
    t, y, mode, period = guess(flow, **{k: v for k, v in kwargs.items() if k not in shoot_keys})
    return shoot(flow, t, y, mode, period, **{k: v for k, v in kwargs.items() if k in shoot_keys})
