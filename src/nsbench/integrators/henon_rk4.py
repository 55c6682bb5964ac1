"""``henon-rk4``: fixed-step classical RK4 with Henon's trick on every surface (METHODS.md section 7).

After a step that crosses a guard ``S``, one RK4 step of size ``-S`` in the
independent variable ``sigma = S`` (field ``(f, 1) / dS/dt`` over ``(y, t)``, with
the *old* mode's field) lands on the surface; ``t`` is carried as a state so the
forced cases are handled. This keeps RK4's order 4 for event times. A guard
that dips across and back within one step is caught from the cubic Hermite
interpolant of the guard (values and rates at the step ends), and located by
bisection on RK4 sub-steps, as is any Henon point outside its step (near-grazing).
Sections use the same Henon step; dense output is the cubic Hermite
interpolant, consistent with order 4. The arcs run in the compiled kernel
:mod:`nsbench.integrators._henon_kernel`; the step grid starts at each arc's start.
"""

from __future__ import annotations

import math

import numpy as np

from nsbench.errors import ConfigError, UnsupportedProblemError
from nsbench.integrators.base import Capabilities, CompiledArcs, Option

#: RK4 is stable for ``|h lambda|`` up to ``2 sqrt(2)`` on the imaginary axis (2.785 on the real one).
STABILITY_LIMIT = 2.0 * math.sqrt(2.0)
#: Below this ``|h lambda|`` a step changes a state of order one by less than its rounding.
RESOLUTION_LIMIT = float(np.finfo(float).eps)


def fastest_rate(problem) -> float:
    """The largest ``|lambda|`` of the field linearised at the problem's start, at least ``1 / time_scale``.

    On the friction family the field is taken with every block slipping, which
    carries every spring and damper (a stuck block is frozen: from rest on a belt
    at rest every block starts stuck, with a zero Jacobian), so this is the
    fastest motion of the linear part; cubic springs only stiffen it away from
    the rest state. A field without a linear part (the falling ball: a nilpotent
    Jacobian, every eigenvalue 0) still moves on the problem's own time scale.
    """
    y = np.asarray(problem.initial_state(), dtype=float)
    if problem.traits.belt_blocks:
        mode = (1,) * problem.n_blocks
    else:
        mode = problem.initial_mode(0.0, y)
    rate = float(np.max(np.abs(np.linalg.eigvals(problem.jacobian(mode, 0.0, y)))))
    return max(rate, 1.0 / problem.time_scale)


class HenonRK4(CompiledArcs):
    """Classical RK4 at fixed step ``h`` with Henon's method for every guard and section."""

    name = "henon-rk4"
    capabilities = Capabilities(
        event_location="henon",
        order=4,
        adaptive=False,
        needs_jacobian=False,
        supports_nonlinear=True,
        precision="double",
        step_option="h",
    )
    options = {"h": Option(0.01, float, lower=0.0, doc="step size (time units)")}
    accuracy_levels = ({"h": 0.04}, {"h": 0.01}, {"h": 0.0025}, {"h": 0.000625})
    counter_names = ("henon_steps", "bisections")

    def check_settings(self) -> None:
        h = self.settings["h"]
        if not math.isfinite(h):
            raise ConfigError(f"{self.name}: option h = {h!r} must be a finite step size > 0")

    def setup(self, problem) -> None:
        """Refuse a step that RK4 cannot take on ``problem``, then build and load the kernel.

        ``h`` times the fastest rate of the problem must lie between the
        rounding of a step (below it the state never moves, and the step count
        of a span can exceed any integer) and RK4's stability limit (above it
        every step amplifies the motion; a step longer than the span would be
        cut to the span and end in one unstable step).
        """
        h, rate = float(self.settings["h"]), fastest_rate(problem)
        if h * rate > STABILITY_LIMIT:
            raise UnsupportedProblemError(
                f"{self.name}: h = {h:g} is beyond RK4's stability limit on this problem (h times its fastest "
                f"rate {rate:.4g} is {h * rate:.3g} > {STABILITY_LIMIT:.3f}); use h <= {STABILITY_LIMIT / rate:.3g}"
            )
        if h * rate < RESOLUTION_LIMIT:
            raise UnsupportedProblemError(
                f"{self.name}: h = {h:g} is too small to move the state in double precision (h times the "
                f"problem's fastest rate {rate:.4g} is {h * rate:.3g} < {RESOLUTION_LIMIT:.3g}); use "
                f"h >= {RESOLUTION_LIMIT / rate:.3g}"
            )
        super().setup(problem)

    def build_kernel(self, problem):
        from nsbench.integrators._henon_kernel import OPTIONS, henon_arc, scratch
        from nsbench.model.abi import kernel_data
        from nsbench.model.kernel import ArcKernel, arc_table

        n, g = problem.n_states, problem.max_guards
        kernel = ArcKernel(
            arc_table(henon_arc, problem),
            kernel_data(f2a=scratch(n, 2, g)),
            np.array([float(self.settings[name]) for name in OPTIONS]),
            self.counter_names,
            name=self.name,
        )

        def prepare_run(n_sections: int):
            if kernel.data.f2a.shape[1] < n_sections:
                kernel.data = kernel_data(f2a=scratch(n, n_sections, g))
            return kernel.data

        kernel.prepare_run = prepare_run
        return kernel
