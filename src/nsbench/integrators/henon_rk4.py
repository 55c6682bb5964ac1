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

import numpy as np

from nsbench.integrators.base import Capabilities, CompiledArcs, Option


class HenonRK4(CompiledArcs):
    """Classical RK4 at fixed step ``h`` with Henon's method for every guard and section."""

    name = "henon-rk4"
    capabilities = Capabilities(
        event_location="henon", order=4, adaptive=False, needs_jacobian=False,
        supports_nonlinear=True, precision="double", step_option="h",
    )
    options = {"h": Option(0.01, float, lower=0.0, doc="step size (time units)")}
    accuracy_levels = ({"h": 0.04}, {"h": 0.01}, {"h": 0.0025}, {"h": 0.000625})
    counter_names = ("henon_steps", "bisections")

    def build_kernel(self, problem):
        from nsbench.integrators._henon_kernel import OPTIONS, henon_arc, scratch
        from nsbench.model.abi import kernel_data
        from nsbench.model.kernel import ArcKernel, arc_table

        n, g = problem.n_states, problem.max_guards
        kernel = ArcKernel(arc_table(henon_arc, problem), kernel_data(f2a=scratch(n, 2, g)),
                           np.array([float(self.settings[name]) for name in OPTIONS]), self.counter_names,
                           name=self.name)

        def prepare_run(n_sections: int):
            if kernel.data.f2a.shape[1] < n_sections:
                kernel.data = kernel_data(f2a=scratch(n, n_sections, g))
            return kernel.data

        kernel.prepare_run = prepare_run
        return kernel
