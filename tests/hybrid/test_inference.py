"""The event inference of whole-system methods (nsbench.hybrid.inference) on constructed trajectories.

Every expected time is derived by hand from the straight lines the rule interpolates.
"""

from __future__ import annotations

import numpy as np
import pytest

from nsbench.hybrid.inference import band_modes, infer_events, section_hits
from nsbench.problems import get_problem
from nsbench.sections import StateSection


@pytest.fixture(scope="module")
def one_dof():
    return get_problem("one-dof")  # v0 = 1/12, fr = 1, c = 0.05, k = 1


def test_a_reversal_is_placed_at_the_zero_of_the_relative_velocity(one_dof):
    v0 = one_dof.v0
    t = np.array([0.0, 0.1, 0.2])
    # u = v - v0 goes 0.3 -> 0.1 -> -0.3: the line through the last two is zero at 0.1 + 0.1 * 0.1 / 0.4
    y = np.array([[0.0, v0 + 0.3], [0.0, v0 + 0.1], [0.0, v0 - 0.3]])
    ev = infer_events(one_dof, t, y)
    assert len(ev) == 1 and one_dof.event_kinds[ev.kind[0]] == "reverse" and ev.block[0] == 0
    assert ev.t[0] == pytest.approx(0.125, abs=1e-15)
    assert ev.y[0, 1] == v0  # MODEL.md: v = v0 at a reverse
    assert ev.mode[0].tolist() == [-1] and ev.start_mode.tolist() == [1]
    assert ev.step.tolist() == [1] and ev.located is None


def test_a_pinned_stick_is_extrapolated_from_the_last_two_slipping_steps(one_dof):
    v0 = one_dof.v0
    t = np.array([0.0, 0.1, 0.2, 0.3])
    # u = -0.3, -0.1 on the last slipping steps: the line reaches 0 at t = 0.25 (the method pins u = 0 at 0.3;
    # at x = 0 the load R = c v0 = 0.004 is well inside the static limit fr = 1: it sticks)
    y = np.array([[0.0, v0 - 0.6], [0.0, v0 - 0.3], [0.0, v0 - 0.1], [0.0, v0]])
    ev = infer_events(one_dof, t, y)
    assert one_dof.event_kinds[ev.kind[0]] == "stick"
    assert ev.t[0] == pytest.approx(0.25, abs=1e-14)
    # a line that would reach 0 only after the step is kept within it (its end)
    y[2, 1] = v0 - 0.25
    assert infer_events(one_dof, t, y).t[0] == pytest.approx(0.3, abs=1e-15)
    # a stuck step that Siconos's relay leaves at u = 1e-15 is at the belt speed all the same (rule 1's z)
    y[3, 1] = v0 + 1e-15
    assert infer_events(one_dof, t, y).t[0] == pytest.approx(0.3, abs=1e-15)


def test_leaving_stick_interpolates_the_static_limit(one_dof):
    v0 = one_dof.v0
    c = 0.05
    # stuck: R = c v0 + x reaches fr = 1 at x = 1 - c v0; the steps hold x = 0.9 and 1.1 (the guard with v = v0)
    x_star = 1.0 - c * v0
    t = np.array([0.0, 1.0])
    y = np.array([[x_star - 0.25, v0], [x_star + 0.75, v0 - 0.01]])
    ev = infer_events(one_dof, t, y)
    assert one_dof.event_kinds[ev.kind[0]] == "slip"
    assert ev.t[0] == pytest.approx(0.25, abs=1e-14)
    assert ev.mode[0].tolist() == [-1]
    # still at the belt speed at the second step but past the limit: a break-away all the same, in the
    # direction of the load (R > fr drives u < 0), at the same guard zero
    y[1, 1] = v0
    ev = infer_events(one_dof, t, y)
    assert [one_dof.event_kinds[k] for k in ev.kind] == ["slip"] and ev.mode[0].tolist() == [-1]
    assert ev.t[0] == pytest.approx(0.25, abs=1e-14)


def test_the_band_rule_reads_modes_off_the_velocities(one_dof):
    v0 = one_dof.v0
    band = 0.01
    u = np.array([-0.05, -0.03, 0.0, 0.005, 0.03])
    y = np.column_stack([np.zeros(5), v0 + u])
    assert band_modes(one_dof, y, band)[:, 0].tolist() == [-1, -1, 0, 0, 1]
    t = np.arange(5.0)
    ev = infer_events(one_dof, t, y, None, band)
    kinds = [one_dof.event_kinds[k] for k in ev.kind]
    assert kinds == ["stick", "slip"]
    # |u| - band: 0.02 -> -0.01 crosses at 1 + 2/3; band - |u|: 0.005 -> -0.02 crosses at 3 + 0.2
    assert ev.t[0] == pytest.approx(1 + 2 / 3, abs=1e-14)
    assert ev.t[1] == pytest.approx(3.2, abs=1e-14)


