"""``cyrk-*``: CyRK's ``pysolve_ivp`` (C++ step loop, Cython) per mode, guards as terminal events.

CyRK (Joe P. Renaud; PyPI ``CyRK``, installed by the extra ``[cyrk]``) runs scipy's
``solve_ivp`` interface in C++: the step loop, the error control, the dense output and
the event handling (scipy's rule: a sign change between two accepted steps, then
Brent's method on the dense output to ``4 eps``) are compiled, and only the vector
field and the event functions are Python calls. nsbench hands it the problem's
compiled law (numba), as for scipy, so what is measured is CyRK's own loop.

The arcs are built as ``scipy-*`` builds them (:mod:`nsbench.integrators.scipy_`):
each guard a terminal event crossing from its expected sign, a guard that starts on its
own surface divided by ``t - t0`` so that the start is no crossing, sections as
non-terminal events, the step capped at 1/16 of the forcing period on forced problems
(``max_step=None``), ``max_num_steps`` from the step budget. ``nfev`` counts the calls
of the field (CyRK keeps no count of its own).

**The methods registered** (four of CyRK's nine): ``cyrk-rk45`` and ``cyrk-dop853``, the
tableaux of ``scipy-rk45`` and ``scipy-dop853``, so the pair measures a compiled step loop
against scipy's Python one on the same method; ``cyrk-tsit5`` (Tsitouras 5(4)) and
``cyrk-vern7`` (Verner's "most efficient" 7(6) pair, with its order-7 interpolant), the
defaults DifferentialEquations.jl recommends at moderate and at tight tolerances, which
scipy does not have. Not registered: ``RK23`` (order 3: more steps than RK45 for the
same accuracy on these smooth arcs), ``Vern8`` (its dense output is of lower order than
the step: on the ball's quadratic arc its event times are 100 times less accurate than
Vern7's, 1.3e-13 against 3e-16), and the implicit ``BDF``, ``Radau``, ``LSODA``:
``pysolve_ivp`` takes no Jacobian (they difference the field) and nsbench's problems are
not stiff; ``scipy-radau``, ``scipy-bdf`` and SUNDIALS cover implicit methods with the
analytic Jacobian.

**What it runs:** every problem with a compiled law, as ``scipy-*``: the friction
family (cubic springs and every friction law included), the impact problems, the relay,
Henon-Heiles.
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np

from nsbench.integrators._optional import OptionalBackend
from nsbench.integrators.base import ArcRequest, ArcResult, Capabilities, Option, SectionHit
from nsbench.integrators.scipy_ import _guard_event, _section_event
from nsbench.status import Status

#: CyRK's status when its ``max_num_steps`` is reached (``CyrkErrorCodes.MAX_STEPS_USER_EXCEEDED``).
MAX_STEPS_STATUS = -52


class CyRKIntegrator(OptionalBackend):
    """Base of the CyRK adapters; subclasses set ``method`` (CyRK's name of it)."""

    ecosystem = "CyRK"
    backend_modules = ("CyRK",)
    extra = "cyrk"
    method: ClassVar[str] = ""
    options = {
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
    accuracy_levels = tuple({"rtol": r, "atol": r * 1e-2} for r in (1e-6, 1e-9, 1e-12))

    def advance(self, request: ArcRequest) -> ArcResult:
        from CyRK import pysolve_ivp

        problem = request.problem
        opts = self.settings
        law, p = problem.law, problem.data.p
        m = problem.mode_array(request.mode)
        n = problem.n_states
        y0 = np.array(request.y0, dtype=float)
        guard_events = [
            _guard_event(g, m, True, -float(g.expected_sign), float(request.t0), y0) for g in request.guards
        ]
        section_events = [_section_event(s, float(s.direction)) for s in request.sections]
        max_step = opts["max_step"]
        if max_step is None:
            w = problem.forcing_frequency
            max_step = (2.0 * np.pi / w) / 16.0 if (problem.is_forced and w > 0.0) else np.inf
        rhs = law.rhs
        calls = [0]

        def diffeq(dy: np.ndarray, t: float, y: np.ndarray) -> None:
            calls[0] += 1
            rhs(p, m, t, y, dy)

        events = [*guard_events, *section_events]
        dense = request.t_eval.size > 0
        sol = pysolve_ivp(
            diffeq,
            (float(request.t0), float(request.t_end)),
            y0,
            method=self.method,
            rtol=opts["rtol"],
            atol=opts["atol"],
            max_step=float(max_step),
            events=events or None,
            dense_output=dense,
            pass_dy_as_arg=True,
            max_num_steps=int(max(request.max_steps, 1)),
        )
        nfev, nsteps = calls[0], int(sol.steps_taken)
        t_all, y_all = sol.t, sol.y
        if not sol.success and not sol.event_terminated:
            budget = sol.status == MAX_STEPS_STATUS
            return ArcResult(
                t=float(t_all[-1]) if t_all.size else float(request.t0),
                y=y_all[:, -1].copy() if t_all.size else y0,
                fired=None,
                y_eval=np.empty((n, 0)),
                status=Status.BUDGET_EXHAUSTED if budget else Status.INTEGRATOR_FAILURE,
                message=(
                    f"step budget exhausted at t = {t_all[-1]:.6g}" if budget and t_all.size else f"CyRK: {sol.message}"
                ),
                nfev=nfev,
                nsteps=nsteps,
            )
        t_events = sol.t_events or []
        y_events = sol.y_events or []
        fired = None
        t_stop, y_stop = float(request.t_end), y_all[:, -1].copy()
        if sol.event_terminated:
            # the earliest guard root; on an exact tie the lowest index (CyRK reports one of them)
            roots = [(float(t_events[q][0]), q) for q in range(len(guard_events)) if len(t_events[q])]
            t_stop, fired = min(roots)
            y_stop = np.array(y_events[fired][:, 0], dtype=float)
        hits = []
        offset = len(guard_events)
        for k in range(len(section_events)):
            times = np.asarray(t_events[offset + k], dtype=float)
            for j, t_hit in enumerate(times):
                if request.t0 < t_hit <= t_stop:
                    hits.append(SectionHit(k, float(t_hit), np.array(y_events[offset + k][:, j], dtype=float)))
        hits.sort(key=lambda h: h.t)
        n_eval = int(np.searchsorted(request.t_eval, t_stop, side="right"))
        if n_eval:
            grid = np.ascontiguousarray(request.t_eval[:n_eval], dtype=float)
            y_eval = np.asarray(sol(grid), dtype=float).reshape(n, n_eval)
        else:
            y_eval = np.empty((n, 0))
        return ArcResult(t=t_stop, y=y_stop, fired=fired, y_eval=y_eval, section_hits=hits, nfev=nfev, nsteps=nsteps)


def _caps(order: int) -> Capabilities:
    return Capabilities(
        event_location="dense-output-root",
        order=order,
        adaptive=True,
        supports_nonlinear=True,
        precision="double",
        step_option="rtol",
    )


class CyRKRK45(CyRKIntegrator):
    """CyRK's Dormand-Prince 5(4) (scipy-rk45's tableau), C++ step loop and event location."""

    name = "cyrk-rk45"
    method = "RK45"
    capabilities = _caps(5)


class CyRKDOP853(CyRKIntegrator):
    """CyRK's Dormand-Prince 8(5,3) (scipy-dop853's tableau), C++ step loop and event location."""

    name = "cyrk-dop853"
    method = "DOP853"
    capabilities = _caps(8)


class CyRKTsit5(CyRKIntegrator):
    """CyRK's Tsitouras 5(4), DifferentialEquations.jl's default explicit method, C++ step loop."""

    name = "cyrk-tsit5"
    method = "Tsit5"
    capabilities = _caps(5)


class CyRKVern7(CyRKIntegrator):
    """CyRK's Verner 7(6) with its order-7 interpolant, C++ step loop and event location."""

    name = "cyrk-vern7"
    method = "Vern7"
    capabilities = _caps(7)
    # Verner's 7(6) pair is a method for tight tolerances (SciML's solver guide: "low tolerance
    # (1e-8 to 1e-12) with Float64: Vern7"), and its levels span that range, not the others'
    # 1e-6 .. 1e-12. Below it the tolerance does not control the step: on the block on ground's
    # first arc (0.216 time units, the conformance kit's smooth arc) Vern7 takes the same 2 steps
    # (32 evaluations) at every rtol from 1e-4 to 1e-9, and its error (3e-13 .. 9.4e-12, 1e3 to 1e5
    # times below the tolerance asked) moves only with the initial step's guess, so the kit's
    # "tightening never makes it less accurate" compared two runs of one step count (measured:
    # 1.3e-12 at rtol 1e-6, 9.4e-12 at 1e-9). At these levels each takes more steps than the
    # looser one: 6.2e-12 (2 steps), 1.4e-12 (3), 1.1e-14 (4) at rtol 1e-8, 1e-10, 1e-12.
    accuracy_levels = tuple({"rtol": r, "atol": r * 1e-2} for r in (1e-8, 1e-10, 1e-12))
