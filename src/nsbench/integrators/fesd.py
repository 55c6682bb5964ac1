"""``fesd``: finite elements with switch detection (FESD) through nosnoc, on the Filippov problems.

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

**What is mapped.** :mod:`nsbench.integrators.fesd_models` writes each problem as a nosnoc
model: the relay feedback system, Casella's sliding test, the circle oscillator and the
friction oscillators with ``fs = fr`` on every block (one switching function ``v_i - v0`` per
block; Filippov sliding on it is the stick, and a stuck block's reported state is snapped to
``v_i = v0``). Stiction (``fs < fr``) is not a Filippov system and is refused at setup with
each block's values, as is every problem not mapped. ``n_fe`` defaults to the number of
switching functions and one more (several blocks may switch within one step).

**What it returns.** The states at every finite-element end (``t`` the accumulated
element lengths: nosnoc's ``switch_times`` output holds element lengths, not times), the
mode of each element read off its ``theta`` at the element's end (sliding where
``min theta > sqrt(comp_tol)``, the complementarity residual's scale, else the region of
the larger ``theta``; per switching function) and, with ``switch_detection``, the element
boundaries inside a step where a label changes as
:attr:`~nsbench.integrators.whole.SystemResult.switch_times` (with the switching function as
``switch_elements``), if every stage of the element after is in its new mode (a change on
the step grid is the grid's, and one inside an element, its first stages in the old mode,
is not at the boundary: neither is a located switch). An exit from sliding (the relay's
exit, a block's break-away) is never a located switch: it leaves the surface tangentially,
and the boundary where its label flips is where ``theta`` passes the label's floor, up to
4e-4 before the state leaves (measured on the relay). The events are inferred from the
labels (the relay family, :mod:`nsbench.hybrid.inference` rule 6) or from the snapped
velocities (the friction family, rules 1-4) and the located times reported beside them (the
event log's ``t_located``).

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
from nsbench.integrators.fesd_models import FesdModel, default_elements, fesd_model
from nsbench.integrators.whole import SystemRequest, SystemResult, WholeSystem
from nsbench.status import Status

if TYPE_CHECKING:  # pragma: no cover
    from nsbench.problems.base import HybridProblem

#: The IRK schemes nosnoc offers (``IrkSchemes``), by nsbench's option value.
SCHEMES = {"radau-iia": "RADAU_IIA", "gauss-legendre": "GAUSS_LEGENDRE"}
#: How often a failed step is halved before the run gives up (``h / 2**MAX_HALVINGS`` is the shortest step).
MAX_HALVINGS = 3


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
    """FESD (finite elements with switch detection) through nosnoc, step by step, on the Filippov systems
    :mod:`nsbench.integrators.fesd_models` writes."""

    name = "fesd"
    ecosystem = "nosnoc"
    backend_modules = ("nosnoc", "casadi")
    extra = "fesd"
    capabilities = Capabilities(
        event_location="switch-detection",
        order=None,
        adaptive=False,
        supports_nonlinear=True,  # casadi writes any smooth field and surface: cubic springs, the circle
        step_option="h",
        family="time-stepping",
        # a switched first-order field (its side of each surface, or its sliding), or blocks on a belt with
        # fs = fr (Coulomb sliding on v = v0 is the stick); fesd_models refuses the rest with the reason
        accepts=("sliding", "belt_blocks"),
    )
    options = {
        "h": Option(
            0.05, float, lower=0.0, doc="step: the span of one nosnoc program (rounded so whole steps fill the span)"
        ),
        "n_fe": Option(
            None,
            int,
            lower=1,
            lower_inclusive=True,
            nullable=True,
            doc="finite elements per step (None: one per switching function and one more)",
        ),
        "n_s": Option(3, int, lower=1, lower_inclusive=True, upper=9, doc="stages of the IRK scheme"),
        "scheme": Option("radau-iia", str, choices=tuple(SCHEMES), doc="the IRK scheme"),
        "switch_detection": Option(
            True, bool, doc="FESD's element lengths as unknowns (False: nosnoc's plain IRK on fixed elements)"
        ),
        "comp_tol": Option(1e-12, float, lower=0.0, upper=1e-2, doc="complementarity tolerance of the homotopy"),
    }
    accuracy_levels = ({"h": 0.1}, {"h": 0.05}, {"h": 0.025})
    known_gaps = {
        "event-times": "an exit from sliding (the relay's, a block's break-away) is a tangential change of the "
        "active set that FESD's elements need not resolve: the relay's may stay on the step grid (an error of up "
        "to one step); a break-away, inside an element, leaves the relaxation's error (1e-7 to 6e-6 in its time)",
        "cubic-event-times": "as event-times: the break-aways (measured 1.6e-5 on one-dof case 4 with r_f = 1)",
        "switch-convergence": "the break-aways' error is the relaxation's, of the order of sqrt(comp_tol) in the "
        "state after the exit, whatever h: it need not fall from h = 0.1 to 0.025 (6.7e-9, 1.1e-5 on one-dof)",
        "convergence": "the belt presets' smooth arc (amplitude 0.02 over 4 time units) is at IPOPT's tolerance at "
        "every level: its errors (1.1e-12, 1.9e-12, 2.1e-12 on one-dof) are that noise, not a trend",
        "energy-balance": "no dense output: the states between element ends are linear interpolations, so the "
        "balance closes to the square of an element (1.1e-4 at h = 0.05 on one-dof case 2), not to 1e-6",
    }

    def smooth_order(self) -> int | None:
        # Radau IIA with s stages is of order 2s - 1, Gauss-Legendre of order 2s, on a smooth arc
        s = int(self.settings["n_s"])
        return 2 * s - 1 if self.settings["scheme"] == "radau-iia" else 2 * s

    def setup(self, problem: "HybridProblem") -> None:
        reason = type(self).unavailable()
        if reason:
            raise UnsupportedProblemError(f"{self.name}: {reason}")
        super().setup(problem)  # the traits (Capabilities.accepts)
        self._model = fesd_model(problem, self.name)  # the mapping, or the reason it has none
        self._solvers: dict[float, Any] = {}

    def model(self, problem: "HybridProblem") -> FesdModel:
        """The nosnoc model of ``problem`` (:mod:`~nsbench.integrators.fesd_models`), built at setup."""
        model = self.__dict__.get("_model")
        return model if model is not None else fesd_model(problem, self.name)

    def n_fe(self, problem: "HybridProblem") -> int:
        """Finite elements per step: the option, or one per switching function and one more."""
        given = self.settings["n_fe"]
        return int(given) if given is not None else default_elements(self.model(problem))

    # ------------------------------------------------------------------ nosnoc's model and programs
    def _solver(self, problem, h: float) -> Any:
        """nosnoc's solver of one step of length ``h`` (built once per length: the span is part of the program)."""
        cache = self.__dict__.setdefault("_solvers", {})
        if h in cache:
            return cache[h]
        nosnoc = import_nosnoc()
        import casadi as ca

        model = self.model(problem).nosnoc_model(nosnoc, ca)
        opts = nosnoc.NosnocOpts()
        s = self.settings
        opts.use_fesd = bool(s["switch_detection"])
        opts.pss_mode = nosnoc.PssMode.STEWART
        opts.irk_scheme = getattr(nosnoc.IrkSchemes, SCHEMES[s["scheme"]])
        opts.n_s = int(s["n_s"])
        opts.N_finite_elements = self.n_fe(problem)
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
        """One program from the model's state ``x0`` over ``h``: ``([(dt, x, theta) per element], IPOPT
        iterations, converged)``, ``theta`` of shape ``(stages, switching functions, 2)``."""
        nosnoc = import_nosnoc()
        solver = self._solver(problem, h)
        solver.set("x0", np.asarray(x0, dtype=float))
        with quiet():
            res = solver.solve()
        iters = int(sum(i for i in res["nlp_iter"] if i is not None))
        w = np.asarray(res["w_sol"], dtype=float)
        # theta at every stage of every element (nosnoc's index lists: [control stage][element][stage][system])
        stages = [np.array([[w[np.asarray(ind)] for ind in st] for st in fe]) for fe in solver.problem.ind_theta[0]]
        rows = [
            (float(dt), np.asarray(xk, dtype=float).ravel(), th)
            for dt, xk, th in zip(res["time_steps"], res["x_list"], stages)
        ]
        ok = res["status"] == nosnoc.Status.SUCCESS and all(np.all(np.isfinite(r[1])) for r in rows)
        return rows, iters, ok

    # ------------------------------------------------------------------ the run
    def integrate(self, request: SystemRequest) -> SystemResult:
        problem = request.problem
        model = self.model(problem)
        span = request.t_end - request.t0
        n_steps = max(1, math.ceil(span / float(self.settings["h"]) - 1e-9))
        h = span / n_steps
        ts, ys = [request.t0], [np.array(request.y0, dtype=float)]
        modes = [np.asarray(problem.initial_mode(request.t0, request.y0), dtype=np.int64)]
        located: list[tuple[float, int]] = []
        counts = {"nlp_solves": 0, "ipopt_iterations": 0, "halvings": 0}
        status, message = Status.SUCCESS, ""
        for i in range(n_steps):
            if i >= request.max_steps:
                status, message = Status.BUDGET_EXHAUSTED, f"{request.max_steps} steps used by t = {ts[-1]:.6g}"
                break
            t_end = request.t0 + (i + 1) * h if i < n_steps - 1 else request.t_end
            rows = self._advance(problem, ts[-1], t_end, h, model.start(ts[-1], ys[-1]), 0, counts)
            if rows is None:
                status = Status.INTEGRATOR_FAILURE
                message = f"nosnoc's program failed at t = {ts[-1]:.6g}, with the step halved {MAX_HALVINGS} times"
                break
            for t_row, x_row, label, fresh in rows:
                if self.settings["switch_detection"]:
                    # the element boundary where a label changes, the element after in its new mode: FESD's own;
                    # an exit from sliding (a break-away) is tangential, its boundary where theta passes the
                    # label's floor, before the state leaves: not a located switch (module docstring)
                    switched = (label != modes[-1]) & fresh & ~model.sliding(modes[-1])
                    located += [(ts[-1], int(k)) for k in np.flatnonzero(switched)]
                if t_row > ts[-1]:
                    ts.append(t_row)
                    ys.append(model.state(x_row, label))
                    modes.append(label)
                else:  # an element of zero length: its label stands, its state is the last one
                    modes[-1] = label
                    ys[-1] = model.state(x_row, label)
        return self._result(ts, ys, modes, located, counts, status, message)

    def _result(self, ts, ys, modes, located, counts, status, message) -> SystemResult:
        """The run's :class:`SystemResult` (``located``: ``(time, subsystem)`` of each switch FESD located)."""
        detect = bool(self.settings["switch_detection"])
        return SystemResult(
            t=np.array(ts),
            y=np.array(ys),
            modes=np.array(modes, dtype=np.int64).reshape(len(ts), -1),
            switch_times=np.array([t for t, _ in located], dtype=float) if detect else None,
            switch_elements=np.array([k for _, k in located], dtype=np.int64) if detect else None,
            nsteps=len(ts) - 1,
            extra={key: float(value) for key, value in counts.items()},
            status=status,
            message=message,
        )

    def _advance(
        self, problem, t0: float, t1: float, length: float, x0: np.ndarray, depth: int, counts: dict
    ) -> list | None:
        """Rows ``(t, x, label, fresh)`` of the elements from ``t0`` to ``t1`` (retried halved on failure),
        or ``None``. ``length`` is the nominal ``t1 - t0`` (one program per length, whatever the rounding of
        the times); ``x`` the model's state; ``fresh`` per switching function: the element starts inside
        the step and every stage of it is in one mode (a label change at its start is then a switch FESD
        located)."""
        counts["nlp_solves"] += 1
        elements, iters, ok = self._step(problem, length, x0)
        counts["ipopt_iterations"] += iters
        if ok:
            model = self.model(problem)
            floor = math.sqrt(float(self.settings["comp_tol"]))
            out, t = [], t0
            for j, (dt, xk, theta) in enumerate(elements):
                t = t1 if j == len(elements) - 1 else t + dt  # the step's end exactly, whatever the rounding
                labels = np.array([model.label(stage, floor) for stage in theta])
                # an exit inside an element (its first stages still sliding) is not at the element's boundary
                fresh = np.all(labels == labels[-1], axis=0) & (j > 0)
                out.append((t, xk, labels[-1], fresh))
            return out
        if depth >= MAX_HALVINGS:
            return None
        counts["halvings"] += 1
        mid = t0 + 0.5 * (t1 - t0)
        first = self._advance(problem, t0, mid, 0.5 * length, x0, depth + 1, counts)
        if first is None:
            return None
        x_mid = first[-1][1]
        second = self._advance(problem, mid, t1, 0.5 * length, x_mid, depth + 1, counts)
        return None if second is None else first + second
