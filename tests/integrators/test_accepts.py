"""Integrators declare the problems they run by the problems' traits (``Capabilities.accepts``), and
set-up refuses, with the reason, a problem that declares none of them (issue 50, item 4)."""

from __future__ import annotations

import pytest

from nsbench import registry
from nsbench.errors import ConfigError, UnsupportedProblemError
from nsbench.integrators import get_integrator
from nsbench.integrators.base import (
    WHOLE_SYSTEM_ACCEPTS,
    ArcRequest,
    ArcResult,
    Capabilities,
    Integrator,
    accepted_traits,
)
from nsbench.problems import get_problem, list_problems
from nsbench.problems.base import TRAIT_NAMES, problem_traits


@pytest.mark.parametrize("accepts", [("belt",), (), ["sliding"], "sliding"])
def test_a_bad_accepts_is_refused_naming_the_traits(accepts):
    with pytest.raises(ConfigError) as caught:
        Capabilities(event_location="bisection", order=2, adaptive=False, accepts=accepts)
    message = str(caught.value)
    assert repr(accepts) in message
    assert all(t in message for t in TRAIT_NAMES)


class _SlidingOnly(Integrator):
    """A plug-in's event-driven method for switched first-order fields only (never integrates here)."""

    name = "sliding-only"
    capabilities = Capabilities(event_location="bisection", order=2, adaptive=False, accepts=("sliding",))

    def advance(self, request: ArcRequest) -> ArcResult:  # pragma: no cover - set-up is what is tested
        raise AssertionError("not run")


def test_a_plugin_accepts_the_problems_with_its_traits_and_refuses_the_others():
    integ = _SlidingOnly()
    integ.check_problem(get_problem("relay-feedback"))  # declares sliding: accepted
    with pytest.raises(UnsupportedProblemError) as caught:
        integ.check_problem(get_problem("one-dof"))
    assert str(caught.value) == (
        "sliding-only runs problems with a switched first-order field with sliding (the relay family) only "
        "(Capabilities.accepts); one-dof declares none of these traits"
    )


def test_a_whole_system_method_that_declares_nothing_takes_blocks_on_a_belt():
    from nsbench.integrators.switch_model import SwitchModel

    assert SwitchModel.capabilities.accepts is None
    assert accepted_traits(SwitchModel) == WHOLE_SYSTEM_ACCEPTS == ("belt_blocks",)


def _problems():
    return [get_problem(name) for name in list_problems()]


def test_every_integrator_refuses_each_problem_without_a_trait_it_accepts():
    """What ``accepts`` declares holds: no built-in runs a problem that declares none of its traits."""
    problems = _problems()
    declaring = 0
    for name in registry.names("integrators"):
        if registry.unavailable_reason("integrators", name) is not None:
            continue  # not installed here (an extra)
        accepts = accepted_traits(registry.load("integrators", name))
        if accepts is None:
            continue  # every problem, through its hybrid law
        declaring += 1
        integ = get_integrator(name)
        outside = [p for p in problems if not problem_traits(p).has_any(accepts)]
        assert outside, f"{name} accepts every built-in problem: its accepts says nothing"
        for problem in outside:
            with pytest.raises(UnsupportedProblemError) as caught:
                integ.check_problem(problem)
            assert problem.name in str(caught.value), name
    assert declaring >= 7  # cvode-bdf, cvode-adams, ida, moreau-jean, lugre, smoothing, switch-model (and the extras)
