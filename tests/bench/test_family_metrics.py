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


def test_stick_creep_is_the_largest_speed_and_drift_off_the_belt():
    v_belt = 0.5
    ref = _log([(1.0, "stick", 1), (3.0, "slip", 1)])
    times = np.array([0.5, 1.5, 2.0, 2.5, 3.5])
    # inside (1, 3): t = 1.5, 2, 2.5 with v - v_belt = 0.01, -0.03, 0.02 and x drifting 0, +0.001, -0.002
    v = v_belt + np.array([9.0, 0.01, -0.03, 0.02, 9.0])
    x = np.array([0.0, 1.0, 1.0 + 0.5 * v_belt + 0.001, 1.0 + 1.0 * v_belt - 0.002, 0.0])
    creep = stick_creep(ref, times, np.vstack([x, v]), v_belt, 4.0)
    assert creep.creep == pytest.approx(0.03)
    assert creep.drift == pytest.approx(0.002)
    assert math.isnan(stick_creep(ref, np.array([0.5, 3.5]), np.zeros((2, 2)), v_belt, 4.0).creep)


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
    times = np.array([2.0])
    out = case_metrics(
        ref,
        run,
        np.zeros((2, 1)),
        np.array([[0.0], [0.6]]),
        np.zeros(2),
        np.zeros(2),
        times=times,
        v_belt=0.5,
        t_end=4.0,
    )
    assert out["stick_creep"] == pytest.approx(0.1) and out["stick_drift"] == 0.0
    assert out["breakaway_err_max"] == pytest.approx(0.1)
    assert math.isnan(case_metrics(ref, run, None, None, None, None)["stick_creep"])


def test_impact_metrics_are_the_depth_below_ground_and_the_energy_left():
    from nsbench.bench.metrics import impact_metrics
    from nsbench.problems import get_problem

    ball = get_problem("bouncing-ball")  # E = v^2 / 2 + g x, g = 9.81
    dense = np.array([[0.5, -1e-4, 0.0], [1.0, -2.0, 0.0]])
    pen, err = impact_metrics(ball.energy, dense, np.array([0.0, 0.0]), np.array([1e-3, 0.1]))
    assert pen == pytest.approx(1e-4)
    assert err == pytest.approx(0.005 + 9.81e-3)
    assert math.isnan(impact_metrics(ball.energy, None, None, None)[0])