def test_the_methods_own_labels_are_not_read():
    """Two methods' labels of one state may differ (a relay at its bound, an enumeration's stuck step): the
    phases come from the trajectory alone, so contradictory labels change nothing."""
    problem = get_problem("block-on-ground")
    t = np.array([0.0, 0.1, 0.2, 0.3])
    y = np.array([[-0.5, -0.3], [-0.5, -0.1], [-0.5, 0.0], [-0.5, 0.0]])
    a = infer_events(problem, t, y, np.array([[-1], [-1], [0], [0]]))
    b = infer_events(problem, t, y, np.array([[-1], [-1], [-1], [1]]))
    assert np.array_equal(a.t, b.t) and np.array_equal(a.kind, b.kind)
    assert [problem.event_kinds[k] for k in a.kind] == ["stick"]


def test_simultaneous_changes_come_in_time_order_with_the_running_mode():
    problem = get_problem("two-dof", case=1)
    v0 = problem.v0
    t = np.array([0.0, 1.0])
    # block 1 reverses at 0.75, block 2 at 0.25
    y = np.array([[0.0, v0 + 0.3, 0.0, v0 + 0.1], [0.0, v0 - 0.1, 0.0, v0 - 0.3]])
    ev = infer_events(problem, t, y)
    assert ev.t.tolist() == pytest.approx([0.25, 0.75])
    assert ev.block.tolist() == [1, 0]
    assert ev.mode.tolist() == [[1, -1], [-1, -1]]


def test_section_hits_are_interpolated_linearly():
    sec = StateSection("x1", (1.0, 0.0), level=0.5, direction=1)
    t = np.array([0.0, 1.0, 2.0])
    y = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 0.0]])
    hits = section_hits([sec], t, y)
    assert len(hits) == 1 and hits[0][1] == pytest.approx(0.5)


def test_a_negative_band_is_refused(one_dof):
    with pytest.raises(ValueError, match="band"):
        infer_events(one_dof, np.array([0.0]), np.zeros((1, 2)), None, -1.0)


def test_a_one_step_stick_past_the_static_limit_is_a_reversal():
    problem = get_problem("block-on-ground")  # v0 = 0, k = 1, fr = 1
    t = np.array([0.0, 0.1, 0.2])
    # at x = -3 the spring's pull (R = x = -3) exceeds fr = 1: the stuck step cannot hold
    y = np.array([[-3.0, -0.2], [-3.0, 0.0], [-3.0, 0.2]])
    ev = infer_events(problem, t, y)
    assert [problem.event_kinds[k] for k in ev.kind] == ["reverse"]
    assert ev.t[0] == pytest.approx(0.1)
    # within the static limit the stuck step is real: a stick and a slip
    y[:, 0] = -0.5
    ev = infer_events(problem, t, y)
    assert [problem.event_kinds[k] for k in ev.kind] == ["stick", "slip"]


def test_a_pass_through_the_band_past_the_static_limit_is_one_reversal():
    """Issue 48 item 6: a regularised block passes through the stick band in several steps; past its static
    limit (|R| = 3 > fr = 1) that is one reverse, at the zero of u, not a stick and a slip."""
    problem = get_problem("block-on-ground")
    band = 0.05
    u = np.array([-0.2, -0.04, -0.01, 0.03, 0.2])  # three steps inside the band, u's zero at 2 + 0.01 / 0.04
    t = np.arange(5.0)
    y = np.column_stack([np.full(5, -3.0), u])
    ev = infer_events(problem, t, y, None, band)
    assert [problem.event_kinds[k] for k in ev.kind] == ["reverse"]
    assert ev.t[0] == pytest.approx(2.25, abs=1e-14) and ev.mode[0].tolist() == [1]
    # within the limit (|R| = 0.5) the block stays in the band: stuck there, then it slips
    y[:, 0] = -0.5
    ev = infer_events(problem, t, y, None, band)
    assert [problem.event_kinds[k] for k in ev.kind] == ["stick", "slip"]


def test_the_same_trajectory_gives_the_same_events_to_rounding():
    """Issue 48 item 7: a trajectory moved by 1e-13 (the agreement of moreau-jean and Siconos), stuck steps
    left at |u| ~ 1e-15 instead of 0, gives every event time within 1e-9."""
    from nsbench import get_integrator
    from nsbench.integrators.whole import SystemRequest

    for params, t_end in (({}, 30.0), ({"F": 1.5, "w": 0.5}, 60.0)):
        problem = get_problem("block-on-ground", **params)
        method = get_integrator("moreau-jean", h=0.01)
        method.setup(problem)
        res = method.integrate(SystemRequest(problem=problem, t0=0.0, y0=problem.initial_state(), t_end=t_end))
        a = infer_events(problem, res.t, res.y)
        rng = np.random.default_rng(7)
        y = res.y + rng.uniform(-1e-13, 1e-13, res.y.shape)
        b = infer_events(problem, res.t, y)
        assert len(a) >= 8 and np.array_equal(a.kind, b.kind) and np.array_equal(a.block, b.block)
        assert np.abs(a.t - b.t).max() <= 1e-9


