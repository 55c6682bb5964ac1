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
(:mod:`nsbench.integrators._step_check`): the guard's values and rates at both
ends, then, on the few steps where those allow a dip, the guard on the step's
dense output. A dip is located and ends the arc like any crossing. The rates
take the field at the step end, which the explicit methods and Radau already
hold (no extra evaluation); for BDF and LSODA it is one evaluation of the
compiled field per step, outside the method (``extra['check_fev']``, not in
``nfev``). The dense outputs the check builds are the method's own work and are
in ``nfev`` (3 evaluations each for DOP853, none for the others);
``extra['check_searches']`` counts the steps searched.

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


class _StepCheck:
    """The per-step missed-crossing check of one arc (:mod:`nsbench.integrators._step_check`).

    Keeps each guard's signed value and rate at the last step end; :meth:`dip` checks the
    step just taken and returns the first guard that dips inside it, with the time.
    """

    def __init__(self, problem, m: np.ndarray, guards, t0: float, y0: np.ndarray, solver) -> None:
        law = problem.law
        self.p, self.m, self.law = problem.data.p, m, law
        self.codes = [(g.code, g.block - 1, float(g.expected_sign)) for g in guards]
        self.n = problem.n_states
        # the field at a step end: the explicit methods and Radau keep it (solver.f); BDF and LSODA do not
        self.keeps_f = hasattr(solver, "f")
        self.extra_fev = 0
        self.searches = 0  # steps whose dense output was searched for a dip
        self.t0 = t0
        self.h, self.d = self._at(t0, y0, self._field(solver, t0, y0), None)
        # on its own surface at the arc's start (a phase start): its event is the guard over t - t0
        self.fresh = [h == 0.0 for h in self.h]

    def _field(self, solver, t: float, y: np.ndarray) -> np.ndarray:
        if self.keeps_f:
            return solver.f
        out = np.empty(self.n)
        self.law.rhs(self.p, self.m, t, y, out)
        self.extra_fev += 1
        return out

    def _at(self, t: float, y: np.ndarray, f: np.ndarray, g) -> tuple[list[float], list[float]]:
        """Signed values and rates of the guards at ``(t, y)``; ``g``: the events' values there (a guard's
        own value unless it started on its surface), or None."""
        value, rate, p, m = self.law.guard_value, self.law.guard_rate, self.p, self.m
        h = [
            s * (g[q] if g is not None and not self.fresh[q] else value(p, m, k, i, t, y))
            for q, (k, i, s) in enumerate(self.codes)
        ]
        d = [s * rate(p, m, k, i, t, y, f) for k, i, s in self.codes]
        return h, d

    def dip(self, solver, t_old: float, t: float, y: np.ndarray, g, crossed: set[int], sol):
        """``((guard, time) or None, sol)``: the first excursion inside the step ``[t_old, t]`` of a guard on
        its side at both ends (``crossed``: the guards whose sign changed, which the root finding locates;
        ``g``: the events' values at ``t``), and the step's dense output (``sol``, built here if needed)."""
        h0, d0 = self.h, self.d
        h1, d1 = self._at(t, y, self._field(solver, t, y), g)
        dt = t - t_old
        first = t_old == self.t0
        found = None
        for q in range(len(self.codes)):
            if q in crossed or not (h1[q] > 0.0 and h0[q] >= 0.0):
                continue
            fresh = first and self.fresh[q]
            if not step_check.may_dip(h0[q], h1[q], dt * d0[q], dt * d1[q], fresh):
                continue
            if sol is None:
                sol = solver.dense_output()
            self.searches += 1
            kind, index, sign = self.codes[q]
            law, p, m = self.law, self.p, self.m

            def h(tt, yy, kind=kind, index=index, sign=sign):
                return sign * law.guard_value(p, m, kind, index, tt, yy)

            tau = step_check.dip_root(h, sol, t_old, t, h0[q], step_check.rounding(y))
            if tau is not None and (found is None or tau < found[1]):
                found = (q, tau)
        self.h, self.d = h1, d1
        return found, sol


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

    def step(self, solver, check: _StepCheck | None) -> bool:
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
        roots: list[tuple[float, int]] = []
        if active:
            if sol is None:
                sol = solver.dense_output()
            for q in active:
                event = self.events[q]
                roots.append((brentq(lambda tt: event(tt, sol(tt)), t_old, t, xtol=4 * _EPS, rtol=4 * _EPS), q))
        dip = None
        if check is not None:
            crossed = {q for q in active if q < self.n_guards}
            dip, sol = check.dip(solver, t_old, t, y, g_new, crossed, sol)
        if dip is not None:
            roots.append((dip[1], dip[0]))
        end = None
        if roots:
            roots.sort(key=lambda r: r[0])  # time order; a dip or a crossing, whichever comes first
            for tau, q in roots:
                if q < self.n_guards:  # the first guard ends the arc; sections after it are not reached
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

    def budget_exhausted(self, problem, solver, check) -> ArcResult:
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

    def result(self, problem, request, solver, check, status: Status, message: str, method: str) -> ArcResult:
        extra_fev = check.extra_fev if check is not None else 0
        searches = check.searches if check is not None else 0
        nsteps = len(self.ts) - 1
        counts = dict(
            nfev=int(solver.nfev),
            njev=int(solver.njev),
            nsteps=nsteps,
            extra={"nlu": int(solver.nlu), "check_fev": extra_fev, "check_searches": searches},
        )
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
    implicit: ClassVar[bool] = False
    #: Whether every accepted step is checked for a guard's excursion inside it (the module docstring).
    check_steps: ClassVar[bool] = True
    options = dict(_TOLERANCES)
    accuracy_levels = tuple({"rtol": r, "atol": r * 1e-2} for r in (1e-6, 1e-9, 1e-12))

    def advance(self, request: ArcRequest) -> ArcResult:
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
        check = _StepCheck(problem, m, request.guards, t0, y0, solver) if self.check_steps and request.guards else None
        arc = _Arc(guard_events, section_events, t0, y0, dense)
        budget = request.max_steps
        while True:
            message = solver.step()
            if solver.status == "failed":
                failure = message or "integration failed"
                return arc.result(problem, request, solver, check, Status.INTEGRATOR_FAILURE, failure, self.method)
            if arc.steps >= budget:  # this step is one past the budget: it ends the run there
                arc.steps += 1
                return arc.budget_exhausted(problem, solver, check)
            if arc.step(solver, check):
                break
        return arc.result(problem, request, solver, check, Status.SUCCESS, "", self.method)


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
