"""Test-only integrators of the bifurcation-target tests (importable by worker processes)."""

from __future__ import annotations

from nsbench.errors import UnsupportedProblemError
from nsbench.integrators.scipy_ import ScipyRK45


class Refusing(ScipyRK45):
    """Refuses every problem, as an integrator that cannot solve it does."""

    name = "refusing-test"
    accuracy_levels = ({"rtol": 1e-6, "atol": 1e-8},)

    def setup(self, problem):
        raise UnsupportedProblemError(f"{self.name} refuses {problem.name}")