def test_located_switches_are_paired_with_their_events_and_never_move_them(one_dof):
    v0 = one_dof.v0
    t = np.array([0.0, 0.1, 0.2, 0.3, 0.4])
    y = np.array([[0.0, v0 + 0.3], [0.0, v0 + 0.1], [0.0, v0 - 0.3], [0.0, v0 - 0.5], [0.0, v0 - 0.7]])
    plain = infer_events(one_dof, t, y)
    # the method's own switch at 0.117 (inside the steps around the change), one far away (unpaired), one of
    # another element (unpaired)
    ev = infer_events(one_dof, t, y, switch_times=np.array([0.117, 0.39, 0.12]), switch_elements=np.array([0, 0, 1]))
    assert np.array_equal(ev.t, plain.t)
    assert ev.located.tolist() == [0.117]
    none = infer_events(one_dof, t, y, switch_times=np.array([0.39]), switch_elements=None)
    assert np.isnan(none.located[0])


def _method(result_of):
    """A whole-system 'method' for the driver's checks: it returns what it is told to (never a measurement)."""
    from nsbench.integrators.base import Capabilities
    from nsbench.integrators.whole import WholeSystem

    class Stub(WholeSystem):
        name = "test-whole"
        capabilities = Capabilities(
            event_location="inferred-from-status", order=1, adaptive=False, family="time-stepping"
        )

        def integrate(self, request):
            return result_of(request)

    return Stub()


def test_a_result_that_breaks_the_protocol_is_a_failure_status(one_dof):
    from nsbench import simulate
    from nsbench.integrators.whole import SystemResult

    bad_shape = _method(lambda r: SystemResult(t=np.array([r.t0, r.t_end]), y=np.zeros((2, 3))))
    res = simulate(one_dof, bad_shape, 1.0)
    assert res.status.value == "integrator failure" and "(n_steps, n_states)" in res.message

    short = _method(lambda r: SystemResult(t=np.array([r.t0, 0.5]), y=np.zeros((2, 2))))
    res = simulate(one_dof, short, 1.0)
    assert res.status.value == "integrator failure" and "< t_end" in res.message

    def boom(request):
        raise RuntimeError("no luck")

    res = simulate(one_dof, _method(boom), 1.0)
    assert res.status.value == "integrator failure" and "RuntimeError: no luck" in res.message


def test_a_non_finite_step_ends_the_run_where_the_steps_were_finite(one_dof):
    from nsbench import simulate
    from nsbench.integrators.whole import SystemResult

    v0 = one_dof.v0

    def blows_up(request):
        t = np.linspace(request.t0, request.t_end, 5)
        y = np.column_stack([np.zeros(5), np.full(5, v0 - 0.1)])
        y[3:] = np.nan
        return SystemResult(t=t, y=y, modes=np.full((5, 1), -1))

    res = simulate(one_dof, _method(blows_up), 1.0)
    assert res.status.value == "integrator failure" and "non-finite" in res.message
    assert res.t_final == 0.5


def test_a_whole_system_method_has_no_arcs(one_dof):
    from nsbench.errors import ConfigError
    from nsbench.integrators.base import ArcRequest
    from nsbench.integrators.whole import SystemResult

    method = _method(lambda r: SystemResult(t=np.array([r.t0]), y=np.zeros((1, 2))))
    mode = one_dof.initial_mode(0.0, one_dof.initial_state())
    with pytest.raises(ConfigError, match="whole-system"):
        method.advance(ArcRequest(one_dof, mode, 0.0, one_dof.initial_state(), 1.0, one_dof.guards(mode)))


def test_a_family_is_one_of_the_four():
    from nsbench.errors import ConfigError
    from nsbench.integrators.base import FAMILIES, Capabilities

    assert FAMILIES == ("event-driven", "time-stepping", "switch-model", "smoothing")
    with pytest.raises(ConfigError, match="family 'implicit'"):
        Capabilities(event_location="x", order=1, adaptive=False, family="implicit")


def test_the_hybrid_core_refuses_a_whole_system_method_early(one_dof):
    from nsbench.errors import ConfigError
    from nsbench.hybrid.run import run_hybrid
    from nsbench.integrators import get_integrator

    with pytest.raises(ConfigError, match=r"whole-system method \(family time-stepping\)"):
        run_hybrid(one_dof, get_integrator("moreau-jean"), 1.0)
