"""Every number option of every registered integrator refuses NaN and the infinities, naming itself.

``inf`` is a value only where it means "no limit" (a largest step: ``Option.unbounded``);
there it is accepted and runs as the unbounded default does.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import nsbench
from nsbench.integrators import integrator_class, list_integrators


def _number_options():
    for name in list_integrators():
        try:
            cls = integrator_class(name)
        except Exception:  # an optional engine that is not installed: its own tests say so
            continue
        for option, spec in cls.options.items():
            if spec.kind in (int, float) and spec.choices is None:
                yield name, option, spec


NUMBER_OPTIONS = list(_number_options())


@pytest.mark.parametrize("value", [math.nan, math.inf, -math.inf])
@pytest.mark.parametrize("name, option, spec", NUMBER_OPTIONS, ids=[f"{n}-{o}" for n, o, _ in NUMBER_OPTIONS])
def test_nan_and_infinities_are_refused_unless_inf_means_no_limit(name, option, spec, value):
    if spec.unbounded and value == math.inf:
        assert nsbench.get_integrator(name, **{option: value}).settings[option] == math.inf
        return
    with pytest.raises(nsbench.ConfigError, match=f"option {option} = .*(finite|>)"):
        nsbench.get_integrator(name, **{option: value})


def test_the_unbounded_options_are_the_largest_steps():
    assert {(n, o) for n, o, spec in NUMBER_OPTIONS if spec.unbounded} == {
        (n, "max_step") for n, o, _ in NUMBER_OPTIONS if o == "max_step"
    }


@pytest.mark.parametrize("name", ["cvode-adams", "scipy-dop853"])
def test_an_infinite_largest_step_runs_as_no_limit(name):
    problem = nsbench.get_problem("one-dof", case=1)  # unforced: scipy's default has no cap either
    unbounded = nsbench.simulate(problem, name, 30.0, options={"max_step": math.inf})
    default = nsbench.simulate(problem, name, 30.0)
    assert unbounded.ok and len(unbounded.events) > 3
    assert np.array_equal(unbounded.events.t.to_numpy(), default.events.t.to_numpy())
