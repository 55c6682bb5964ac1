"""Test-only plug-ins that misbehave on purpose, importable by worker processes (registered at run time).

An integrator that never returns from ``advance``, and problem factories that loop or raise:
the supervised ``check``, ``continuation``, ``bench`` and ``bifurcation`` must end each of
them within their limits with a verdict. The integrator wraps a real one (no fake results).
"""

from __future__ import annotations

import os
import time

from nsbench.integrators.exact import ExactIntegrator
from nsbench.integrators.scipy_ import ScipyRK45


class HangingAdvance(ScipyRK45):
    """Never returns from ``advance`` (a plug-in whose stepping loops)."""

    name = "hanging-advance-test"
    accuracy_levels = ({"rtol": 1e-6, "atol": 1e-8},)

    def advance(self, request):
        time.sleep(3600)


def looping_problem(case=None, dimensional=False, **params):
    """A problem factory that never returns."""
    time.sleep(3600)


def raising_problem(case=None, dimensional=False, **params):
    """A problem factory with a bug."""
    raise RuntimeError("plug-in bug in the problem factory")


#: Name of each problem factory when registered.
PROBLEMS = {"looping-problem-test": looping_problem, "raising-problem-test": raising_problem}


#: ``CrashingPast`` ends its process at belt speeds above this: past the end of the first branch of
#: two-dof case 1 swept over v0 = 0.2:0.3 in 16 steps (it ends at 0.27442, and every value tried on it is
#: at most one step of 0.00625 beyond, below 0.2807), at the first value sought after it (0.28077).
CRASH_PAST_V0 = 0.2807


class CrashingPast(ExactIntegrator):
    """``exact`` that kills its process (``os._exit(7)``) once set up at a belt speed above :data:`CRASH_PAST_V0`."""

    name = "crashing-past-test"

    def setup(self, problem):
        if getattr(problem, "v0", 0.0) > CRASH_PAST_V0:
            os._exit(7)
        return super().setup(problem)
