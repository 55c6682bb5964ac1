"""``moreau-jean``: Moreau-Jean time-stepping (event-capturing) of the friction family.

A fixed step ``h`` and the theta-method (``theta`` = 1/2 by default) on positions
and velocities; the friction *impulse* of each step obeys the set-valued
Coulomb law with stiction at the step's new velocity, and that one-step problem
is solved exactly (to rounding) by enumerating the stick/slip status of the
blocks up to :data:`MAX_BLOCKS` blocks, and by an active-set (semismooth Newton)
iteration on longer chains (option ``one_step``;
:mod:`nsbench.integrators._moreau_jean_kernel`). No event is located: the
switches are inferred afterwards from the steps by the rule of every
whole-system method (:mod:`nsbench.hybrid.inference`: the phases read off the
trajectory; the status the enumeration chose is returned but not read), so
switching times are first order in ``h``.
On a smooth arc (no status change) the scheme is the trapezoidal rule for
``theta = 1/2`` (order 2) and first order otherwise.

Runs the friction family with linear springs (``one-dof``, ``two-dof``,
``chain``, ``block-on-ground``) and the bouncing ball
(Newton's impact law at the velocity level, the impulses reported for the event
inference: :func:`nsbench.integrators._moreau_jean_kernel.mj_ball`); refuses cubic
springs (the one-step problem would need a Newton iteration, not implemented).

Counters: ``nsteps`` the steps; ``nfev`` the evaluations of the one-step problem, the
work a step does in place of right-hand-side evaluations: each assembles the step's
new velocities from the forces for one stick/slip status (a linear solve) and tests
them against the friction law. A step whose previous status still holds costs one;
a switching step costs one more per status the enumeration tries (or per solve of
the active set). On the bouncing ball each step evaluates its contact law once:
``nfev = nsteps``.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from nsbench.errors import UnsupportedProblemError
from nsbench.integrators.base import Capabilities, Option
from nsbench.integrators.whole import SystemRequest, SystemResult, WholeSystem
from nsbench.status import Status

#: Longest chain the enumeration of the one-step problem accepts (3**8 = 6561 statuses at a switching step).
MAX_BLOCKS = 8
#: Values of option ``one_step``: ``auto`` is the enumeration up to :data:`MAX_BLOCKS` blocks, the active set above.
ONE_STEP = ("auto", "enumeration", "active-set")


def stiffness_matrix(k) -> np.ndarray:
    """The chain's stiffness matrix: spring 1 ties block 1 to the ground, spring ``i`` blocks ``i-1`` and ``i``."""
    n = len(k)
    K = np.zeros((n, n))
    for i in range(n):
        K[i, i] += k[i]
        if i > 0:
            K[i - 1, i - 1] += k[i]
            K[i - 1, i] -= k[i]
            K[i, i - 1] -= k[i]
    return K


def uniform_steps(t0: float, t_end: float, h: float) -> tuple[int, float]:
    """``(n, h_used)``: the fewest equal steps no longer than ``h`` that fill ``[t0, t_end]``."""
    span = t_end - t0
    n = max(1, math.ceil(span / h * (1.0 - 1e-12)))
    return n, span / n


def rest_window(e: float, h: float, n_impacts: int) -> tuple[float, float]:
    """``(lo, hi)``: where the ball's inferred ``rest`` lies relative to the accumulation time, ``lo <= t_rest - t_Z <= hi``.

    For the scheme of :func:`nsbench.integrators._moreau_jean_kernel.mj_ball` at ``theta = 1/2`` (its flights
    are exact samples of the parabolas) and ``n_impacts`` impacts before the rest (docs/families.md,
    "The bouncing ball: where the rest falls", derives it). Each resolved impact moves the accumulation time
    its trajectory predicts by ``D`` in ``(-h / e, h]``, to first order in ``g h / (e |v|)``; the rest label
    cuts off the tail of the last flight, ``G`` in ``(-2 h, (2 + e) h / (1 - e) - h / 2]``:
    ``t_rest - t_Z = sum(D) - G``. The first-order range of ``D`` widens for flights of a few steps; the
    bound was checked on a grid of ``e`` from 0.3 to 0.95 and ``h`` from 1e-4 to 1e-2 (tests).
    """
    k = max(int(n_impacts) - 1, 0)
    return -k * h / e - (2.0 + e) * h / (1.0 - e) + 0.5 * h, k * h + 2.0 * h


