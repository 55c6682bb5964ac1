"""``moreau-jean``: Moreau-Jean time-stepping of the friction family, measured against ``exact``."""

from __future__ import annotations

import numpy as np
import pytest

from nsbench import simulate
from nsbench.errors import ConfigError, UnsupportedProblemError
from nsbench.integrators import get_integrator
from nsbench.integrators.moreau_jean import MAX_BLOCKS, stiffness_matrix, uniform_steps
from nsbench.problems import get_problem
from nsbench.testing import check_integrator


def _sequence(events):
    return list(zip(events["kind"], events["block"]))


@pytest.fixture(scope="module")
def one_dof_exact():
    problem = get_problem("one-dof")
    return problem, simulate(problem, "exact", 40.0).events


def test_switching_time_error_falls_linearly_with_h(one_dof_exact):
    """Order 1 across switches on the 1-DOF standard scenario, with exact's switch sequence at every h.

    A switch falls anywhere within a step, so the error at one h is ``C h`` with ``C`` between
    about 0.15 and 2 depending on that phase (measured), and a slope through four halvings alone
    can land anywhere from 0.3 to 1.8. The trend is fitted through a dense geometric ladder
    (four values per halving) over seven halvings, where the phase averages out.
    """
    problem, ref = one_dof_exact
    hs = 1e-2 / 2 ** np.linspace(0.0, 7.0, 29)
    errors = []
    for h in hs:
        run = simulate(problem, "moreau-jean", 40.0, options={"h": h})
        assert run.ok and _sequence(run.events) == _sequence(ref), f"h = {h:.3g}: switch sequence differs"
        errors.append(np.max(np.abs(run.events["t"].to_numpy() - ref["t"].to_numpy())))
    order = np.polyfit(np.log(hs), np.log(errors), 1)[0]
    assert 0.8 <= order <= 1.2, f"fitted order {order:.3f}"
    assert max(e / h for e, h in zip(errors, hs)) < 3.0  # first order with a modest constant


def test_smooth_arc_is_second_order_at_theta_half_and_first_order_otherwise():
    assert get_integrator("moreau-jean").smooth_order() == 2
    assert get_integrator("moreau-jean", theta=1.0).smooth_order() == 1
    results = check_integrator("moreau-jean", checks=["declared-order"], options={"theta": 1.0, "h": 1e-3},
                               problem="one-dof")
    assert results[0].status == "passed", results[0].message


def test_two_dof_case_1_has_exacts_switches():
    problem = get_problem("two-dof", case=1)
    ref = simulate(problem, "exact", 60.0).events
    run = simulate(problem, "moreau-jean", 60.0, options={"h": 1e-3})
    assert _sequence(run.events) == _sequence(ref)
    assert np.max(np.abs(run.events["t"].to_numpy() - ref["t"].to_numpy())) < 5 * 1e-3
    # its counters, by slot name: one one-step problem per step, one candidate solve at least for each
    extra = run.counters.extra
    assert extra["one_step_problems"] == run.counters.nsteps == 60_000
    assert 0 < extra["enumerations"] < 60 and extra["candidate_solves"] > extra["one_step_problems"]


def test_block_on_ground_passes_through_zero_speed_as_reversals():
    problem = get_problem("block-on-ground")
    ref = simulate(problem, "exact", 40.0).events
    run = simulate(problem, "moreau-jean", 40.0, options={"h": 1e-3})
    assert _sequence(run.events) == _sequence(ref)
    assert np.max(np.abs(run.events["t"].to_numpy() - ref["t"].to_numpy())) < 5 * 1e-3
    assert run.y_final[0] == pytest.approx(ref["x1"].iloc[-1], abs=1e-3)  # the rest position


def test_a_stuck_block_moves_exactly_with_the_belt():
    problem = get_problem("one-dof")
    v0 = problem.v0
    grid = np.linspace(0.0, 8.0, 81)
    run = simulate(problem, "moreau-jean", 8.0, y0=[0.3, v0], t_eval=grid, options={"h": 1e-2})
    assert len(run.events) == 0
    tr = run.trajectory
    assert np.max(np.abs(tr["v1"] - v0)) == 0.0
    assert np.max(np.abs(tr["x1"] - (0.3 + v0 * tr["t"]))) < 1e-13


def test_conformance():
    results = check_integrator("moreau-jean", checks=["protocol", "determinism", "inputs-not-mutated",
                                                      "switch-convergence", "declared-order", "convergence",
                                                      "refuses-unsupported", "stuck-stays-stuck",
                                                      "failure-status", "config-round-trip"])
    failed = [(r.check, r.message) for r in results if r.status != "passed"]
    assert not failed, failed


@pytest.mark.parametrize("problem, match", [
    (lambda: get_problem("chain", n=MAX_BLOCKS + 1), "enumerating"),
    (lambda: get_problem("two-dof", case=3), "cubic"),
])
def test_refuses_what_it_cannot_run(problem, match):
    with pytest.raises(UnsupportedProblemError, match=match):
        get_integrator("moreau-jean").setup(problem())


@pytest.mark.parametrize("options", [{"h": 0.0}, {"h": -1e-3}, {"theta": 0.4}, {"theta": 1.5}, {"h": float("nan")}])
def test_bad_options_are_refused(options):
    with pytest.raises(ConfigError):
        get_integrator("moreau-jean", **options)


def test_whole_steps_fill_the_span_and_the_operators_are_the_chains():
    assert uniform_steps(0.0, 1.0, 0.3) == (4, 0.25)
    assert np.array_equal(stiffness_matrix([1.0, 2.0, 3.0]),
                          [[3.0, -2.0, 0.0], [-2.0, 5.0, -3.0], [0.0, -3.0, 3.0]])


def test_a_budget_stops_the_run_with_a_status():
    run = simulate(get_problem("one-dof"), "moreau-jean", 10.0, options={"h": 1e-3}, max_steps=100)
    assert run.status.value == "step budget exhausted" and run.t_final == pytest.approx(0.1)


def test_the_bouncing_ball_impacts_and_rest():
    """Newton's impact law at the velocity level: the impact times converge to the closed form at first order;
    the ball rests once its impact speed is below one step's gain under gravity (e |v| <= g h), missing the
    remaining flights, which last about 2 h / (e (1 - e)) = 12.5 h in all (e = 0.8): the rest time is within
    20 h of the accumulation time."""
    problem = get_problem("bouncing-ball")
    closed = problem.impact_times(6)
    errors = []
    for h in (1e-3, 1e-4):
        run = simulate(problem, "moreau-jean", 6.0, options={"h": h})
        assert run.ok, run.message
        kinds = list(run.events["kind"])
        assert kinds[:6] == ["impact"] * 6 and kinds[-1] == "rest" and kinds.count("rest") == 1
        err = np.max(np.abs(run.events["t"].to_numpy()[:6] - closed))
        assert err <= 5 * h
        errors.append(err)
        assert abs(run.events["t"].iloc[-1] - problem.accumulation_time()) <= 20 * h
        assert abs(run.y_final[1]) < 1e-12 and run.mode_final == (1,)
    assert errors[1] < errors[0] / 4
