"""An integrator outside nsbench brings a compiled arc kernel of its own, and the core runs it.

The compiled loop calls an integrator's arc kernel through the address table
the integrator hands it (:func:`nsbench.model.kernel.arc_table`); it imports no
integrator. Here the kernel is a numba function of this test module (not of
nsbench): it runs RK4's arc (``henon_arc``, the step it builds on) and counts
its own calls in a counter slot the built-in kernel leaves free. The core runs
it with no change: the event log is ``henon-rk4``'s to the last bit, and the
counter says the plug-in's function ran once per arc.
"""

from __future__ import annotations

import numpy as np
from numba import njit

import nsbench
from nsbench.integrators._henon_kernel import henon_arc
from nsbench.integrators.henon_rk4 import HenonRK4
from nsbench.model.abi import X2


@njit(cache=True, nogil=True, _nrt=False)
def counting_arc(kd, fo, p, arc, sec, hits, dense, si, y_out, cnt):
    """The plug-in's arc: RK4's, and one more in its own counter slot."""
    cnt[X2] += 1
    return henon_arc(kd, fo, p, arc, sec, hits, dense, si, y_out, cnt)


class CountingRK4(HenonRK4):
    """A third party's integrator: RK4 with a compiled arc kernel of its own module."""

    name = "test-counting-rk4"
    counter_names = ("henon_steps", "bisections", "plugin_arcs")

    def build_kernel(self, problem):
        from nsbench.model.kernel import arc_table

        kernel = super().build_kernel(problem)
        kernel.table = arc_table(counting_arc, problem)
        return kernel


def test_the_core_runs_a_compiled_kernel_it_does_not_import():
    problem = nsbench.get_problem("two-dof", case=2)
    want = nsbench.simulate(problem, "henon-rk4", 60.0)
    got = nsbench.simulate(problem, CountingRK4(), 60.0)
    assert got.ok and want.ok, (got.message, want.message)
    assert len(got.events) == len(want.events) >= 10
    assert np.array_equal(got.events["t"].to_numpy(), want.events["t"].to_numpy())
    assert got.counters.nsteps == want.counters.nsteps
    assert got.counters.extra["henon_steps"] == want.counters.extra["henon_steps"]
    # the plug-in's own function ran, once per arc: one arc per event and the last one to t_end
    assert got.counters.extra["plugin_arcs"] == len(got.events) + 1
