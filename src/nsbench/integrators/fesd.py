"""``fesd``: finite elements with switch detection (FESD) through nosnoc, on the relay feedback system.

FESD (Nurkanovic, Sperl, Albrecht and Diehl, "Finite elements with switch detection for
direct optimal control of nonsmooth systems", Numerische Mathematik 156 (2024)) writes a
Filippov system in Stewart's form, ``x' = sum_i theta_i f_i(x)`` with the multipliers
``theta`` of the regions complementary to the indicator functions, and integrates it with
an implicit Runge-Kutta scheme on ``n_fe`` finite elements per step whose *lengths* are
unknowns: cross-complementarity conditions force every change of the active set onto an
element boundary, so a switch is located by the step's own nonlinear program, not by a
root finder. nosnoc (PyPI ``nosnoc`` 0.2.0, nosnoc_py, with casadi and IPOPT) builds and
solves that program; nsbench runs it step by step in its simulation mode (one program of
span ``h`` per step, the next started from the last state).

**What is mapped.** The relay feedback system (``relay-feedback``): ``x' = A x + B`` where
``C x < 0`` (region 1, ``u = +1``) and ``A x - B`` where ``C x > 0`` (region 2), one
switching function ``c(x) = C x``; Filippov sliding on ``C x = 0`` is the convex
combination ``theta``. Other problems are refused at setup with the reason.

**What it returns.** The states at every finite-element end (``t`` the accumulated
element lengths: nosnoc's ``switch_times`` output holds element lengths, not times), the
mode of each element read off its ``theta`` at the element's end (sliding where
``min theta > sqrt(comp_tol)``, the complementarity residual's scale, else the region of
the larger ``theta``) and, with ``switch_detection``, the element boundaries inside a step
where that label changes as :attr:`~nsbench.integrators.whole.SystemResult.switch_times`,
if every stage of the element after is in its new mode (a change on the step grid is the
grid's, and one inside an element, its first stages in the old mode, is not at the
boundary: neither is a located switch). The events are inferred
from the labels (:mod:`nsbench.hybrid.inference`, rule 6) and the located times reported
beside them (the event log's ``t_located``).

**Defaults.** Radau IIA with ``n_s = 3`` stages (order 5; nosnoc's own examples use 2 for the relay, 3 for
its oscillator's order study) and ``comp_tol = 1e-12`` (nosnoc's order experiments; its relay example uses
1e-6), with nosnoc's homotopy floor ``sigma_N`` lowered to ``comp_tol`` (else it stops at 1e-8 whatever
``comp_tol`` says). Measured on the relay (docs/families.md): with two stages the crossing arcs
(``omega = 25``) leave a state error near 5e-2 that no ``comp_tol`` removes, and the relaxation leaves an
end-state error of the order of ``sqrt(comp_tol)`` that no step removes (4e-3 at 1e-6); both are needed for
every switch of ``exact``'s log from the case's own start at ``h = 0.025``.

**Failures.** A step whose program does not converge (IPOPT's status, or a non-finite
state) is retried as two steps of half the length, down to ``h / 8``; if that fails too the
run stops with ``Status.INTEGRATOR_FAILURE`` at the last good state.
"""

from __future__ import annotations

import contextlib
import io
import math
import os
import sys
import warnings
from typing import TYPE_CHECKING, Any, Iterator

import numpy as np

from nsbench.errors import UnsupportedProblemError
from nsbench.integrators._optional import OptionalBackend
from nsbench.integrators.base import Capabilities, Option
from nsbench.integrators.whole import SystemRequest, SystemResult, WholeSystem
from nsbench.status import Status

if TYPE_CHECKING:  # pragma: no cover
    from nsbench.problems.base import HybridProblem

#: The IRK schemes nosnoc offers (``IrkSchemes``), by nsbench's option value.
SCHEMES = {"radau-iia": "RADAU_IIA", "gauss-legendre": "GAUSS_LEGENDRE"}
#: How often a failed step is halved before the run gives up (``h / 2**MAX_HALVINGS`` is the shortest step).
MAX_HALVINGS = 3
#: Region labels of the relay (``relay_feedback_spec``): u = +1, u = -1, sliding.
_UP, _DOWN, _SLIDE = 0, 1, 2


@contextlib.contextmanager
def quiet() -> Iterator[None]:
    """Silence nosnoc and IPOPT: Python's ``print`` and what the C libraries write to file descriptor 1."""
    sys.stdout.flush()
    try:
        fd = sys.__stdout__.fileno() if sys.__stdout__ is not None else 1
        saved = os.dup(fd)
    except (OSError, ValueError, io.UnsupportedOperation):  # no real stdout (a captured one): Python's only
        with contextlib.redirect_stdout(io.StringIO()):
            yield
        return
    try:
        with open(os.devnull, "w") as null:
            os.dup2(null.fileno(), fd)
            with contextlib.redirect_stdout(io.StringIO()):
                yield
    finally:
        os.dup2(saved, fd)
        os.close(saved)


