"""``cvode-bdf``, ``cvode-adams``, ``ida``: SUNDIALS through scikit-sundae, per mode, with its own root finding.

Each arc (re)initialises a solver kept per (mode, number of sections), steps
with ``onestep`` towards ``t_end`` (``tstop`` set there) and lets SUNDIALS'
root finding locate the guards (direction: ``expected_sign * guard``
decreasing, so a phase starting on its own surface does not stop at once) and
the sections. The first root return of a guard ends the arc; section roots are
recorded and stepping goes on. Trajectory points are SUNDIALS' interpolant
(``normal`` output inside the last step), read between steps, so an arc that
asks for states is stepped from Python one internal step at a time. An arc that
asks for none (a sweep's, or ``check_points=0``) is one call of scikit-sundae's
``solve`` over ``[t0, t_end]`` instead: the same ``onestep`` calls of the same
solver, the guards terminal, looped in compiled code (the same steps, roots and
counters; tests/integrators/test_sundials.py). Right-hand sides, residuals,
Jacobians (analytic) and root functions are compiled numba kernels
(:mod:`nsbench.integrators._sundials_kernels`).

``cvode-*`` integrate the frozen-mode ODE with ``cos(w t)``, ``sin(w t)`` as two
extra states for forced problems: with every block stuck the mechanical states
are linear in time, and only these states make the step-size control follow
the forcing that drives the stick guards. ``ida`` integrates the DAE with the
friction forces as algebraic variables (the stuck block's ``v = v0`` is an
algebraic constraint and ``|f| <= fr`` its guard); a stuck block's force
carries the forcing into the error test. Consistent initial values are
computed at every switch.

Every internal step is checked for a guard that leaves its side and comes back
inside the step, which SUNDIALS' root finding (a sign test between step ends)
cannot see (:mod:`nsbench.integrators._step_check`): from the step ends the arc
already returns, the guards' values and rates at both ends (one compiled call
per arc). A step where those allow a dip is integrated again from its start by a
solver of the same method whose largest step is an eighth of that step, and
checked in turn (at most three levels): a root found there ends the arc; none,
and the arc stands as it was.

Counters: ``nfev`` and ``njev`` from SUNDIALS' statistics, ``nsteps`` counted
internal steps (those of the steps integrated again included);
``extra['root_returns']`` the solver's root stops, ``extra['check_reruns']`` the
steps integrated again by the check.

All of the above is the *per-arc* path. Wherever the native binding loads, the
whole run goes instead through SUNDIALS' C API from a compiled event loop (the
whole-run protocol: :meth:`SundialsIntegrator.native_refusal` and
:meth:`SundialsIntegrator.run`, :mod:`nsbench.integrators._sundials_native`): the
same formulations, options, steps and events, without Python per step or event;
the option ``loop = 'per-arc'`` forces the path above (docs/core.md, "SUNDIALS natively").
"""

from __future__ import annotations

import time
from typing import Any, ClassVar

import numpy as np

from nsbench.integrators import _step_check as step_check
from nsbench.integrators import _sundials_kernels as sk
from nsbench.integrators._sundials_loop import (
    ROOT_RETURN,
    TSTOP_RETURN,
    CallbackData,
    InterpolatedOutput,
    forget_roots,
)
from nsbench.integrators.base import (
    LOOP_OPTION,
    ArcRequest,
    ArcResult,
    Capabilities,
    Integrator,
    Option,
    RunReport,
    RunRequest,
    SectionHit,
)
from nsbench.status import Status

_OPTIONS = {
    "rtol": Option(1e-8, float, lower=0.0, upper=1e-3, doc="relative tolerance"),
    "atol": Option(1e-10, float, lower=0.0, doc="absolute tolerance"),
    "max_step": Option(
        None, float, lower=0.0, nullable=True, unbounded=True, doc="largest step (time units); None or inf: unbounded"
    ),
    "loop": LOOP_OPTION,
}