class MoreauJean(WholeSystem):
    """Moreau-Jean time-stepping: theta-method, fixed step h, friction impulses by enumeration or active set."""

    name = "moreau-jean"
    capabilities = Capabilities(
        event_location="inferred-from-status",
        order=1,
        adaptive=False,
        supports_nonlinear=False,
        step_option="h",
        family="time-stepping",
        # the friction oscillators, and the bouncing ball (Newton's impact law at the velocity level)
        accepts=("belt_blocks", "falling_mass"),
    )
    options = {
        "h": Option(1e-3, float, lower=0.0, doc="fixed step (rounded down so whole steps fill the span)"),
        "theta": Option(
            0.5,
            float,
            lower=0.0,
            upper=1.0,
            doc="theta of the theta-method (1/2: trapezoidal on smooth arcs, 1: implicit Euler)",
        ),
        "one_step": Option(
            "auto",
            str,
            choices=ONE_STEP,
            doc="solver of the one-step friction problem: enumeration of the statuses (chains up to "
            f"{MAX_BLOCKS} blocks), active-set iteration (any chain), or auto (the first where "
            "it applies)",
        ),
    }
    accuracy_levels = ({"h": 1e-2}, {"h": 1e-3}, {"h": 1e-4})
    known_gaps = {
        "event-times": "first order in h: switching times within 1e-5 of exact on case 2 need h ~ 1e-6 "
        "(millions of steps per unit time); the bench measures how the error falls with h",
        "energy-balance": "time-stepping dissipates at switches (the impulse acts over a whole step): the energy "
        "balance closes to O(h), not to 1e-6",
    }

    def check_settings(self) -> None:
        if self.settings["theta"] < 0.5:
            from nsbench.errors import ConfigError

            raise ConfigError(
                f"{self.name}: option theta = {self.settings['theta']!r} must be >= 0.5 "
                "(below 1/2 the theta-method is unstable on the undamped springs)"
            )

    def smooth_order(self) -> int:
        return 2 if self.settings["theta"] == 0.5 else 1

    def setup(self, problem) -> None:
        super().setup(problem)
        if problem.traits.impacts and not problem.traits.falling_mass:
            raise UnsupportedProblemError(
                f"{self.name}: of the impact problems it knows the bouncing ball only, not {problem.name}"
            )
        nb = getattr(problem, "n_blocks", 0)
        if nb > MAX_BLOCKS and self.settings["one_step"] == "enumeration":
            raise UnsupportedProblemError(
                f"{self.name}: one_step = 'enumeration' enumerates 3^n statuses, for chains of at most "
                f"{MAX_BLOCKS} blocks; {problem.name} has {nb} (one_step = 'active-set' or 'auto' runs it)"
            )
        from nsbench.integrators import _moreau_jean_kernel as kern

        self._kern = kern
        if getattr(self, "_checking", False):  # a check stops after the refusals
            return
        # compile (or load) and run a few steps, untimed
        self.integrate(
            SystemRequest(
                problem=problem, t0=0.0, y0=problem.initial_state(), t_end=4 * self.settings["h"], max_steps=10
            )
        )

    def _data(self, problem, h: float):
        key = (id(problem), h)
        cache = self.__dict__.setdefault("_ops", {})
        if key not in cache:
            c = problem.coefficients
            m, cc, k = (np.array(a, dtype=float) for a in (c.m, c.c, c.k))
            K = stiffness_matrix(k)
            method = self._method(len(m))
            W, winv = self._kern.operators(
                m, cc, K, h, self.settings["theta"], inverses=method == self._kern.ENUMERATION
            )
            cache.clear()
            cache[key] = self._kern.StepData(
                W,
                winv,
                m,
                cc,
                K,
                np.array(c.fs, dtype=float),
                np.array(c.fr, dtype=float),
                float(c.F),
                float(c.w),
                float(c.v0),
                float(self.settings["theta"]),
                float(h),
                method,
                self._kern.active_set_cap(len(m)),
            )
        return cache[key]

    def _method(self, n_blocks: int) -> int:
        """The one-step solver's code for a chain of ``n_blocks`` blocks."""
        choice = self.settings["one_step"]
        if choice == "enumeration" or (choice == "auto" and n_blocks <= MAX_BLOCKS):
            return self._kern.ENUMERATION
        return self._kern.ACTIVE_SET

    def _ball(self, request: SystemRequest, n_steps: int, n_run: int, h: float, budget: bool) -> SystemResult:
        """The bouncing ball (:func:`nsbench.integrators._moreau_jean_kernel.mj_ball`); impacts as ``impulses``."""
        problem: Any = request.problem  # a falling mass (its traits say so): it declares g and e
        T = np.empty(n_run + 1)
        Y = np.empty((n_run + 1, 2))
        modes = np.zeros((n_run + 1, 1), np.int64)
        P = np.zeros(n_run + 1)
        self._kern.mj_ball(
            float(problem.g),
            float(problem.e),
            float(self.settings["theta"]),
            h,
            float(request.t0),
            float(request.y0[0]),
            float(request.y0[1]),
            n_run,
            T,
            Y,
            modes,
            P,
        )
        status, message = Status.SUCCESS, ""
        if budget:
            status, message = (
                Status.BUDGET_EXHAUSTED,
                (f"{n_steps} steps of h = {h:.3g} needed, budget {request.max_steps}; stopped at t = {T[-1]:.6g}"),
            )
        else:
            T[-1] = request.t_end
        return SystemResult(
            t=T,
            y=Y,
            modes=modes,
            impulses=P.reshape(-1, 1),
            nfev=n_run,  # one evaluation of the contact law (free flight or impact) per step
            nsteps=n_run,
            extra={"impulse_steps": int(np.count_nonzero(P))},
            status=status,
            message=message,
        )

    def __getstate__(self) -> dict[str, Any]:
        state = dict(self.__dict__)
        state.pop("_kern", None)
        state.pop("_ops", None)
        return state

    def integrate(self, request: SystemRequest) -> SystemResult:
        problem = request.problem
        if not hasattr(self, "_kern"):
            from nsbench.integrators import _moreau_jean_kernel as kern

            self._kern = kern
        n_steps, h = uniform_steps(request.t0, request.t_end, self.settings["h"])
        budget = n_steps > request.max_steps
        n_run = min(n_steps, int(request.max_steps))
        if problem.traits.falling_mass:
            return self._ball(request, n_steps, n_run, h, budget)
        data = self._data(problem, h)
        nb = len(data.m)
        T = np.empty(n_run + 1)
        Y = np.empty((n_run + 1, 2 * nb))
        modes = np.empty((n_run + 1, nb), np.int64)
        counters = np.zeros(self._kern.N_COUNTERS, np.int64)
        mode0 = np.array(problem.initial_mode(request.t0, request.y0), dtype=np.int64)
        y0 = np.ascontiguousarray(request.y0, dtype=float)
        out = self._kern.Trajectory(T, Y, modes, counters)
        code, done = self._kern.mj_run(data, float(request.t0), y0, mode0, n_run, out)
        status, message = Status.SUCCESS, ""
        if code == self._kern.NO_STATUS:
            status = Status.INTEGRATOR_FAILURE
            message = f"no consistent stick/slip status at step {done} (t = {T[done]:.6g})"
        elif code == self._kern.NOT_CONVERGED:
            status = Status.INTEGRATOR_FAILURE
            message = (
                f"the active-set solver found no consistent stick/slip status within "
                f"{self._kern.active_set_cap(nb)} solves at step {done} (t = {T[done]:.6g})"
            )
        elif budget:
            status, message = (
                Status.BUDGET_EXHAUSTED,
                (f"{n_steps} steps of h = {h:.3g} needed, budget {request.max_steps}; stopped at t = {T[done]:.6g}"),
            )
        if done == n_steps and status.ok:
            T[done] = request.t_end  # the last step ends exactly at t_end (t0 + n h may round off it)
        kern = self._kern
        # the second slot counts the steps whose first candidate failed: searched by enumeration or by the
        # active set, whichever the run used
        searched = "enumerations" if data.method == kern.ENUMERATION else "active_set_searches"
        extra: dict[str, float] = {
            "one_step_problems": int(counters[kern.ONE_STEP_PROBLEMS]),
            searched: int(counters[kern.ENUMERATIONS]),
            "candidate_solves": int(counters[kern.CANDIDATE_SOLVES]),
        }
        return SystemResult(
            t=T[: done + 1],
            y=Y[: done + 1],
            modes=modes[: done + 1],
            # the work of the steps is their one-step problems: every candidate status solved and tested
            nfev=int(counters[kern.CANDIDATE_SOLVES]),
            njev=0,
            nsteps=int(done),
            extra=extra,
            status=status,
            message=message,
        )
