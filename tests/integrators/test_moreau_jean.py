"""``moreau-jean``: Moreau-Jean time-stepping of the friction family, measured against ``exact``."""

from __future__ import annotations

import numpy as np
import pytest

from nsbench import simulate
from nsbench.errors import ConfigError, UnsupportedProblemError
from nsbench.integrators import get_integrator
from nsbench.integrators._moreau_jean_kernel import spd_inverse
from nsbench.integrators.moreau_jean import MAX_BLOCKS, rest_window, stiffness_matrix, uniform_steps
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


def _phase_averaged_error(problem, ref, h, span, k=4):
    """The largest switching-time error of a run, averaged over ``k`` offsets of the step grid.

    A run starts at ``t0 = phi h`` (``phi`` = 1/8, 3/8, 5/8, 7/8) from exact's state there and takes whole
    steps of exactly ``h`` (its span is the whole number of them nearest ``span``), so the break-away, which a time-stepping method can
    only take at a step boundary, falls at a phase spread evenly over the step."""
    names = list(problem.state_names)
    phis = (np.arange(k) + 0.5) / k * h
    starts = simulate(problem, "exact", float(phis[-1]) * (1 + 1e-6), t_eval=phis).trajectory[names].to_numpy()
    worst = []
    n = round(span / h)
    for phi, y0 in zip(phis, starts):
        run = simulate(problem, "moreau-jean", float(phi) + n * h, t0=float(phi), y0=y0, options={"h": h})
        assert run.ok and _sequence(run.events) == _sequence(ref), f"h = {h:.3g}, t0 = {phi:.3g}"
        assert run.counters.nsteps == n  # whole steps of h: the offset is the phase
        worst.append(np.max(np.abs(run.events["t"].to_numpy() - ref["t"].to_numpy())))
    return float(np.mean(worst))


@pytest.mark.parametrize("h0", [1e-2, 3.5e-3, 1.25e-3])
def test_phase_averaged_switching_time_error_is_first_order_over_three_halvings(h0):
    """The issue's check: order between 0.8 and 1.2 over three halvings, at several starting h.

    The largest switching-time error of one run is ``C h`` with ``C`` set by where the break-away falls in
    its step (a stuck block can only leave at a step boundary): ``C`` jumps between 0.15 and 2 as h changes,
    and a slope through four values of h lands anywhere from 0.3 to 1.8. Averaged over four offsets of the
    step grid (the phase spread over the step) it is a well-defined quantity, ``C`` = 0.38 at every h
    (measured), and its slope is 1.00 +- 0.01. The span [0, 20] holds one break-away (the first stick, the
    break-away, the next stick and the next break-away, whose errors all follow from the first one's
    phase); over longer spans the later break-aways add phases of their own, offset from the first by an
    amount that changes with h, which no offset of the grid averages out (measured over [0, 40]: slopes 0.7
    to 1.6 even so)."""
    problem = get_problem("one-dof")
    ref = simulate(problem, "exact", 20.0 + h0).events
    assert list(ref["kind"]) == ["stick", "slip", "stick", "slip"]
    hs = h0 / 2.0 ** np.arange(4)
    errors = [_phase_averaged_error(problem, ref, h, 20.0) for h in hs]
    order = np.polyfit(np.log(hs), np.log(errors), 1)[0]
    assert 0.8 <= order <= 1.2, f"fitted order {order:.3f}, errors {errors}"
    ratios = np.array(errors) / hs
    assert ratios.max() < 1.1 * ratios.min(), ratios  # one constant C at every h (measured 0.377 to 0.380)


def test_smooth_arc_is_second_order_at_theta_half_and_first_order_otherwise():
    assert get_integrator("moreau-jean").smooth_order() == 2
    assert get_integrator("moreau-jean", theta=1.0).smooth_order() == 1
    results = check_integrator(
        "moreau-jean", checks=["declared-order"], options={"theta": 1.0, "h": 1e-3}, problem="one-dof"
    )
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


def test_the_forced_block_on_ground_converges_to_exacts_stick_slip_cycle():
    """Issue 48 item 11: the forced variant (F = 1.5, w = 0.5: 6 reversals, then 13 sticks and 13 slips over
    [0, 100]), the natural test of time-stepping on stick-slip cycles. exact's sequence at every h, the largest
    switching-time error first order (measured 2.0e-2, 1.7e-3, 2.5e-4: between 0.1 h and 3 h)."""
    problem = get_problem("block-on-ground", F=1.5, w=0.5)
    ref = simulate(problem, "exact", 100.0).events
    errors = []
    for h in (1e-2, 1e-3, 1e-4):
        run = simulate(problem, "moreau-jean", 100.0, options={"h": h})
        assert run.ok and _sequence(run.events) == _sequence(ref), h
        errors.append(np.max(np.abs(run.events["t"].to_numpy() - ref["t"].to_numpy())))
        assert errors[-1] <= 3 * h
    assert errors[0] > 5 * errors[1] > 25 * errors[2]


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
    results = check_integrator(
        "moreau-jean",
        checks=[
            "protocol",
            "determinism",
            "inputs-not-mutated",
            "switch-convergence",
            "declared-order",
            "convergence",
            "refuses-unsupported",
            "stuck-stays-stuck",
            "failure-status",
            "config-round-trip",
        ],
    )
    failed = [(r.check, r.message) for r in results if r.status != "passed"]
    assert not failed, failed