def _sundials_max_step(max_step: float | None) -> float:
    """SUNDIALS' largest step: 0 means none."""
    return 0.0 if max_step is None or max_step == np.inf else max_step


class SundialsIntegrator(Integrator):
    """Shared stepping loop of the CVODE and IDA adapters."""

    ecosystem = "SUNDIALS"

    #: Whether every internal step is checked for a guard's excursion inside it (the module docstring).
    check_steps: ClassVar[bool] = True
    options = dict(_OPTIONS)
    accuracy_levels = tuple({"rtol": r, "atol": r * 1e-2} for r in (1e-6, 1e-9, 1e-12))

    def check_problem(self, problem) -> None:
        """The refusals of :meth:`setup`, without compiling the callbacks."""
        Integrator.setup(self, problem)  # refuses a problem without blocks on a belt (capabilities.accepts)

    def setup(self, problem) -> None:
        self.check_problem(problem)
        if getattr(self, "_problem", None) is not problem:
            self._close_native()  # the native solvers hold the previous problem's parameters
        if self.native_refusal(problem, forced=True) == "":
            # the native path's compiled callbacks and loop load with their module: here, not in a run
            from nsbench.integrators import _sundials_native  # noqa: F401
        self._problem = problem
        self._p = np.array(problem.packed, dtype=float)
        self._solvers: dict[tuple, tuple[Any, Any, CallbackData]] = {}

    # ---- the native path (whole-run protocol): SUNDIALS' C API from a compiled loop (_sundials_native)
    native_kind: ClassVar[str] = "cvode"

    def native_refusal(self, problem, forced: bool = False) -> str:
        """The whole run in compiled code wherever the native binding loads (docs/core.md, "SUNDIALS natively")."""
        from nsbench.integrators import _sundials_capi

        reason = _sundials_capi.unavailable()
        return f"the native SUNDIALS binding does not load: {reason}" if reason else ""

    def run(self, request: RunRequest) -> RunReport:
        """The whole run with CVODE or IDA called from compiled code (:mod:`._sundials_native`)."""
        from nsbench.integrators import _sundials_native as native

        problem = request.problem
        if getattr(self, "_problem", None) is not problem:
            self.setup(problem)
        key = len(request.sections)
        solvers = self.__dict__.setdefault("_native", {})
        tic = time.perf_counter()
        if key not in solvers:  # created on a configuration's first native run, timed as set-up
            kind = native.CVODE if self.native_kind == "cvode" else native.IDA
            max_step = _sundials_max_step(self.settings["max_step"])
            method = getattr(self, "method", "BDF")
            rtol, atol = self.settings["rtol"], self.settings["atol"]
            solvers[key] = native.NativeSolver(kind, problem, method, rtol, atol, max_step, key)
        created = time.perf_counter() - tic
        report = native.run(solvers[key], request)
        report.prepare_time += created
        return report

    def _close_native(self) -> None:
        """Free the native solvers (their SUNDIALS objects) of the previous problem."""
        for solver in self.__dict__.pop("_native", {}).values():
            solver.close()

    def _first_arc(self, problem) -> None:
        """A short arc, so that the callbacks compile (or load) for the types SUNDIALS hands them, in setup."""
        mode = problem.initial_mode(0.0, problem.initial_state())
        self.advance(ArcRequest(problem, mode, 0.0, problem.initial_state(), 1e-3, problem.guards(mode)))
        self._solvers.clear()

    def _common_options(
        self, n_events: int, n_guards: int, directions: list[int], eventsfn, max_step: float | None = None
    ) -> dict[str, Any]:
        # a guard's root ends an arc run in one call (_whole_arc); stepped from Python (advance),
        # the loop decides, and scikit-sundae's step reports every root whatever this says
        eventsfn.terminal = [True] * n_guards + [False] * (n_events - n_guards)
        eventsfn.direction = directions
        opts = dict(
            rtol=self.settings["rtol"],
            atol=self.settings["atol"],
            max_step=_sundials_max_step(self.settings["max_step"] if max_step is None else max_step),
            max_num_steps=10**9,
            eventsfn=eventsfn if n_events else None,
            num_events=n_events,
        )
        return opts

    def _solver(self, request: ArcRequest):
        key = (request.mode, len(request.guards), len(request.sections))
        if key not in self._solvers:
            arc = CallbackData(len(request.guards), len(request.sections), request.problem.n_states)
            directions = [-1] * len(request.guards) + [int(s.direction) for s in request.sections]
            self._solvers[key] = (*self._build(arc, len(request.guards), directions), arc)
        return self._solvers[key]

    def _build(
        self, arc: CallbackData, n_guards: int, directions: list[int], max_step: float | None = None
    ):  # pragma: no cover - abstract
        raise NotImplementedError

    def _initial(self, request: ArcRequest) -> tuple[np.ndarray, ...]:  # pragma: no cover - abstract
        """The solver's start values at ``request.t0`` (``y0``; ``y0, yp0`` for a DAE)."""
        raise NotImplementedError

    def _whole_arc(self, request: ArcRequest, solver, eventsfn) -> tuple[ArcResult, np.ndarray, np.ndarray]:
        """The arc as one call of scikit-sundae's ``solve`` (``onestep`` over ``[t0, t_end]``, the guards
        terminal): for an arc that asks for no states, the per-step Python of :meth:`advance` left out.

        Every internal step's end comes back (``res.t``, ``tstop`` included); a root that does not
        end the arc (a section) is not a step's end and comes back in the events only. The step
        budget is checked when the call returns: a run whose budget this arc crosses ends there
        with :attr:`Status.BUDGET_EXHAUSTED` (its counters then exceed the budget by part of the arc).
        """
        n, n_guards = request.problem.n_states, len(request.guards)
        if hasattr(eventsfn, "_i_cnt"):  # scikit-sundae counts roots over the solver's life: a fresh count per arc
            eventsfn._i_cnt[:] = 0
            forget_roots(eventsfn)
        try:
            res = solver.solve(np.array([float(request.t0), float(request.t_end)]), *self._initial(request))
        except RuntimeError as exc:  # SUNDIALS errors surface as RuntimeError in scikit-sundae
            y0 = np.array(request.y0, dtype=float)
            failed = ArcResult(
                t=float(request.t0),
                y=y0,
                fired=None,
                status=Status.INTEGRATOR_FAILURE,
                message=f"SUNDIALS: {exc}",
                y_eval=np.empty((n, 0)),
            )
            return failed, np.empty(0), np.empty((0, n))
        hits: list[SectionHit] = []
        fired = None
        roots = 0
        if res.i_events is not None:
            roots = len(res.i_events)
            for t_root, which_row, y_root in zip(res.t_events.tolist(), res.i_events, res.y_events):
                which = np.flatnonzero(which_row)
                for j in which[which >= n_guards]:
                    hits.append(SectionHit(int(j - n_guards), t_root, y_root[:n].copy()))
                guard_hits = which[which < n_guards]
                if guard_hits.size:
                    fired = int(guard_hits[0])
            forget_roots(eventsfn)
        t, y = float(res.t[-1]), res.y[-1]
        status, message = Status.SUCCESS, ""
        if res.status < 0:
            status, message = Status.INTEGRATOR_FAILURE, f"SUNDIALS: {res.message} (t = {t:.6g})"
            fired = None
        elif fired is None:
            t = float(request.t_end)
        # Every row after the start ends a step but the last one of a failure or of a root that ends
        # the arc, and a tstop return at the time of the row before (the step had ended there).
        ends = res.t if status is Status.SUCCESS and fired is None else res.t[:-1]
        steps = ends.size - 1 - int(np.count_nonzero(ends[1:] == ends[:-1]))
        if status is Status.SUCCESS and steps > request.max_steps:
            status, message = Status.BUDGET_EXHAUSTED, f"step budget exhausted at t = {t:.6g}"
            fired = None
        result = ArcResult(
            t=t,
            y=np.array(y[:n], dtype=float),
            fired=fired,
            y_eval=np.empty((n, 0)),
            section_hits=hits,
            nfev=int(res.nfev),
            njev=int(res.njev),
            nsteps=steps,
            extra={"root_returns": roots, "dense_fallbacks": 0},
            status=status,
            message=message,
        )
        return result, np.asarray(res.t, dtype=float), np.asarray(res.y, dtype=float)

    def advance(self, request: ArcRequest) -> ArcResult:
        problem = request.problem
        if getattr(self, "_problem", None) is not problem:
            self.setup(problem)
        solver, eventsfn, arc = self._solver(request)
        arc.load(request)
        if not request.t_eval.size:
            res, times, states = self._whole_arc(request, solver, eventsfn)
        else:
            res, times, states = self._stepped_arc(request, solver, eventsfn)
        return self._checked(request, res, times, states, arc, 0)

    def _checked(self, request: ArcRequest, res: ArcResult, times, states, arc, depth: int) -> ArcResult:
        """``res`` with every internal step of the arc checked (:func:`nsbench.integrators._step_check.checked`):
        a flagged step is integrated again as an arc in one call, by a solver of the same method whose
        largest step is an eighth of that step (built for it: the check flags few steps)."""
        if not self.check_steps:
            return res

        def rerun(sub: ArcRequest, level: int) -> ArcResult:
            # a solver of its own, whose largest step makes at least RERUN_STEPS steps of the flagged one
            cap = (sub.t_end - sub.t0) / step_check.RERUN_STEPS
            limit = self.settings["max_step"]
            cap = cap if limit is None or limit == np.inf else min(cap, limit)
            directions = [-1] * len(sub.guards) + [int(s.direction) for s in sub.sections]
            fine, fine_events = self._build(arc, len(sub.guards), directions, cap)
            again, sub_times, sub_states = self._whole_arc(sub, fine, fine_events)
            return self._checked(sub, again, sub_times, sub_states, arc, level)

        return step_check.checked(request, res, times, states, rerun, depth)

    def _stepped_arc(self, request: ArcRequest, solver, eventsfn) -> tuple[ArcResult, np.ndarray, np.ndarray]:
        """The arc stepped from Python one internal step at a time, its states read at the requested times
        from each step's interpolant."""
        n, n_guards = request.problem.n_states, len(request.guards)
        t_end = request.t_end
        dense = InterpolatedOutput(solver, request.t_eval, n)
        steps, roots = 0, 0
        hits: list[SectionHit] = []
        fired, status, message = None, Status.SUCCESS, ""
        t, y = float(request.t0), np.array(request.y0, dtype=float)
        last = None  # the last successful return: its counters are the arc's
        step = solver.step
        start = self._initial(request)
        ends_t, ends_y = [float(request.t0)], [np.asarray(start[0], dtype=float)]  # the step ends, for the check
        try:
            solver.init_step(float(request.t0), *start)
            while True:
                if steps >= request.max_steps:
                    status, message = Status.BUDGET_EXHAUSTED, f"step budget exhausted at t = {t:.6g}"
                    break
                res = step(t_end, method="onestep", tstop=t_end)
                flag = res.status
                if flag < 0:
                    status = Status.INTEGRATOR_FAILURE
                    message = f"SUNDIALS: {res.message} (t = {float(res.t):.6g})"
                    break
                last, t, y = res, float(res.t), res.y  # res.y: a fresh array per return
                ends_t.append(t)
                ends_y.append(y)
                if flag != ROOT_RETURN:
                    steps += 1
                    dense.step_end(t, y)
                    if flag == TSTOP_RETURN or t >= t_end:
                        t = t_end
                        break
                    continue
                roots += 1
                which = np.flatnonzero(res.i_events[-1])
                forget_roots(eventsfn)
                for j in which[which >= n_guards]:
                    hits.append(SectionHit(int(j - n_guards), t, y[:n].copy()))
                guard_hits = which[which < n_guards]
                if guard_hits.size:
                    fired = int(guard_hits[0])
                    if dense.pending(t):
                        # Finish the step (no new one) so that its interpolant can
                        # be read at the times before the root.
                        done = solver.step(t_end, method="onestep", tstop=t_end)
                        while done.status == ROOT_RETURN:
                            forget_roots(eventsfn)
                            done = solver.step(t_end, method="onestep", tstop=t_end)
                        dense.upto(t, float(done.t), (t, y))
                    break
        except RuntimeError as exc:  # SUNDIALS errors surface as RuntimeError in scikit-sundae
            status, message = Status.INTEGRATOR_FAILURE, f"SUNDIALS: {exc}"
        result = ArcResult(
            t=t,
            y=np.array(y[:n], dtype=float),
            fired=fired,
            y_eval=dense.states(),
            section_hits=hits,
            nfev=0 if last is None else int(last.nfev),
            njev=0 if last is None else int(last.njev),
            nsteps=steps,
            extra={"root_returns": roots, "dense_fallbacks": dense.fallbacks},
            status=status,
            message=message,
        )
        return result, np.array(ends_t), np.array(ends_y)


