"""The metrics of the whole-system families: stick creep, break-away error, observed order (hand-derived values)."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from nsbench.bench.metrics import breakaway_error, case_metrics, observed_order, stick_creep, stick_intervals


def _log(rows):
    return pd.DataFrame(rows, columns=["t", "kind", "block"])


def test_stick_intervals_run_from_a_stick_to_the_blocks_next_slip():
    ref = _log([(1.0, "stick", 1), (2.0, "stick", 2), (3.0, "slip", 1), (4.0, "reverse", 2), (5.0, "stick", 1)])
    assert stick_intervals(ref, 10.0) == [(1, 1.0, 3.0), (2, 2.0, 10.0), (1, 5.0, 10.0)]


def test_stick_creep_is_the_drift_velocity_per_unit_of_stick_time():
    v_belt = 0.5
    ref = _log([(1.0, "stick", 1), (3.0, "slip", 1)])
    times = np.array([0.5, 1.5, 2.0, 2.5, 3.5])
    # inside (1, 3): t = 1.5, 2, 2.5, x - v_belt t = 0.25, 0.251, 0.248 (v is not read: the positions say how
    # far the block went): moved 0.001 + 0.003 in 1.0 of stick time; largest drift from the first point 0.002
    v = v_belt + np.array([9.0, 0.01, -0.03, 0.02, 9.0])
    x = np.array([0.0, 1.0, 1.0 + 0.5 * v_belt + 0.001, 1.0 + 1.0 * v_belt - 0.002, 0.0])
    creep = stick_creep(ref, times, np.vstack([x, v]), v_belt, 4.0)
    assert creep.creep == pytest.approx(0.004)
    assert creep.drift == pytest.approx(0.002)
    assert math.isnan(stick_creep(ref, np.array([0.5, 3.5]), np.zeros((2, 2)), v_belt, 4.0).creep)
    # out of the cone at t = 2: two windows of one point each, no pair left
    cone = np.array([[True, True, False, True, True]])
    assert math.isnan(stick_creep(ref, times, np.vstack([x, v]), v_belt, 4.0, cone).creep)
    # out of the cone at t = 2.5 only: the pair (1.5, 2) alone, 0.001 in 0.5
    cone = np.array([[True, True, True, False, True]])
    creep = stick_creep(ref, times, np.vstack([x, v]), v_belt, 4.0, cone)
    assert creep.creep == pytest.approx(0.002) and creep.drift == pytest.approx(0.001)
    # an interval whose stick is not in the run's matched prefix is left out
    assert math.isnan(stick_creep(ref, times, np.vstack([x, v]), v_belt, 4.0, None, n_prefix=0).creep)


def test_the_creep_windows_are_cut_to_where_the_run_sticks_too():
    """A run that sticks late (1.6 for 1.0) and slips early (2.6 for 3.0): its slipping before and after is its
    switching-time error, not creep; only (1.6, 2.6) counts."""
    v_belt = 0.5
    ref = _log([(1.0, "stick", 1), (3.0, "slip", 1)])
    run = _log([(1.6, "stick", 1), (2.6, "slip", 1)])
    times = np.array([1.2, 1.5, 1.8, 2.1, 2.4, 2.8])
    # relative to the belt: slipping at 1 per unit time before 1.6 and after 2.6, creeping 0.01 per unit between
    off = np.array([-0.4, -0.1, 0.002, 0.005, 0.008, 0.2])
    x = off + v_belt * times
    dense = np.vstack([x, np.full(times.size, v_belt)])
    plain = stick_creep(ref, times, dense, v_belt, 4.0, None, n_prefix=2)
    assert plain.creep == pytest.approx((0.3 + 0.102 + 0.003 + 0.003 + 0.192) / 1.6)
    cut = stick_creep(ref, times, dense, v_belt, 4.0, None, n_prefix=2, events=run)
    assert cut.creep == pytest.approx(0.006 / 0.6) and cut.drift == pytest.approx(0.006)
    # a closing slip the run does not match (outside its prefix): the run's own next slip ends the window
    cut = stick_creep(ref, times, dense, v_belt, 4.0, None, n_prefix=1, events=run)
    assert cut.creep == pytest.approx(0.006 / 0.6)


def test_in_cone_compares_the_load_at_the_belt_speed_with_the_kinetic_level():
    from nsbench.bench.metrics import in_cone
    from nsbench.problems import get_problem

    problem = get_problem("one-dof")  # R = c v0 + x at the belt speed, c = 0.05, v0 = 1/12, fs = 5/6
    x = np.array([0.0, 0.8, 0.83, -0.9])
    dense = np.vstack([x, np.zeros(4)])
    r = 0.05 / 12 + x
    assert in_cone(problem, np.zeros(4), dense).tolist() == [list(np.abs(r) <= 5 / 6)]
    assert in_cone(problem, np.zeros(4), dense).tolist() == [[True, True, False, False]]
    assert in_cone(get_problem("bouncing-ball"), np.zeros(1), np.zeros((2, 1))) is None


def test_breakaway_error_takes_the_slip_events_of_the_prefix():
    ref = _log([(1.0, "stick", 1), (3.0, "slip", 1), (5.0, "stick", 1), (7.0, "slip", 1)])
    assert breakaway_error(ref, np.array([0.5, -0.2, 0.1, 0.3]), 4) == pytest.approx(0.3)
    assert breakaway_error(ref, np.array([0.5, -0.2, 0.1]), 3) == pytest.approx(0.2)
    assert math.isnan(breakaway_error(ref, np.array([0.5]), 1))


def test_observed_order_is_the_log_log_slope():
    h = np.array([0.1, 0.05, 0.025])
    assert observed_order(h, 3.0 * h**2) == pytest.approx(2.0)
    assert observed_order(h, [1e-3, np.nan, 2.5e-4]) == pytest.approx(1.0)
    assert math.isnan(observed_order([0.1, 0.1], [1.0, 2.0]))


def test_case_metrics_fill_the_new_columns():
    ref = _log([(1.0, "stick", 1), (3.0, "slip", 1)])
    run = _log([(1.1, "stick", 1), (2.9, "slip", 1)])
    times = np.array([2.0, 2.5])
    # the block creeps at 0.1 off the belt: x - v_belt t = 0, -0.05
    out = case_metrics(
        ref,
        run,
        np.zeros((2, 2)),
        np.array([[1.0, 1.2], [0.4, 0.4]]),
        np.zeros(2),
        np.zeros(2),
        times=times,
        v_belt=0.5,
        t_end=4.0,
    )
    assert out["stick_creep"] == pytest.approx(0.1) and out["stick_drift"] == pytest.approx(0.05)
    assert out["breakaway_err_max"] == pytest.approx(0.1)
    assert math.isnan(out["located_err_max"])  # the run locates no switch of its own
    assert math.isnan(case_metrics(ref, run, None, None, None, None)["stick_creep"])
    # a method's own switch times: the largest |t_located - t_ref| of the prefix, beside the inferred errors
    own = run.assign(t_located=[1.02, np.nan])
    located = case_metrics(ref, own, None, None, None, None)
    assert located["located_err_max"] == pytest.approx(0.02)
    assert located["n_located"] == 1  # of the prefix's two events, the method located the first
    assert out["n_located"] is None  # no t_located column: no count, not a count of 0


def test_impact_metrics_are_the_depth_below_ground_and_the_energy_left():
    from nsbench.bench.metrics import impact_metrics
    from nsbench.problems import get_problem

    ball = get_problem("bouncing-ball")  # E = v^2 / 2 + g x, g = 9.81
    dense = np.array([[0.5, -1e-4, 0.0], [1.0, -2.0, 0.0]])
    pen, err = impact_metrics(ball.energy, dense, np.array([0.0, 0.0]), np.array([1e-3, 0.1]))
    assert pen == pytest.approx(1e-4)
    assert err == pytest.approx(0.005 + 9.81e-3)
    assert math.isnan(impact_metrics(ball.energy, None, None, None)[0])
