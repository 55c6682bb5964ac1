"""``Integrator.check_problem``: the refusals of ``setup`` without compiling (a command's early check)."""

from __future__ import annotations

import pytest

from nsbench.errors import UnsupportedProblemError
from nsbench.integrators import get_integrator
from nsbench.problems import get_problem


@pytest.mark.parametrize(
    "name, options, problem, match",
    [
        ("exact", {}, dict(name="two-dof", case=3), "linear problems only"),  # capabilities
        ("henon-rk4", {"h": 5.0}, dict(name="two-dof", case=1), "stability limit"),  # its own setup's refusal
        ("heyoka", {}, dict(name="impact-oscillator"), "friction family"),
        (
            "cvode-bdf",
            {},
            dict(name="bouncing-ball"),
            r"blocks on a belt \(the friction oscillators' formulation\) only",
        ),
        ("ida", {}, dict(name="bouncing-ball"), r"blocks on a belt \(the friction oscillators' formulation\) only"),
        # the default refusal names the requirement, nothing of exact's method (exact-mp steps by Taylor series)
        ("exact-mp", {}, dict(name="henon-heiles"), r"piecewise-linear problems only \(<henon-heiles> is not"),
    ],
)
def test_check_problem_refuses_what_setup_refuses(name, options, problem, match):
    p = get_problem(problem.pop("name"), **problem)
    for method in ("check_problem", "setup"):
        with pytest.raises(UnsupportedProblemError, match=match):
            getattr(get_integrator(name, **options), method)(p)


@pytest.mark.parametrize("name", ["exact", "henon-rk4", "ofapi", "heyoka", "cvode-adams"])
def test_check_problem_accepts_without_building_anything(name):
    integ = get_integrator(name)
    integ.check_problem(get_problem("two-dof", case=1))
    assert not hasattr(integ, "_kernel") and not hasattr(integ, "_models") and not hasattr(integ, "_solvers")
