"""``scipy-*``: ``scipy.integrate.solve_ivp`` per mode, guards as terminal events.

Each guard becomes a terminal event whose direction is the crossing from its
expected sign to the other side, so a phase that starts on its own surface
does not stop at once. Events are located by scipy on the method's dense
output (Brent's method). Sections are non-terminal events. A step counter,
written as a never-firing event (scipy calls events once per step), enforces
the step budget. The implicit methods get the analytic mode Jacobian.

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
from scipy.integrate import solve_ivp

from nsbench.integrators.base import ArcRequest, ArcResult, Capabilities, Integrator, Option, SectionHit
from nsbench.status import Status


class _BudgetExhausted(Exception):
    def __init__(self, t: float, y: np.ndarray) -> None:
        super().__init__(t)
        self.t, self.y = t, np.array(y, dtype=float)


class _StepCounter:
    """An event function that never fires; scipy calls it once per accepted step."""

    terminal = False
    direction = 0.0

    def __init__(self, budget: int) -> None:
        self.calls = 0
        self.budget = budget

    def __call__(self, t: float, y: np.ndarray) -> float:
        self.calls += 1
        if self.calls - 1 > self.budget:
            raise _BudgetExhausted(t, y)
        return 1.0


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


class ScipyIntegrator(Integrator):
    """Base of the ``solve_ivp`` adapters; subclasses set ``method``."""

    method: ClassVar[str] = ""
    ecosystem = "scipy"
    implicit: ClassVar[bool] = False
    options = dict(_TOLERANCES)
    accuracy_levels = tuple({"rtol": r, "atol": r * 1e-2} for r in (1e-6, 1e-9, 1e-12))

    def advance(self, request: ArcRequest) -> ArcResult:
        problem, mode = request.problem, request.mode
        opts = self.settings
        counter = _StepCounter(request.max_steps)
        law, p = problem.law, problem.data.p
        m = problem.mode_array(mode)
        y0 = np.array(request.y0, dtype=float)
        guard_events = [
            _guard_event(g, m, True, -float(g.expected_sign), float(request.t0), y0) for g in request.guards
        ]
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
        try:
            sol = solve_ivp(
                fun,
                (request.t0, request.t_end),
                np.array(request.y0, dtype=float),
                method=self.method,
                rtol=opts["rtol"],
                atol=opts["atol"],
                max_step=max_step,
                events=[*guard_events, *section_events, counter],
                dense_output=dense,
                **kwargs,
            )
        except _BudgetExhausted as stop:
            return ArcResult(
                t=stop.t,
                y=stop.y,
                fired=None,
                y_eval=np.empty((problem.n_states, 0)),
                nsteps=counter.calls - 1,
                status=Status.BUDGET_EXHAUSTED,
                message=f"step budget exhausted at t = {stop.t:.6g}",
            )
        nsteps = max(len(sol.t) - 1, 0)
        counts = dict(nfev=int(sol.nfev), njev=int(sol.njev), nsteps=nsteps, extra={"nlu": int(sol.nlu)})
        if sol.status == -1:
            return ArcResult(
                t=float(sol.t[-1]),
                y=sol.y[:, -1].copy(),
                fired=None,
                y_eval=np.empty((problem.n_states, 0)),
                status=Status.INTEGRATOR_FAILURE,
                message=sol.message,
                **counts,
            )
        fired = None
        t_stop, y_stop = float(sol.t[-1]), sol.y[:, -1].copy()
        if sol.status == 1:
            for q in range(len(guard_events)):
                if len(sol.t_events[q]):
                    fired = q
                    t_stop = float(sol.t_events[q][0])
                    y_stop = np.array(sol.y_events[q][0], dtype=float)
                    break
        else:
            t_stop = request.t_end
        hits = []
        offset = len(guard_events)
        for k in range(len(section_events)):
            for t_hit, y_hit in zip(sol.t_events[offset + k], sol.y_events[offset + k]):
                if t_hit <= t_stop and t_hit > request.t0:
                    hits.append(SectionHit(k, float(t_hit), np.array(y_hit, dtype=float)))
        hits.sort(key=lambda h: h.t)
        n_eval = int(np.searchsorted(request.t_eval, t_stop, side="right"))
        if n_eval:
            y_eval = np.asarray(sol.sol(request.t_eval[:n_eval])).reshape(problem.n_states, n_eval)
        else:
            y_eval = np.empty((problem.n_states, 0))
        return ArcResult(t=t_stop, y=y_stop, fired=fired, y_eval=y_eval, section_hits=hits, **counts)


def _caps(order: int | None, implicit: bool) -> Capabilities:
    return Capabilities(
        event_location="dense-output-root",
        order=order,
        adaptive=True,
        needs_jacobian=implicit,
        supports_nonlinear=True,
        precision="double",
        step_option="rtol",
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
