"""``smoothing``: the regularised friction law on a stiff solver; its creep against exact's stick intervals."""

from __future__ import annotations

import numpy as np
import pytest

from nsbench import simulate
from nsbench.bench.metrics import stick_creep
from nsbench.errors import ConfigError, UnsupportedProblemError
from nsbench.integrators import get_integrator
from nsbench.integrators.smoothing import friction
from nsbench.problems import get_problem
from nsbench.testing import check_integrator


def _creep(eps, law="arctan"):
    problem = get_problem("one-dof")
    ref = simulate(problem, "exact", 8.0).events  # stuck from t = 0.100 on, the load below fs until t ~ 10
    grid = np.linspace(0.0, 8.0, 161)
    run = simulate(problem, "smoothing", 8.0, t_eval=grid, options={"eps": eps, "law": law})
    assert run.ok, run.message
    dense = run.trajectory[list(problem.state_names)].to_numpy().T
    return stick_creep(ref, grid, dense, problem.v0, 8.0), problem, run


@pytest.mark.parametrize("law", ["arctan", "tanh"])
def test_creep_falls_as_eps_grows(law):
    """While exact sticks, the smoothed block creeps at the u where the regularised force balances its load R
    (its acceleration is nearly 0): arctan: u = tan(pi R / (2 fs)) / eps, tanh: u = artanh(R / fs) / eps. The
    load grows with time, so the largest creep is at the last dense point inside the stick interval (t = 7.95,
    the span's end t = 8 being the interval's end), within 5% of the balance at t = 8 (R < fs)."""
    creeps = []
    for eps in (1e2, 1e3, 1e4):
        creep, problem, run = _creep(eps, law)
        c = problem.coefficients
        x, v = run.y_final
        load = c.c[0] * v + c.k[0] * x  # R of MODEL.md section 4, unforced, the run's own state
        u = (np.tan(np.pi * load / (2 * c.fs[0])) if law == "arctan" else np.arctanh(load / c.fs[0])) / eps
        assert creep.creep == pytest.approx(u, rel=0.05), (eps, creep.creep, u)
        creeps.append(creep.creep)
    assert creeps[0] > 5 * creeps[1] > 25 * creeps[2]


def test_the_regularised_law_and_its_derivative():
    fs = np.array([2.0])
    f, df = friction("arctan", fs, 10.0, np.array([0.1]))
    assert f[0] == pytest.approx(-2.0 * 2 / np.pi * np.arctan(1.0)) and df[0] == pytest.approx(-2.0 * 2 / np.pi * 5.0)
    f, df = friction("tanh", fs, 10.0, np.array([0.1]))
    assert f[0] == pytest.approx(-2.0 * np.tanh(1.0)) and df[0] == pytest.approx(-20.0 * (1 - np.tanh(1.0) ** 2))


def test_smoothing_breaks_away_at_the_kinetic_level():
    """No stiction: the block leaves stick where its load reaches fs (and the band), before exact's fr."""
    problem = get_problem("one-dof")
    ref = simulate(problem, "exact", 20.0).events
    run = simulate(problem, "smoothing", 20.0, options={"eps": 1e4})
    slips = run.events[run.events["kind"] == "slip"]["t"].to_numpy()
    assert slips.size and slips[0] < ref[ref["kind"] == "slip"]["t"].iloc[0] - 1.0


def test_conformance():
    results = check_integrator(
        "smoothing",
        checks=["protocol", "determinism", "inputs-not-mutated", "failure-status", "config-round-trip"],
        problem="one-dof",
    )
    failed = [(r.check, r.message) for r in results if r.status != "passed"]
    assert not failed, failed


def test_bad_input():
    with pytest.raises(ConfigError):
        get_integrator("smoothing", eps=0.0)
    with pytest.raises(ConfigError):
        get_integrator("smoothing", law="sigmoid")
    with pytest.raises(UnsupportedProblemError):
        get_integrator("smoothing").setup(get_problem("bouncing-ball"))


def test_a_non_coulomb_friction_law_is_refused_at_setup_with_its_name():
    # the method's force law is built on fs alone: under a weakening or Stribeck law it would integrate
    # another system, so it refuses (the rows of a suite say unsupported, with this reason)
    from nsbench import registry
    from nsbench.errors import UnsupportedProblemError
    from nsbench.problems import get_problem

    integ = registry.load("integrators", "smoothing")()
    for problem, law in (
        (get_problem("one-dof", case="leine"), "weakening"),
        (get_problem("two-dof", case=2, law="stribeck", fk=0.5, vs=0.2), "stribeck"),
    ):
        with pytest.raises(UnsupportedProblemError, match=f"regularises Coulomb's law .* the {law} friction law"):
            integ.setup(problem)


@pytest.mark.parametrize("eps", [1e2, 1e4])
def test_cvode_bdf_integrates_the_same_regularised_ode_as_scipy(eps):
    """``solver = 'CVODE-BDF'`` (SUNDIALS through scikit-sundae, the analytic Jacobian) steps the same ODE as
    scipy's Radau: at rtol = 1e-10, atol = 1e-12 both dense trajectories are within a small multiple of the
    tolerances of the true solution on this damped, stable run (measured 2e-10 to 1.4e-9 apart), so they
    agree far inside 1e-7, while a different eps changes the states by far more (checked below)."""
    problem = get_problem("one-dof")
    grid = np.linspace(0.0, 8.0, 161)
    names = list(problem.state_names)
    tight = {"eps": eps, "rtol": 1e-10, "atol": 1e-12}
    runs = {
        s: simulate(problem, "smoothing", 8.0, t_eval=grid, options={**tight, "solver": s})
        for s in ("Radau", "CVODE-BDF")
    }
    assert all(r.ok for r in runs.values()), [r.message for r in runs.values()]
    cvode = runs["CVODE-BDF"]
    assert cvode.counters.njev > 0 and cvode.counters.nsteps > 0  # CVODE's own Newton iterations, its own steps
    gap = np.max(np.abs(runs["Radau"].trajectory[names].to_numpy() - cvode.trajectory[names].to_numpy()))
    assert gap < 1e-7, gap
    other = simulate(problem, "smoothing", 8.0, t_eval=grid, options={**tight, "eps": 2 * eps, "solver": "CVODE-BDF"})
    assert np.max(np.abs(other.trajectory[names].to_numpy() - cvode.trajectory[names].to_numpy())) > 100 * gap
    assert list(cvode.events["kind"]) == list(runs["Radau"].events["kind"])


def test_cvode_bdf_reports_a_budget_and_a_failure_as_statuses():
    problem = get_problem("one-dof")
    run = simulate(problem, "smoothing", 8.0, options={"solver": "CVODE-BDF"}, max_steps=20)
    assert run.status.value == "step budget exhausted" and 0.0 < run.t_final < 8.0
