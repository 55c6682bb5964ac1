"""The hybrid flow over a fixed time with its Jacobian: state-transition and saltation matrices.

:class:`HybridFlow` runs a problem with one set-up integrator through the
engine (:func:`nsbench.engine.run`: ``nsbench.simulate``'s defaults and its
missed-crossing check, so a run that steps over a crossing fails instead of
giving a wrong orbit) from a start time, state and mode over a given span, and returns
the :class:`Pass`: the end state and mode, and every event with the mode
before and after it. :meth:`HybridFlow.jacobian` then gives the derivative of
the end state with respect to the start state as the ordered product

    Phi_last S_k Phi_k ... S_1 Phi_1

of each arc's state-transition matrix ``Phi`` (the exact matrix exponential of
the mode's matrix for linear problems; the variational equations integrated
along the arc otherwise) and each event's saltation matrix ``S``
(:func:`saltation`). The event times come from the integrator (``exact`` for
linear problems, heyoka in double at machine tolerance otherwise); the
Jacobian is only used for Newton steps and multipliers, so it need not be
more accurate than the flow.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.integrate
import scipy.linalg

from nsbench.errors import ConfigError
from nsbench.problems.base import problem_traits
from nsbench.problems.modes import STICK, Guard, Mode

#: Integrator of the flow by default: exact event times for linear problems.
LINEAR_FLOW: tuple[str, dict[str, Any]] = ("exact", {})
#: heyoka in double at its own epsilon (event times to a few ulp) for cubic springs.
NONLINEAR_FLOW: tuple[str, dict[str, Any]] = ("heyoka", {})


@dataclass(frozen=True)
class Crossing:
    """One event of a pass: time, kind, block, state after it, the modes around it and the guard."""

    t: float
    kind: str
    block: int
    y: np.ndarray
    mode_before: Mode
    mode_after: Mode
    guard: Guard  # the guard that fired (its kind: "velocity", "upper" or "lower")


@dataclass(frozen=True)
class Pass:
    """The flow from ``(t0, y0, mode0)`` over ``span``: where it ended and what happened on the way."""

    t0: float
    y0: np.ndarray
    mode0: Mode
    span: float
    y: np.ndarray
    mode: Mode
    events: tuple[Crossing, ...]

    @property
    def pattern(self) -> tuple[str, ...]:
        """Event names in order, e.g. ``('stick2', 'slip2')``."""
        return tuple(f"{e.kind}{e.block}" for e in self.events)


def is_friction(problem) -> bool:
    """Whether ``problem`` is a friction oscillator (blocks with stick and slip phases)."""
    return problem_traits(problem).belt_blocks


def guard_of(kind: str, block: int, problem, t: float, y: np.ndarray, mode_before: Mode) -> Guard:
    """The guard that fired for an event of ``kind`` (MODEL.md: stick and reverse end a slip phase on
    ``v - v0``; a slip ends a stick phase on ``R - fr`` (upper) or ``R + fr`` (lower)).

    Other families: the only guard of ``mode_before``, or of several the one nearest zero at the
    event (the resets of the impact oscillator and the relay leave the guard's own variables on
    the surface)."""
    if not is_friction(problem):
        guards = problem.guards(mode_before)
        if not guards:
            raise ConfigError(f"mode {mode_before} has no guard to explain a {kind} event")
        return min(guards, key=lambda g: abs(float(g.value(t, y))))
    for g in problem.guards(mode_before):
        if g.block != block:
            continue
        if kind in ("stick", "reverse") and g.kind == "velocity":
            return g
        if kind == "slip" and g.kind != "velocity":
            r = float(problem.restoring_force(block, t, y))
            if (g.kind == "upper") == (r > 0.0):
                return g
    raise ConfigError(f"no guard of mode {mode_before} explains a {kind} event of block {block}")


def saltation(
    problem, guard: Guard, mode_before: Mode, mode_after: Mode, t: float, y: np.ndarray, kind: str = ""
) -> np.ndarray:
    """Saltation matrix of an event: how a perturbation just before the switch maps to one just after.

    ``S = I + (f+ - f-) grad(g)^T / (dg/dt)`` with ``f-``, ``f+`` the vector fields of
    the modes before and after, ``g`` the guard that fired and ``dg/dt = grad(g) . f- + dg/dt|explicit``
    its rate of change just before the event. The resets of MODEL.md (``v_i = v0`` at a stick or a
    reverse) only remove rounding, so the reset map's derivative is the identity on the
    surface; at a stick the formula sends the ``v_i`` perturbation to zero, which is the
    stuck block's lost dimension.

    Other (piecewise-linear) families: :func:`event_saltation`, with the event's ``kind``.
    """
    if not is_friction(problem):
        return event_saltation(problem, guard, kind, mode_before, mode_after, t, y)
    n = problem.n_states
    f_minus = problem.rhs(mode_before, t, y)
    f_plus = problem.rhs(mode_after, t, y)
    grad = np.zeros(n)
    i = guard.block - 1
    if guard.kind == "velocity":
        grad[2 * i + 1] = 1.0
    else:
        # R_i's gradient: the velocity row of a slip mode's Jacobian is -grad(R_i) / m_i.
        slip = tuple(-1 if q == i else p for q, p in enumerate(mode_before))
        grad = -problem.coefficients.m[i] * problem.jacobian(slip, t, y)[2 * i + 1]
    rate = float(guard.rate(t, y, f_minus))
    if rate == 0.0:
        raise ArithmeticError(f"grazing event ({guard.name} touches zero with zero slope at t = {t:.17g})")
    return np.eye(n) + np.outer(f_plus - f_minus, grad) / rate


def event_saltation(
    problem, guard: Guard, kind: str, mode_before: Mode, mode_after: Mode, t: float, y_after: np.ndarray
) -> np.ndarray:
    """Saltation matrix of an event with a state reset ``y+ = R(y-)``:

    ``S = R_y + (f+(y+) - R_y f-(y-)) grad(g)^T / (dg/dt)``, ``dg/dt = grad(g) . f-(y-) + dg/dt|explicit``.

    The problem gives the state just before the event and ``R_y`` through
    ``problem.event_linearisation(kind, t, y_after)`` (the impact oscillator: ``v- = -v+ / r``,
    ``R_y = diag(1, -r)``; the relay: the state and the identity). A ``None`` from it
    means the event forgets every perturbation (a mass that sticks on the stop: its state there
    and its release time do not depend on where it came from), so ``S = 0``. The guard's gradient
    is read from :meth:`guard_row` (piecewise-linear problems).
    """
    n = problem.n_states
    y_after = np.asarray(y_after, dtype=float)
    found = problem.event_linearisation(kind, t, y_after)
    if found is None:
        return np.zeros((n, n))
    y_before, reset = found
    f_minus = np.asarray(problem.rhs(mode_before, t, y_before), dtype=float)
    f_plus = np.asarray(problem.rhs(mode_after, t, y_after), dtype=float)
    grad = np.asarray(problem.guard_row(mode_before, guard.code, guard.block - 1), dtype=float)[:n]
    rate = float(guard.rate(t, y_before, f_minus))
    if rate == 0.0:
        raise ArithmeticError(f"grazing event ({guard.name} touches zero with zero slope at t = {t:.17g})")
    return reset + np.outer(f_plus - reset @ f_minus, grad) / rate


class HybridFlow:
    """A problem's hybrid flow with one integrator, set up once and reused for every pass.

    Parameters
    ----------
    problem
        The problem (any registered friction oscillator).
    integrator, options
        Integrator of the flow; default ``exact`` for linear problems and ``heyoka``
        (double, machine tolerance) for cubic springs.
    """

    def __init__(self, problem, integrator: str | None = None, options: dict[str, Any] | None = None) -> None:
        from nsbench.engine import prepare
        from nsbench.integrators import get_integrator

        if not (is_friction(problem) or (problem.is_linear and hasattr(problem, "event_linearisation"))):
            raise ConfigError(
                f"{problem.name}: periodic orbits are computed for the friction oscillators and the "
                "piecewise-linear problems whose events say how they map perturbations "
                "(impact-oscillator, relay-feedback); this problem is neither"
            )
        if integrator is None:
            integrator, default = LINEAR_FLOW if problem.is_linear else NONLINEAR_FLOW
            options = {**default, **(options or {})}
        self.problem = problem
        self.integrator_name = integrator
        self.integ = get_integrator(integrator, **(options or {}))
        prepare(problem, self.integ)
        self._expm: dict[Mode, tuple] = {}

    def rebind(self, problem) -> None:
        """Use the same integrator on a problem with other coefficient values (continuation)."""
        self.problem = problem
        self.integ.setup(problem)
        self._expm.clear()

    def run(self, t0: float, y0: np.ndarray, mode0: Mode, span: float, max_events: int = 100_000) -> Pass:
        """The flow over ``[t0, t0 + span]`` with every event on the way.

        Run by :func:`nsbench.engine.run`, with ``nsbench.simulate``'s defaults and its
        missed-crossing check: a run that steps over a crossing is a failure, never a pass.

        Raises
        ------
        ArithmeticError
            The integrator did not reach the end (budget, event storm, a crossing missed, failure).
        """
        from nsbench.engine import run
        from nsbench.problems.modes import EVENT_KINDS

        if span == 0.0:  # no time to flow (a guess with no transient): the start itself, no run (the engine
            # refuses t_end = t0); the next pass from it applies the start rule as a run would
            y = np.asarray(y0, dtype=float).copy()
            return Pass(float(t0), y, tuple(int(m) for m in mode0), 0.0, y.copy(), tuple(int(m) for m in mode0), ())
        names = getattr(self.problem, "event_kinds", ()) or EVENT_KINDS
        raw = run(
            self.problem,
            self.integ,
            t0 + span,
            t0=t0,
            y0=np.asarray(y0, dtype=float),
            mode=mode0,
            max_events=max_events,
            max_steps=50_000_000,
        )
        _require_ok(raw)
        ev = raw.events
        events = []
        before = tuple(int(m) for m in mode0)
        for k in range(len(ev)):
            after = tuple(int(m) for m in ev.mode[k])
            kind, block, t, y = names[int(ev.kind[k])], int(ev.block[k]), float(ev.t[k]), ev.y[k].copy()
            guard = guard_of(kind, block, self.problem, t, y, before)
            events.append(Crossing(t, kind, block, y, before, after, guard))
            before = after
        return Pass(
            float(t0),
            np.asarray(y0, dtype=float).copy(),
            tuple(int(m) for m in mode0),
            float(span),
            raw.y.copy(),
            raw.mode,
            tuple(events),
        )

    def states(self, t0: float, y0: np.ndarray, mode0: Mode, times: np.ndarray) -> np.ndarray:
        """States at the sorted ``times`` (all ``>= t0``) of the flow from ``(t0, y0, mode0)``, shape ``(k, n)``."""
        from nsbench.engine import run

        times = np.ascontiguousarray(times, dtype=float)
        if times[-1] == t0:  # every time is the start (a one-period strobe of an orbit starting on it): y0
            # itself, no run (the engine refuses t_end = t0)
            return np.tile(np.asarray(y0, dtype=float), (times.size, 1))
        raw = run(
            self.problem,
            self.integ,
            float(times[-1]),
            t0=t0,
            y0=np.asarray(y0, dtype=float),
            mode=mode0,
            t_eval=times,
            max_steps=50_000_000,
        )
        _require_ok(raw)
        if len(raw.dense) < times.size:
            raise ArithmeticError(f"flow stopped at t = {raw.t:.6g} before its last requested time")
        return raw.dense.y.copy()

    # ------------------------------------------------------------------ Jacobian
    def arc_transition(self, mode: Mode, t0: float, y0: np.ndarray, dt: float) -> np.ndarray:
        """State-transition matrix of one arc in ``mode`` from ``(t0, y0)`` over ``dt``."""
        n = self.problem.n_states
        if dt <= 0.0:
            return np.eye(n)
        if self.problem.is_linear:
            # The forcing enters additively, so the transition matrix is expm(A dt) exactly:
            # from the mode's eigendecomposition (cached), or scipy's expm if that is ill-conditioned.
            modal = self._expm.get(mode)
            if modal is None:
                a, *_ = self.problem.linear_form(mode)
                lam, vec = np.linalg.eig(a)
                modal = self._expm[mode] = (
                    (a, lam, vec, np.linalg.inv(vec)) if np.linalg.cond(vec) < 1e6 else (a, None, None, None)
                )
            a, lam, vec, inv = modal
            if lam is None:
                return scipy.linalg.expm(a * dt)
            return ((vec * np.exp(lam * dt)) @ inv).real
        problem = self.problem

        def rhs(t, z):
            y, phi = z[:n], z[n:].reshape(n, n)
            return np.concatenate([problem.rhs(mode, t, y), (problem.jacobian(mode, t, y) @ phi).ravel()])

        z0 = np.concatenate([np.asarray(y0, dtype=float), np.eye(n).ravel()])
        sol = scipy.integrate.solve_ivp(rhs, (t0, t0 + dt), z0, method="DOP853", rtol=1e-12, atol=1e-12)
        if not sol.success:  # pragma: no cover - smooth arcs of a bounded orbit
            raise ArithmeticError(f"variational equations failed on an arc at t = {t0:.6g}: {sol.message}")
        return sol.y[n:, -1].reshape(n, n)

    def jacobian(self, p: Pass) -> np.ndarray:
        """``d y(t0 + span) / d y0`` at fixed times: arc transitions and saltation matrices in order."""
        problem = self.problem
        t, y, mode = p.t0, p.y0, p.mode0
        total = np.eye(problem.n_states)
        for e in p.events:
            total = self.arc_transition(mode, t, y, e.t - t) @ total
            total = saltation(problem, e.guard, e.mode_before, e.mode_after, e.t, e.y, e.kind) @ total
            t, y, mode = e.t, e.y, e.mode_after
        return self.arc_transition(mode, t, y, p.t0 + p.span - t) @ total


def free_components(problem, mode: Mode) -> np.ndarray:
    """State indices that may vary in ``mode``: a stuck block's velocity is ``v0``, not an unknown
    (other families: every component)."""
    if not is_friction(problem):
        return np.arange(problem.n_states)
    keep = [j for j in range(problem.n_states) if not (j % 2 == 1 and mode[j // 2] == STICK)]
    return np.array(keep, dtype=int)


def section_points(flow: HybridFlow, orbit, section: str) -> np.ndarray:
    """States where one period of ``orbit`` crosses a sweep's section, shape ``(p, n)``, in time order.

    ``section`` as in :mod:`nsbench.bifurcation.sweep`: ``peaks`` (local maxima of the first position,
    :func:`nsbench.sections.peaks`), ``strobe`` (``t = 2 pi k / Omega``), ``stick``, ``mapping`` (slip
    events) or ``event:KIND`` (the problem's ``KIND`` events).
    """
    from nsbench.engine import run
    from nsbench.sections import peaks

    problem = flow.problem
    if section in ("stick", "mapping") or section.startswith("event:"):
        kind = {"stick": "stick", "mapping": "slip"}.get(section) or section[len("event:") :]
        ys = [e.y for e in orbit.events if e.kind == kind]
        return np.array(ys).reshape(len(ys), problem.n_states)
    if section == "strobe":
        tf = 2.0 * np.pi / problem.forcing_frequency
        k0 = np.ceil(orbit.t0 / tf - 1e-12)
        times = tf * np.arange(k0, k0 + round(orbit.period / tf))
        return flow.states(orbit.t0, orbit.y0, orbit.mode0, times) if times.size else np.empty((0, problem.n_states))
    if section != "peaks":
        raise ConfigError(f"section {section!r} is not allowed; choose one of peaks, strobe, stick, mapping")
    raw = run(
        problem,
        flow.integ,
        orbit.t0 + orbit.period,
        t0=orbit.t0,
        y0=orbit.y0,
        mode=orbit.mode0,
        sections=[peaks(problem)],
        max_steps=50_000_000,
    )
    _require_ok(raw)  # the points of a run that failed (a crossing missed) are no points of the orbit
    return raw.hits.y.copy()


def _require_ok(raw) -> None:
    """``ArithmeticError`` unless the engine's run reached its end (or its stop) successfully with its
    crossings checked (:attr:`nsbench.engine.RunRecord.crossings_checked`): a pass of a run that could
    have stepped over a crossing unseen is never part of an orbit."""
    if not raw.ok:
        raise ArithmeticError(f"flow stopped at t = {raw.t:.6g}: {raw.status.value} {raw.message}")
    if not raw.crossings_checked:
        raise ArithmeticError(
            "flow run with its crossings unchecked (an integrator that checks no step and no check points)"
        )
