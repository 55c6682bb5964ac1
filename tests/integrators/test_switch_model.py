"""``switch-model``: Leine's switch model on a scipy solver, against exact's switches."""

from __future__ import annotations

import numpy as np
import pytest

from nsbench import simulate
from nsbench.bench.metrics import stick_creep
from nsbench.errors import ConfigError
from nsbench.integrators import get_integrator
from nsbench.problems import get_problem
from nsbench.testing import check_integrator


def _sequence(events):
    return list(zip(events["kind"], events["block"]))


def test_switches_approach_exacts_as_the_band_narrows():
    problem = get_problem("one-dof")
    ref = simulate(problem, "exact", 40.0).events
    errors = []
    for eta in (1e-3, 1e-4, 1e-5):
        run = simulate(problem, "switch-model", 40.0, options={"eta": eta, "rtol": 1e-10, "atol": 1e-12})
        assert run.ok and _sequence(run.events) == _sequence(ref), eta
        errors.append(np.max(np.abs(run.events["t"].to_numpy() - ref["t"].to_numpy())))
    assert errors[0] > errors[1] > errors[2]


def test_a_stuck_block_stays_within_the_band():
    problem = get_problem("one-dof")
    eta = 1e-4
    ref = simulate(problem, "exact", 11.0).events
    grid = np.linspace(0.0, 11.0, 221)
    run = simulate(problem, "switch-model", 11.0, t_eval=grid, options={"eta": eta})
    dense = run.trajectory[list(problem.state_names)].to_numpy().T
    creep = stick_creep(ref, grid, dense, problem.v0, 11.0)
    assert creep.creep <= eta * (1 + 1e-9)
    assert creep.drift <= eta * 11.0


def test_two_dof_case_1_has_exacts_switches():
    problem = get_problem("two-dof", case=1)
    ref = simulate(problem, "exact", 30.0).events
    run = simulate(problem, "switch-model", 30.0, options={"eta": 1e-5, "rtol": 1e-10, "atol": 1e-12})
    assert _sequence(run.events) == _sequence(ref)
    assert np.max(np.abs(run.events["t"].to_numpy() - ref["t"].to_numpy())) < 1e-2


def test_conformance():
    results = check_integrator(
        "switch-model",
        checks=[
            "protocol",
            "determinism",
            "inputs-not-mutated",
            "switch-convergence",
            "failure-status",
            "config-round-trip",
        ],
        problem="one-dof",
    )
    failed = [(r.check, r.message) for r in results if r.status != "passed"]
    assert not failed, failed


def test_bad_input():
    for bad in ({"eta": 0.0}, {"eta": -1.0}, {"solver": "Euler"}, {"rtol": 1.0}):
        with pytest.raises(ConfigError):
            get_integrator("switch-model", **bad)


def test_a_non_coulomb_friction_law_is_refused_at_setup_with_its_name():
    # the method's force law is built on fs alone: under a weakening or Stribeck law it would integrate
    # another system, so it refuses (the rows of a suite say unsupported, with this reason)
    from nsbench import registry
    from nsbench.errors import UnsupportedProblemError
    from nsbench.problems import get_problem

    integ = registry.load("integrators", "switch-model")()
    for problem, law in (
        (get_problem("one-dof", case="leine"), "weakening"),
        (get_problem("two-dof", case=2, law="stribeck", fk=0.5, vs=0.2), "stribeck"),
    ):
        with pytest.raises(UnsupportedProblemError, match=f"regularises Coulomb's law .* the {law} friction law"):
            integ.setup(problem)


@pytest.mark.parametrize("solver, eta", [("CVODE-Adams", 1e-4), ("CVODE-BDF", 1e-5)])
def test_sundials_cvode_runs_the_switch_model(solver, eta):
    """The same discontinuous field on SUNDIALS CVODE (scikit-sundae, difference-quotient Jacobian): exact's
    switch sequence, and switching times as close to exact's as scipy RK45's on the same band (both place the
    switches on the band's edges: the band, not the solver, sets the error once rtol is 1e-10)."""
    problem = get_problem("one-dof")
    ref = simulate(problem, "exact", 40.0).events
    tight = {"eta": eta, "rtol": 1e-10, "atol": 1e-12}
    run = simulate(problem, "switch-model", 40.0, options={**tight, "solver": solver})
    assert run.ok and _sequence(run.events) == _sequence(ref), run.events
    rk = simulate(problem, "switch-model", 40.0, options=tight)
    err = np.max(np.abs(run.events["t"].to_numpy() - ref["t"].to_numpy()))
    err_rk = np.max(np.abs(rk.events["t"].to_numpy() - ref["t"].to_numpy()))
    assert err == pytest.approx(err_rk, rel=0.05), (err, err_rk)
