"""``scipy-*`` adapters against ``exact`` on the linear 2-DOF cases."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import nsbench
from nsbench.integrators.scipy_ import ScipyDOP853
from tests.conftest import exact_events, max_time_error, same_sequence

SCIPY = ["scipy-rk45", "scipy-dop853", "scipy-radau", "scipy-bdf", "scipy-lsoda"]


@pytest.mark.parametrize("case", [1, 2])
def test_dop853_tight_reproduces_exact_over_300(case):
    p = nsbench.get_problem("two-dof", case=case)
    res = nsbench.simulate(p, "scipy-dop853", 300.0, options={"rtol": 1e-12, "atol": 1e-12})
    ref = exact_events("two-dof", case)
    assert res.ok
    assert same_sequence(res.events, ref)
    assert max_time_error(res.events, ref) <= 1e-8


@pytest.mark.parametrize("name", SCIPY)
def test_every_scipy_method_finds_the_event_sequence(name):
    p = nsbench.get_problem("two-dof", case=2)
    res = nsbench.simulate(p, name, 100.0, options={"rtol": 1e-10, "atol": 1e-12})
    ref = exact_events("two-dof", 2, 100.0)
    assert res.ok, res.message
    assert same_sequence(res.events, ref)
    assert max_time_error(res.events, ref) <= 1e-5
    assert res.counters.nfev > 0 and res.counters.nsteps > 0
    if nsbench.get_integrator(name).capabilities.needs_jacobian:
        assert res.counters.njev > 0


class _Unchecked(ScipyDOP853):
    """``scipy-dop853`` as ``solve_ivp`` runs it: only the signs at its step ends are looked at."""

    name = "test-dop853-unchecked"
    check_steps = False
    capabilities = dataclasses.replace(ScipyDOP853.capabilities, checks_steps=False)


def test_an_uncapped_step_over_forced_stick_guards_is_caught_by_the_step_check():
    # Documented pitfall: with every block stuck the field is constant, so without the default max_step
    # cap the step grows past the forcing period and the force-driven slip of block 2 at t ~ 33.46 is
    # stepped over when only the signs at the step ends are looked at. The per-step check flags those
    # steps (the guard's rates at their ends) and integrates them again: the sequence of exact.
    p = nsbench.get_problem("two-dof", case=2)
    ref = exact_events("two-dof", 2)
    tight = {"rtol": 1e-12, "atol": 1e-12}
    capped = nsbench.simulate(p, "scipy-dop853", 300.0, options=tight)
    uncapped = nsbench.simulate(p, "scipy-dop853", 300.0, options={**tight, "max_step": np.inf})
    unchecked = nsbench.simulate(p, _Unchecked(**tight, max_step=np.inf), 300.0)
    assert same_sequence(capped.events, ref)
    assert not same_sequence(unchecked.events, ref)
    assert same_sequence(uncapped.events, ref) and uncapped.counters.extra["check_reruns"] > 0
    assert max_time_error(uncapped.events, ref) <= 1e-8  # as the capped run at this tolerance (test above)


def test_tolerance_controls_the_event_error():
    p = nsbench.get_problem("two-dof", case=1)
    ref = exact_events("two-dof", 1, 100.0)
    errors = []
    for rtol in (1e-6, 1e-9, 1e-12):
        res = nsbench.simulate(p, "scipy-dop853", 100.0, options={"rtol": rtol, "atol": rtol * 1e-2})
        assert same_sequence(res.events, ref)
        errors.append(max_time_error(res.events, ref))
    assert errors[0] > errors[1] > errors[2]


def test_step_budget_is_a_status_not_an_exception(case1):
    res = nsbench.simulate(case1, "scipy-rk45", 300.0, max_steps=50)
    assert res.status is nsbench.Status.BUDGET_EXHAUSTED
    assert res.counters.nsteps <= 52
    assert res.t_final < 300.0


def test_options_are_validated():
    with pytest.raises(nsbench.ConfigError, match="rtol"):
        nsbench.get_integrator("scipy-dop853", rtol=-1)
    with pytest.raises(nsbench.ConfigError, match="unknown option 'h'"):
        nsbench.get_integrator("scipy-dop853", h=0.1)