class CvodeIntegrator(SundialsIntegrator):
    """CVODE on the frozen-mode ODE; subclasses choose the linear multistep method."""

    method: ClassVar[str] = "BDF"

    def setup(self, problem) -> None:
        super().setup(problem)
        from nsbench.problems.friction_spec import LAYOUT

        c = problem.coefficients
        self._F, self._w = float(c.F), float(c.w)
        self._p0 = self._p.copy()
        self._p0[LAYOUT.offset("F", problem.n_blocks)] = 0.0  # the force enters through the cos state
        self._n_extra = 2 if self._F != 0.0 else 0
        # Compile the kernels here, so that setup_time holds the compilation.
        n = problem.n_states + 2
        y, out = np.zeros(n), np.zeros(n)
        mode, codes = np.ones(problem.n_blocks, dtype=np.int64), np.zeros(1, dtype=np.int64)
        sk.cvode_rhs(self._p0, mode, 1.0, 1.0, y, out)
        sk.cvode_jacobian(self._p0, mode, 1.0, 1.0, y, np.zeros((n, n)))
        sk.cvode_roots(self._p0, mode, 1.0, codes, codes, codes, np.zeros((1, n - 2)), np.zeros(1), y, np.zeros(2))
        self._first_arc(problem)

    def _build(self, arc: CallbackData, n_guards: int, directions: list[int], max_step: float | None = None):
        from sksundae.cvode import CVODE

        p0, F, w = self._p0, self._F, self._w

        def rhsfn(t, y, yp):
            sk.cvode_rhs(p0, arc.mode, F, w, y, yp)

        def jacfn(t, y, yp, jj):
            sk.cvode_jacobian(p0, arc.mode, F, w, y, jj)

        def eventsfn(t, y, events):
            sk.cvode_roots(p0, arc.mode, F, arc.kinds, arc.blocks, arc.signs, arc.sec_coeffs, arc.sec_levels, y, events)

        opts = self._common_options(len(directions), n_guards, directions, eventsfn, max_step)
        return CVODE(rhsfn, method=self.method, jacfn=jacfn, **opts), eventsfn

    def _initial(self, request: ArcRequest) -> tuple[np.ndarray, ...]:
        y0 = np.asarray(request.y0, dtype=float)
        if self._n_extra:
            y0 = np.concatenate([y0, [np.cos(self._w * request.t0), np.sin(self._w * request.t0)]])
        return (y0,)