@pytest.mark.parametrize(
    "problem, options, match",
    [
        (lambda: get_problem("chain", n=MAX_BLOCKS + 1, h=0.0), {"one_step": "enumeration"}, "enumerates 3\\^n"),
        (lambda: get_problem("two-dof", case=3), {}, "cubic"),
    ],
)
def test_refuses_what_it_cannot_run(problem, options, match):
    with pytest.raises(UnsupportedProblemError, match=match):
        get_integrator("moreau-jean", **options).setup(problem())


def _pattern_start(n):
    """A deterministic spread of starting states along the chain, so that blocks stick, slip and reverse at
    different times (from the problem's own start, at rest, all blocks stick in the same step)."""
    i = np.arange(1, n + 1)
    y0 = np.empty(2 * n)
    y0[0::2], y0[1::2] = 1.5 * np.sin(1.3 * i), 0.5 * np.cos(0.7 * i)
    return y0


def _per_block(events):
    """Each block's own switch sequence and times: blocks switching in the same step may be logged in any
    order (their times agree to rounding), so sequences are compared block by block."""
    return {b: (list(g["kind"]), g["t"].to_numpy()) for b, g in events.groupby("block")}


@pytest.mark.parametrize("n", range(2, MAX_BLOCKS + 1))
def test_active_set_gives_the_enumerations_answer(n):
    """Both one-step solvers accept a status only if it passes the same consistency test, and every switch
    of these runs has one consistent status: the runs may differ only by the rounding of two ways of
    solving the same linear systems (inverse times vector, Thomas' algorithm), about 1e-16 per step on a
    non-expanding scheme; over 6000 steps that is far inside 1e-10 (measured: at most 7e-14)."""
    problem = get_problem("chain", n=n, h=0.0)
    y0, grid = _pattern_start(n), np.linspace(0.0, 12.0, 121)
    names = list(problem.state_names)
    for theta in (0.5, 1.0):
        runs = [
            simulate(
                problem, "moreau-jean", 12.0, y0=y0, t_eval=grid, options={"h": 2e-3, "theta": theta, "one_step": m}
            )
            for m in ("enumeration", "active-set")
        ]
        assert all(r.ok for r in runs), [r.message for r in runs]
        assert len(runs[0].events) > n  # switches happen: the solvers are exercised
        assert list(zip(runs[0].events["kind"], runs[0].events["block"])) == list(
            zip(runs[1].events["kind"], runs[1].events["block"])
        )
        gap = np.max(np.abs(runs[0].trajectory[names].to_numpy() - runs[1].trajectory[names].to_numpy()))
        assert gap < 1e-10, (theta, gap)
        assert "active_set_searches" in runs[1].counters.extra and "enumerations" in runs[0].counters.extra


@pytest.mark.parametrize("n", [16, 32])
def test_a_long_chain_converges_to_exacts_switches(n):
    """Beyond the enumeration (``one_step = 'auto'`` picks the active set): on 16 and 32 blocks, every block
    has exact's switch sequence, at a first-order error (at most 3 h, as on the 1-DOF scenario; measured
    0.2 h to 0.7 h) that falls with h."""
    problem = get_problem("chain", n=n, h=0.0)
    y0 = _pattern_start(n)
    ref = _per_block(simulate(problem, "exact", 20.0, y0=y0).events)
    assert sum(len(k) for k, _ in ref.values()) > n
    errors = []
    for h in (3e-3, 1e-3, 1e-4):
        run = simulate(problem, "moreau-jean", 20.0, y0=y0, options={"h": h})
        assert run.ok and "active_set_searches" in run.counters.extra, run.message
        got = _per_block(run.events)
        assert {b: k for b, (k, _) in got.items()} == {b: k for b, (k, _) in ref.items()}, f"h = {h}"
        errors.append(max(np.max(np.abs(got[b][1] - ref[b][1])) for b in ref))
        assert errors[-1] <= 3 * h, (h, errors[-1])
    assert errors[-1] < errors[0] / 10


