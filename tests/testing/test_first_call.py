"""The kit's first-call flag (:mod:`nsbench.testing._first_call`) and the built-ins that warm up in ``setup``."""

from __future__ import annotations

import numba
import pytest

from nsbench.integrators import base, get_integrator
from nsbench.integrators.scipy_ import ScipyRK45
from nsbench.problems import get_problem
from nsbench.testing import FIRST_CALL_FLOOR, FIRST_CALL_RATIO, FirstCall, first_call_cost


@pytest.mark.parametrize(
    "first, second, flagged",
    [
        (1.0, 0.01, True),  # 100x and 0.99 s above: a compilation
        (FIRST_CALL_FLOOR * 0.9, 1e-6, False),  # a large ratio on calls too short to hold a compilation
        (2.0, 0.5, False),  # 4x: a slow method, not a first-call cost
        (FIRST_CALL_RATIO * 0.1 + FIRST_CALL_FLOOR * 1.01, 0.1, True),  # just past both limits
    ],
)
def test_the_flag_needs_both_the_ratio_and_the_floor(first, second, flagged):
    cost = FirstCall("x", "advance", 0.0, first, second)
    assert cost.flagged is flagged
    assert ("move it into setup" in cost.message) is flagged
    assert f"first advance {first:.3g} s" in cost.message


class CompilesOnFirstCall(ScipyRK45):
    """scipy's RK45 that compiles twelve numba functions in its first ``advance`` rather than in ``setup``."""

    name = "test-compiles-on-first-call"

    def setup(self, problem):
        base.Integrator.setup(self, problem)  # without scipy's warm arc
        self._compiled = False

    def advance(self, request):
        if not self._compiled:
            for k in range(12):  # fresh closures: each a compilation of its own (no cache)
                numba.njit(lambda x, k=k: x * k + 1.0)(1.0)
            self._compiled = True
        return super().advance(request)


def test_a_first_call_that_compiles_is_flagged():
    # twelve numba compilations take well over the floor (about 0.1 s each, more on a loaded machine);
    # the second call is one short arc of RK45
    cost = first_call_cost(CompilesOnFirstCall())
    assert cost.call == "advance"
    assert cost.first > cost.second
    assert cost.flagged, cost.message
    assert "test-compiles-on-first-call's cost" in cost.message


@pytest.mark.parametrize(
    "name, options",
    [
        ("scipy-rk45", {"rtol": 3.3e-7}),
        ("scipy-radau", {"rtol": 3.3e-7}),
        ("smoothing", {"rtol": 3.3e-7}),
        ("switch-model", {"rtol": 3.3e-7}),
        ("lugre", {"rtol": 3.3e-7}),
    ],
)
def test_builtins_whose_first_call_loads_the_law_make_it_in_setup_and_not_in_check_problem(name, options):
    # the flag found these (first call 0.7-3.3 s against a second of 1-250 ms): their setup now runs
    # one short call; a configuration of its own, so no other test's call counts here
    integ = get_integrator(name, **options)
    problem = get_problem("two-dof", case=2)
    key = (type(integ), repr(sorted(integ.settings.items())), problem.law.source)
    integ.check_problem(problem)
    assert key not in base._FIRST_CALLS  # refusals only: nothing loaded in the command's own process
    integ.setup(problem)
    assert key in base._FIRST_CALLS