class CvodeBDF(CvodeIntegrator):
    """SUNDIALS CVODE, variable-order BDF (1-5) with Newton iterations and the analytic Jacobian."""

    name = "cvode-bdf"
    method = "BDF"
    capabilities = Capabilities(
        event_location="solver-rootfinding",
        order=None,
        adaptive=True,
        needs_jacobian=True,
        supports_nonlinear=True,
        precision="double",
        step_option="rtol",
        checks_steps=True,
        # the friction oscillators' formulation: the forcing as states; for ida the friction forces as
        # algebraic variables
        accepts=("belt_blocks",),
    )


class CvodeAdams(CvodeIntegrator):
    """SUNDIALS CVODE, variable-order Adams-Moulton (1-12) with Newton iterations and the analytic Jacobian."""

    name = "cvode-adams"
    method = "Adams"
    capabilities = CvodeBDF.capabilities


class Ida(SundialsIntegrator):
    """SUNDIALS IDA on the DAE with friction forces as algebraic variables (BDF 1-5)."""

    name = "ida"
    native_kind = "ida"
    capabilities = Capabilities(
        event_location="solver-rootfinding",
        order=None,
        adaptive=True,
        needs_jacobian=True,
        supports_nonlinear=True,
        precision="double",
        step_option="rtol",
        checks_steps=True,
        # the friction oscillators' formulation: the forcing as states; for ida the friction forces as
        # algebraic variables
        accepts=("belt_blocks",),
    )

    def setup(self, problem) -> None:
        super().setup(problem)
        # Compile the kernels here, so that setup_time holds the compilation.
        nb, n = problem.n_blocks, problem.n_states
        mode, codes = np.zeros(nb, dtype=np.int64), np.zeros(1, dtype=np.int64)
        y, out = np.zeros(n + nb), np.zeros(n + nb)
        sk.ida_residual(self._p, mode, 0.0, y, y, out)
        sk.ida_jacobian(self._p, mode, mode, 0.0, y, 1.0, np.zeros((n, n)), np.zeros((n + nb, n + nb)))
        sk.ida_roots(self._p, codes, codes, codes, np.zeros((1, n)), np.zeros(1), y, np.zeros(2))
        sk.consistent_start(self._p, mode, 0.0, np.zeros(n))
        self._first_arc(problem)

    def _build(self, arc: CallbackData, n_guards: int, directions: list[int], max_step: float | None = None):
        from sksundae.ida import IDA

        p = self._p
        nb = self._problem.n_blocks
        n = 2 * nb
        slip_all = np.full(nb, -1, dtype=np.int64)
        scratch = np.zeros((n, n))

        def resfn(t, y, yp, res):
            sk.ida_residual(p, arc.mode, t, y, yp, res)

        def jacfn(t, y, yp, res, cj, jj):
            sk.ida_jacobian(p, arc.mode, slip_all, t, y, cj, scratch, jj)

        def eventsfn(t, y, yp, events):
            sk.ida_roots(p, arc.kinds, arc.blocks, arc.signs, arc.sec_coeffs, arc.sec_levels, y, events)

        mode = np.asarray(self._pending_mode, dtype=np.int64)
        algebraic = [n + i for i in range(nb)] + [2 * i + 1 for i in range(nb) if mode[i] == 0]
        opts = self._common_options(len(directions), n_guards, directions, eventsfn, max_step)
        return IDA(resfn, jacfn=jacfn, algebraic_idx=sorted(algebraic), **opts), eventsfn

    def _solver(self, request: ArcRequest):
        self._pending_mode = request.mode  # the algebraic variables depend on the mode
        return super()._solver(request)

    def _initial(self, request: ArcRequest) -> tuple[np.ndarray, ...]:
        y0, yp0 = sk.consistent_start(
            self._p, np.asarray(request.mode, dtype=np.int64), float(request.t0), np.asarray(request.y0, dtype=float)
        )
        return y0, yp0