def test_the_active_sets_iteration_cap_ends_the_run_with_a_failure(monkeypatch):
    """A step that finds no consistent status within the cap ends the run with a failure status and the
    reason. With a cap of one solve, the first step whose previous status is inconsistent (the block
    reaching the belt at t = 0.1 on the 1-DOF scenario) is such a step."""
    from nsbench.integrators import _moreau_jean_kernel as kern

    monkeypatch.setattr(kern, "active_set_cap", lambda n: 1)
    run = simulate(get_problem("one-dof"), "moreau-jean", 1.0, options={"h": 1e-2, "one_step": "active-set"})
    assert run.status.value == "integrator failure"
    assert "active-set solver found no consistent stick/slip status within 1 solves" in run.message
    assert run.t_final == pytest.approx(0.1, abs=0.011)


@pytest.mark.parametrize("options", [{"h": 0.0}, {"h": -1e-3}, {"theta": 0.4}, {"theta": 1.5}, {"h": float("nan")}])
def test_bad_options_are_refused(options):
    with pytest.raises(ConfigError):
        get_integrator("moreau-jean", **options)


def test_whole_steps_fill_the_span_and_the_operators_are_the_chains():
    assert uniform_steps(0.0, 1.0, 0.3) == (4, 0.25)
    assert np.array_equal(stiffness_matrix([1.0, 2.0, 3.0]), [[3.0, -2.0, 0.0], [-2.0, 5.0, -3.0], [0.0, -3.0, 3.0]])


def test_a_budget_stops_the_run_with_a_status():
    run = simulate(get_problem("one-dof"), "moreau-jean", 10.0, options={"h": 1e-3}, max_steps=100)
    assert run.status.value == "step budget exhausted" and run.t_final == pytest.approx(0.1)


def test_the_bouncing_ball_impacts_and_rest():
    """Newton's impact law at the velocity level: the impact times converge to the closed form at first order;
    the ball rests once its impact speed is below one step's gain under gravity (e |v| <= g h), inside the
    window rest_window derives (docs/families.md)."""
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
        lo, hi = rest_window(problem.e, h, kinds.count("impact"))
        assert lo <= run.events["t"].iloc[-1] - problem.accumulation_time() <= hi
        assert abs(run.y_final[1]) < 1e-12 and run.mode_final == (1,)
    assert errors[1] < errors[0] / 4


@pytest.mark.parametrize(
    "e, x0, h, t_end",
    [(0.9, 1.0, 0.005, 10.0), (0.8, 1.0, 1e-3, 6.0), (0.7, 0.37, 1e-3, 3.0), (0.95, 1.0, 0.01, 20.0)],
)
def test_the_inferred_rest_falls_in_its_first_order_window(e, x0, h, t_end):
    """Issue 48 item 7: at e = 0.9, h = 0.005 the rest is 36 steps before t_Z = 8.579 (the docs' "within 20 h" was
    one measurement at e = 0.8). t_rest - t_Z = sum(D) - G (docs/families.md): each resolved impact shifts the
    accumulation time the trajectory predicts by D in (-h / e, h] and the rest label cuts off a tail G in
    (-2 h, (2 + e) h / (1 - e) - h / 2], both to first order in g h / (e |v|): rest_window. Checked on runs
    that resolve many impacts (15 to 62 here); the window is first order, not a proof for flights of a few steps
    (docs/families.md names the grid point of its measured table where it is exceeded)."""
    problem = get_problem("bouncing-ball", e=e, x0=x0)
    run = simulate(problem, "moreau-jean", t_end, options={"h": h}, check_points=0)
    assert run.ok, run.message
    kinds = list(run.events["kind"])
    assert kinds[-1] == "rest" and kinds.count("impact") >= 10
    _, h_used = uniform_steps(0.0, t_end, h)
    lo, hi = rest_window(e, h_used, kinds.count("impact"))
    assert lo <= run.events["t"].iloc[-1] - problem.accumulation_time() <= hi


def test_the_step_matrix_is_inverted_without_blas():
    """``spd_inverse`` (Gauss-Jordan in a fixed order, not LAPACK through BLAS) inverts exactly where the
    inverse is exact in binary, and to rounding elsewhere; a matrix that is not positive definite is refused."""
    a = np.array([[2.0, 1.0], [1.0, 1.0]])  # inverse [[1, -1], [-1, 2]], every step exact
    np.testing.assert_array_equal(spd_inverse(a), [[1.0, -1.0], [-1.0, 2.0]])
    rng = np.random.default_rng(5)
    for n in (1, 3, 6):
        b = rng.normal(size=(n, n))
        w = b @ b.T + n * np.eye(n)  # well conditioned: the inverse is accurate to a few ulps
        np.testing.assert_allclose(spd_inverse(w) @ w, np.eye(n), atol=1e-14)
    with pytest.raises(ValueError, match="not positive definite"):
        spd_inverse(np.array([[0.0, 1.0], [1.0, 0.0]]))