def import_nosnoc() -> Any:
    """``nosnoc``, imported without its global ``warnings.simplefilter("always")`` outliving the import."""
    with warnings.catch_warnings():
        import nosnoc

    return nosnoc


class Fesd(OptionalBackend, WholeSystem):
    """FESD (finite elements with switch detection) through nosnoc, step by step, on the relay feedback system."""

    name = "fesd"
    ecosystem = "nosnoc"
    backend_modules = ("nosnoc", "casadi")
    extra = "fesd"
    capabilities = Capabilities(
        event_location="switch-detection",
        order=None,
        adaptive=False,
        supports_nonlinear=False,  # the relay only: cubic springs (friction) are refused with the rest
        step_option="h",
        family="time-stepping",
        accepts=("sliding",),  # a switched first-order field: its side of each surface, or its sliding
    )
    options = {
        "h": Option(
            0.05, float, lower=0.0, doc="step: the span of one nosnoc program (rounded so whole steps fill the span)"
        ),
        "n_fe": Option(2, int, lower=1, lower_inclusive=True, doc="finite elements per step"),
        "n_s": Option(3, int, lower=1, lower_inclusive=True, upper=9, doc="stages of the IRK scheme"),
        "scheme": Option("radau-iia", str, choices=tuple(SCHEMES), doc="the IRK scheme"),
        "switch_detection": Option(
            True, bool, doc="FESD's element lengths as unknowns (False: nosnoc's plain IRK on fixed elements)"
        ),
        "comp_tol": Option(1e-12, float, lower=0.0, upper=1e-2, doc="complementarity tolerance of the homotopy"),
    }
    accuracy_levels = ({"h": 0.1}, {"h": 0.05}, {"h": 0.025})
    known_gaps = {
        "event-times": "an exit from sliding is a tangential change of the active set that FESD's elements "
        "need not resolve: it may stay on the step grid (an error of up to one step)",
    }

    def smooth_order(self) -> int | None:
        # Radau IIA with s stages is of order 2s - 1, Gauss-Legendre of order 2s, on a smooth arc
        s = int(self.settings["n_s"])
        return 2 * s - 1 if self.settings["scheme"] == "radau-iia" else 2 * s

    def setup(self, problem: "HybridProblem") -> None:
        from nsbench.problems.relay_feedback import RelayFeedback

        reason = type(self).unavailable()
        if reason:
            raise UnsupportedProblemError(f"{self.name}: {reason}")
        if not isinstance(problem, RelayFeedback):
            raise UnsupportedProblemError(
                f"{self.name}: nsbench writes only the relay feedback system (relay-feedback: two linear fields "
                f"either side of C x = 0) as a nosnoc model; {problem.name} ({problem.family or '?'} family) "
                "is not mapped"
            )
        super().setup(problem)
        self._solvers: dict[float, Any] = {}

    # ------------------------------------------------------------------ nosnoc's model and programs
    def _solver(self, problem, h: float) -> Any:
        """nosnoc's solver of one step of length ``h`` (built once per length: the span is part of the program)."""
        cache = self.__dict__.setdefault("_solvers", {})
        if h in cache:
            return cache[h]
        nosnoc = import_nosnoc()
        import casadi as ca

        a, b, c = problem.A, problem.B, problem.C
        x = ca.SX.sym("x", 3)
        ax = ca.mtimes(ca.DM(a), x)
        fields = ca.horzcat(ax + ca.DM(b), ax - ca.DM(b))  # region 1 (C x < 0): u = +1; region 2: u = -1
        model = nosnoc.NosnocModel(
            x=x, F=[fields], c=[ca.mtimes(ca.DM(c).T, x)], S=[np.array([[-1], [1]])], x0=np.zeros(3)
        )
        opts = nosnoc.NosnocOpts()
        s = self.settings
        opts.use_fesd = bool(s["switch_detection"])
        opts.pss_mode = nosnoc.PssMode.STEWART
        opts.irk_scheme = getattr(nosnoc.IrkSchemes, SCHEMES[s["scheme"]])
        opts.n_s = int(s["n_s"])
        opts.N_finite_elements = int(s["n_fe"])
        opts.comp_tol = float(s["comp_tol"])
        opts.sigma_N = min(opts.sigma_N, opts.comp_tol)  # the homotopy's floor (nosnoc's 1e-8): comp_tol reachable
        opts.terminal_time = float(h)
        opts.print_level = 0
        opts.homotopy_update_rule = nosnoc.HomotopyUpdateRule.SUPERLINEAR
        opts.tol_ipopt = None  # nosnoc's options share one IPOPT dict: preprocess sets it from comp_tol
        with quiet():
            solver = nosnoc.NosnocSolver(opts, model)
        cache[h] = solver
        return solver

    def _step(self, problem, h: float, x0: np.ndarray) -> tuple[list, int, bool]:
        """One program from ``x0`` over ``h``: ``([(dt, x, theta) per element], IPOPT iterations, converged)``,
        ``theta`` of shape ``(stages, 2)``."""
        nosnoc = import_nosnoc()
        solver = self._solver(problem, h)
        solver.set("x0", np.asarray(x0, dtype=float))
        with quiet():
            res = solver.solve()
        iters = int(sum(i for i in res["nlp_iter"] if i is not None))
        w = np.asarray(res["w_sol"], dtype=float)
        # theta at every stage of every element (nosnoc's index lists: [control stage][element][stage][system])
        stages = [np.array([w[np.asarray(st[0])] for st in fe]) for fe in solver.problem.ind_theta[0]]
        rows = [
            (float(dt), np.asarray(xk, dtype=float).ravel(), th)
            for dt, xk, th in zip(res["time_steps"], res["x_list"], stages)
        ]
        ok = res["status"] == nosnoc.Status.SUCCESS and all(np.all(np.isfinite(r[1])) for r in rows)
        return rows, iters, ok

    def _label(self, theta: np.ndarray) -> int:
        """The element's mode from its ``theta`` (module docstring)."""
        if float(np.min(theta)) > math.sqrt(float(self.settings["comp_tol"])):
            return _SLIDE
        return _UP if theta[0] >= theta[1] else _DOWN

    # ------------------------------------------------------------------ the run
    def integrate(self, request: SystemRequest) -> SystemResult:
        problem = request.problem
        span = request.t_end - request.t0
        n_steps = max(1, math.ceil(span / float(self.settings["h"]) - 1e-9))
        h = span / n_steps
        ts, ys = [request.t0], [np.array(request.y0, dtype=float)]
        modes = [int(problem.initial_mode(request.t0, request.y0)[0])]
        located: list[float] = []
        counts = {"nlp_solves": 0, "ipopt_iterations": 0, "halvings": 0}
        status, message = Status.SUCCESS, ""
        for i in range(n_steps):
            if i >= request.max_steps:
                status, message = Status.BUDGET_EXHAUSTED, f"{request.max_steps} steps used by t = {ts[-1]:.6g}"
                break
            t_end = request.t0 + (i + 1) * h if i < n_steps - 1 else request.t_end
            rows = self._advance(problem, ts[-1], t_end, h, ys[-1], 0, counts)
            if rows is None:
                status = Status.INTEGRATOR_FAILURE
                message = f"nosnoc's program failed at t = {ts[-1]:.6g}, with the step halved {MAX_HALVINGS} times"
                break
            for t_row, x_row, label, unlocated in rows:
                if label != modes[-1] and not unlocated and self.settings["switch_detection"]:
                    located.append(ts[-1])  # the element boundary where the label changes: FESD's own
                if t_row > ts[-1]:
                    ts.append(t_row)
                    ys.append(x_row)
                    modes.append(label)
                else:  # an element of zero length: its label stands, its state is the last one
                    modes[-1] = label
        return SystemResult(
            t=np.array(ts),
            y=np.array(ys),
            modes=np.array(modes, dtype=np.int64).reshape(-1, 1),
            switch_times=np.array(located) if self.settings["switch_detection"] else None,
            nsteps=len(ts) - 1,
            extra={key: float(value) for key, value in counts.items()},
            status=status,
            message=message,
        )

    def _advance(
        self, problem, t0: float, t1: float, length: float, x0: np.ndarray, depth: int, counts: dict
    ) -> list | None:
        """Rows ``(t, x, label, unlocated)`` of the elements from ``t0`` to ``t1`` (retried halved on failure),
        or ``None``. ``length`` is the nominal ``t1 - t0`` (one program per length, whatever the rounding of
        the times); ``unlocated``: the element starts on a step boundary, or its stages are not all in one
        mode (a label change at its start is then not a switch FESD located)."""
        counts["nlp_solves"] += 1
        elements, iters, ok = self._step(problem, length, x0)
        counts["ipopt_iterations"] += iters
        if ok:
            out, t = [], t0
            for j, (dt, xk, theta) in enumerate(elements):
                t = t1 if j == len(elements) - 1 else t + dt  # the step's end exactly, whatever the rounding
                labels = {self._label(row) for row in theta}
                # located only where the element after is in its new mode from its first stage on: an exit
                # inside an element (its first stages still sliding) is not at the element's boundary
                out.append((t, xk, self._label(theta[-1]), j == 0 or len(labels) > 1))
            return out
        if depth >= MAX_HALVINGS:
            return None
        counts["halvings"] += 1
        mid = t0 + 0.5 * (t1 - t0)
        first = self._advance(problem, t0, mid, 0.5 * length, x0, depth + 1, counts)
        if first is None:
            return None
        second = self._advance(problem, mid, t1, 0.5 * length, first[-1][1], depth + 1, counts)
        return None if second is None else first + second
