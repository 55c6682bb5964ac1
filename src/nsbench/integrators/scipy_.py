"""``scipy-*``: scipy's ``solve_ivp`` methods per mode, guards as terminal events, every step checked.

The arc is stepped here with the method's own solver class (``RK45``,
``DOP853``, ``Radau``, ``BDF``, ``LSODA``), in the loop ``solve_ivp`` runs:
each guard is a terminal event whose direction is the crossing from its
expected sign to the other side, so a phase that starts on its own surface
does not stop at once; a sign change between two step ends is located on the
method's dense output (Brent's method, to 4 ulp, as ``solve_ivp`` does).
Sections are non-terminal events. The step budget is counted per step. The
implicit methods get the analytic mode Jacobian.

Every accepted step is also checked for a guard that leaves its side and comes
back inside the step, which a sign test at the step ends cannot see
(:mod:`nsbench.integrators._step_check`): after the arc, one compiled call
tests every step from the guards' values and rates at its ends; a step where
those allow a dip is integrated again from its start with a fresh solver of the
same method in at least 8 steps, itself checked, and a crossing found there
ends the arc. A step costs the check only the keeping of its end; the reruns'
work is in the counters (``extra['check_reruns']`` counts them).

Step-size control sees only the vector field. While every block sticks the
field is constant, the error estimate is zero and the step grows without
bound, so a stick guard driven by the harmonic force (``R_2`` contains
``F cos(w t)``) can cross and come back inside one step and be missed. The
default ``max_step=None`` therefore caps the step at 1/16 of the forcing period
for forced problems (no cap otherwise); pass ``max_step=inf`` to see the
uncapped behaviour.

A guard that starts on its own surface (value exactly 0 at ``t0``, as after an
impact or a release) is handed to scipy divided by ``t - t0`` (its rate at
``t0`` itself), which has the same zeros after ``t0``. Otherwise scipy sees the
zero at ``t0`` as one end of a sign change: a first step that carries the guard
out and back across its surface (a short flight of a chattering impact) would
be located at ``t0`` itself, the excursion lost. An exact zero of such a guard
(a first step too short to move it off a double zero, as at a release from a
stop) is taken as still on its surface, not across it.
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np

from nsbench.integrators import _step_check as step_check
from nsbench.integrators.base import ArcRequest, ArcResult, Capabilities, Integrator, Option, SectionHit
from nsbench.status import Status

_EPS = float(np.finfo(float).eps)


def _guard_event(
    guard, mode: np.ndarray, terminal: bool, direction: float, t0: float = np.nan, y0: np.ndarray | None = None
):
    """A guard as a scipy event function, evaluated by the problem's compiled law.

    If the guard is exactly 0 at ``(t0, y0)`` it is returned divided by ``t - t0``
    (its rate at ``t0``), and an exact zero as a tiny value of its expected sign: the
    same crossings after ``t0``, none at ``t0``.
    """
    problem = guard.problem
    law, p = problem.law, problem.data.p
    guard_value = law.guard_value
    kind, index = guard.code, guard.block - 1

    if y0 is not None and guard_value(p, mode, kind, index, t0, y0) == 0.0:
        dy = np.empty(y0.shape[0])
        law.rhs(p, mode, t0, y0, dy)
        start_rate = law.guard_rate(p, mode, kind, index, t0, y0, dy)

        # exactly on the surface is not across it: the smallest value of the expected sign, so that a
        # first step too short to move the guard off a double zero (a release) is no crossing for scipy
        on_surface = float(guard.expected_sign) * 1e-300

        def event(t: float, y: np.ndarray) -> float:
            value = start_rate if t == t0 else guard_value(p, mode, kind, index, t, y) / (t - t0)
            return value if value != 0.0 else on_surface
    else:

        def event(t: float, y: np.ndarray) -> float:
            return guard_value(p, mode, kind, index, t, y)

    event.terminal = terminal
    event.direction = direction
    return event


def _section_event(section, direction: float):
    coeffs, level = np.asarray(section.coeffs, dtype=float), float(section.level)

    def event(t: float, y: np.ndarray) -> float:
        return float(coeffs @ y) - level

    event.terminal = False
    event.direction = direction
    return event


_TOLERANCES = {
    "rtol": Option(1e-8, float, lower=0.0, upper=1.0, doc="relative tolerance"),
    "atol": Option(1e-10, float, lower=0.0, doc="absolute tolerance"),
    "max_step": Option(
        None,
        float,
        lower=0.0,
        nullable=True,
        unbounded=True,
        doc="largest step (time units); None: 1/16 of the forcing period if forced; inf: no limit",
    ),
}


class _Arc:
    """The events, section hits and step ends of one arc as it is stepped (the loop of ``solve_ivp``)."""

    def __init__(self, guard_events, section_events, t0: float, y0: np.ndarray, dense: bool) -> None:
        self.events = [*guard_events, *section_events]
        self.n_guards = len(guard_events)
        self.directions = [float(e.direction) for e in self.events]
        self.g = [e(t0, y0) for e in self.events]
        self.t_events: list[list[float]] = [[] for _ in self.events]
        self.y_events: list[list[np.ndarray]] = [[] for _ in self.events]
        self.dense = dense
        self.ts = [t0]
        self.interpolants: list = []
        self.steps = 0
        self.t0 = t0
        self.fired: int | None = None
        self.t_stop, self.y_stop = t0, y0

    def step(self, solver) -> bool:
        """Record the step the solver just took; whether the arc ends with it (an event, or ``t_end``)."""
        from scipy.optimize import brentq

        self.steps += 1
        t_old, t, y = solver.t_old, solver.t, solver.y
        sol = solver.dense_output() if self.dense else None
        g_new = [e(t, y) for e in self.events]
        active = []
        for q, (a, b, direction) in enumerate(zip(self.g, g_new, self.directions)):
            up, down = a <= 0 and b >= 0, a >= 0 and b <= 0
            if (up and direction > 0) or (down and direction < 0) or ((up or down) and direction == 0):
                active.append(q)
        self.g = g_new
        end = None
        if active:
            if sol is None:
                sol = solver.dense_output()
            roots = []
            for q in active:
                event = self.events[q]
                roots.append((brentq(lambda tt: event(tt, sol(tt)), t_old, t, xtol=4 * _EPS, rtol=4 * _EPS), q))
            roots.sort(
                key=lambda r: r[0]
            )  # time order: the first guard ends the arc, sections after it are not reached
            for tau, q in roots:
                if q < self.n_guards:
                    end = (tau, q)
                    break
                self.t_events[q].append(tau)
                self.y_events[q].append(sol(tau))
        if end is not None:
            t, self.fired = end[0], end[1]
            y = sol(t)
        self._keep(t, sol)
        self.t_stop, self.y_stop = t, y
        return end is not None or solver.status == "finished"

    def _keep(self, t: float, sol) -> None:
        if not self.dense:
            self.ts.append(t)
        elif len(self.ts) > 1 and self.ts[-1] == t:  # a crossing at the step's start: no new segment
            return
        else:
            self.ts.append(t)
            self.interpolants.append(sol)

    def budget_exhausted(self, problem, solver) -> ArcResult:
        t = float(solver.t)
        return ArcResult(
            t=t,
            y=np.array(solver.y, dtype=float),
            fired=None,
            y_eval=np.empty((problem.n_states, 0)),
            nsteps=self.steps,
            status=Status.BUDGET_EXHAUSTED,
            message=f"step budget exhausted at t = {t:.6g}",
        )

    def result(self, problem, request, solver, status: Status, message: str, method: str) -> ArcResult:
        nsteps = len(self.ts) - 1
        counts = dict(nfev=int(solver.nfev), njev=int(solver.njev), nsteps=nsteps, extra={"nlu": int(solver.nlu)})
        if status is not Status.SUCCESS:
            return ArcResult(
                t=float(self.ts[-1]),
                y=np.array(self.y_stop, dtype=float),
                fired=None,
                y_eval=np.empty((problem.n_states, 0)),
                status=status,
                message=message,
                **counts,
            )
        t_stop = float(self.t_stop) if self.fired is not None else float(request.t_end)
        y_stop = np.array(self.y_stop, dtype=float)
        hits = []
        for k in range(self.n_guards, len(self.events)):
            for t_hit, y_hit in zip(self.t_events[k], self.y_events[k]):
                if t_hit <= t_stop and t_hit > request.t0:
                    hits.append(SectionHit(k - self.n_guards, float(t_hit), np.array(y_hit, dtype=float)))
        hits.sort(key=lambda h: h.t)
        n_eval = int(np.searchsorted(request.t_eval, t_stop, side="right"))
        if n_eval:
            from scipy.integrate import OdeSolution

            alt = method in ("BDF", "LSODA")  # the segment rule solve_ivp uses for them
            sol = OdeSolution(self.ts, self.interpolants, alt_segment=alt)
            y_eval = np.asarray(sol(request.t_eval[:n_eval])).reshape(problem.n_states, n_eval)
        else:
            y_eval = np.empty((problem.n_states, 0))
        return ArcResult(t=t_stop, y=y_stop, fired=self.fired, y_eval=y_eval, section_hits=hits, **counts)


class ScipyIntegrator(Integrator):
    """Base of the ``solve_ivp`` adapters; subclasses set ``method``."""

    method: ClassVar[str] = ""
    ecosystem = "scipy"
    implicit: ClassVar[bool] = False
    #: Whether every accepted step is checked for a guard's excursion inside it (the module docstring).
    check_steps: ClassVar[bool] = True
    options = dict(_TOLERANCES)
    accuracy_levels = tuple({"rtol": r, "atol": r * 1e-2} for r in (1e-6, 1e-9, 1e-12))

    def setup(self, problem) -> None:
        super().setup(problem)

        def short_arc():
            y0 = problem.initial_state()
            mode = problem.initial_mode(0.0, y0)
            request = ArcRequest(problem, mode, 0.0, y0, 1e-3 * problem.time_scale, problem.guards(mode))
            ScipyIntegrator.advance(self, request)  # this class's arc: a subclass's own advance is not run here

        # the law's compiled functions and the step check load on a first arc: here, not in a timed one
        self.warm_first_call(problem, short_arc)

    def advance(self, request: ArcRequest) -> ArcResult:
        return self._advance(request, 0)

    def _advance(self, request: ArcRequest, depth: int) -> ArcResult:
        import scipy.integrate

        problem, mode = request.problem, request.mode
        opts = self.settings
        law, p = problem.law, problem.data.p
        m = problem.mode_array(mode)
        t0, t_end = float(request.t0), float(request.t_end)
        y0 = np.array(request.y0, dtype=float)
        guard_events = [_guard_event(g, m, True, -float(g.expected_sign), t0, y0) for g in request.guards]
        section_events = [_section_event(s, float(s.direction)) for s in request.sections]
        dense = request.t_eval.size > 0
        max_step = opts["max_step"]
        if max_step is None:
            w = problem.forcing_frequency
            max_step = (2.0 * np.pi / w) / 16.0 if (problem.is_forced and w > 0.0) else np.inf
        if depth:  # a step integrated again by the check: in at least RERUN_STEPS steps
            max_step = min(max_step, (t_end - t0) / step_check.RERUN_STEPS)
        # the field, Jacobian and guards of the mode are the problem's compiled law: scipy's own
        # work is what is measured, not a Python re-evaluation of the model
        n = problem.n_states
        rhs, jacobian = law.rhs, law.jacobian

        def fun(t, y):
            out = np.empty(n)
            rhs(p, m, t, y, out)
            return out

        kwargs = {}
        if self.implicit:

            def jac(t, y):
                out = np.empty((n, n))
                jacobian(p, m, t, y, out)
                return out

            kwargs["jac"] = jac
        solver = getattr(scipy.integrate, self.method)(
            fun, t0, y0, t_end, rtol=opts["rtol"], atol=opts["atol"], max_step=max_step, vectorized=False, **kwargs
        )
        arc = _Arc(guard_events, section_events, t0, y0, dense)
        keep = self.check_steps and bool(request.guards)
        ends_t, ends_y = [t0], [y0]  # the step ends, for the check (each a fresh array of the solver's)
        budget = request.max_steps
        while True:
            message = solver.step()
            if solver.status == "failed":
                failure = message or "integration failed"
                return arc.result(problem, request, solver, Status.INTEGRATOR_FAILURE, failure, self.method)
            if arc.steps >= budget:  # this step is one past the budget: it ends the run there
                arc.steps += 1
                return arc.budget_exhausted(problem, solver)
            done = arc.step(solver)
            if keep:
                ends_t.append(arc.t_stop)
                ends_y.append(arc.y_stop)
            if done:
                break
        res = arc.result(problem, request, solver, Status.SUCCESS, "", self.method)
        if not keep:
            return res
        return step_check.checked(request, res, np.array(ends_t), np.array(ends_y), self._rerun, depth)

    def _rerun(self, request: ArcRequest, depth: int) -> ArcResult:
        """The arc of ``request`` (a step of another arc integrated again by the check), checked at ``depth``."""
        return self._advance(request, depth)


def _caps(order: int | None, implicit: bool) -> Capabilities:
    return Capabilities(
        event_location="dense-output-root",
        order=order,
        adaptive=True,
        needs_jacobian=implicit,
        supports_nonlinear=True,
        precision="double",
        step_option="rtol",
        checks_steps=True,
    )


class ScipyRK45(ScipyIntegrator):
    """Dormand-Prince 5(4) with quartic dense output."""

    name = "scipy-rk45"
    method = "RK45"
    capabilities = _caps(5, False)


class ScipyDOP853(ScipyIntegrator):
    """Dormand-Prince 8(5,3) with 7th-order dense output."""

    name = "scipy-dop853"
    method = "DOP853"
    capabilities = _caps(8, False)


class ScipyRadau(ScipyIntegrator):
    """Radau IIA, implicit, order 5, analytic Jacobian."""

    name = "scipy-radau"
    method = "Radau"
    implicit = True
    capabilities = _caps(5, True)


class ScipyBDF(ScipyIntegrator):
    """Variable-order BDF (1-5), implicit, analytic Jacobian."""

    name = "scipy-bdf"
    method = "BDF"
    implicit = True
    capabilities = _caps(None, True)


class ScipyLSODA(ScipyIntegrator):
    """LSODA (Adams/BDF switching), analytic Jacobian."""

    name = "scipy-lsoda"
    method = "LSODA"
    implicit = True
    capabilities = _caps(None, True)
