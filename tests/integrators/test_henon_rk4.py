"""``henon-rk4``: order-4 event times (METHODS.md section 7.3)."""

from __future__ import annotations

import numpy as np
import pytest

import nsbench
from tests.conftest import exact_events, max_time_error, same_sequence


@pytest.mark.parametrize("problem, case, t_end", [("one-dof", 1, 40.0), ("two-dof", 2, 40.0)])
def test_event_times_converge_at_order_four(problem, case, t_end):
    p = nsbench.get_problem(problem, case=case)
    ref = exact_events(problem, case, t_end)
    hs = [0.08, 0.04, 0.02, 0.01]
    errors = []
    for h in hs:
        res = nsbench.simulate(p, "henon-rk4", t_end, options={"h": h})
        assert same_sequence(res.events, ref)
        errors.append(max_time_error(res.events, ref))
    orders = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    assert np.all((orders > 3.5) & (orders < 4.5)), (errors, orders)


def test_henon_beats_stepping_to_the_grid():
    # Same h, same field: Henon's step is what makes the event accurate.
    p = nsbench.get_problem("one-dof")
    res = nsbench.simulate(p, "henon-rk4", 40.0, options={"h": 0.05})
    err = max_time_error(res.events, exact_events("one-dof", 1, 40.0))
    assert err < 1e-5  # a switch at the step end would be off by up to h = 0.05


def test_cases_1_and_2_over_300(case1, case2):
    for case, p in ((1, case1), (2, case2)):
        res = nsbench.simulate(p, "henon-rk4", 300.0, options={"h": 0.02})
        ref = exact_events("two-dof", case)
        assert same_sequence(res.events, ref)
        assert max_time_error(res.events, ref) < 1e-5


def test_counts_four_evaluations_per_step(case1):
    res = nsbench.simulate(case1, "henon-rk4", 10.0, options={"h": 0.1})
    c = res.counters
    assert c.nsteps >= 100
    # 4 per step, 4 per Henon step, one field at each arc start and event
    assert 4 * c.nsteps <= c.nfev <= 4 * c.nsteps + 8 * c.n_events + 4 * c.extra["henon_steps"] + 8


def test_section_hits_beyond_the_buffer_are_all_kept():
    # A forced block that slides forever (belt faster than the oscillation):
    # one arc with more section crossings than the core's first hit buffer, so
    # the buffer grows and the arc runs again from its start.
    from nsbench.hybrid.records import Records
    from nsbench.sections import level_crossing

    _HIT_BUFFER = Records(2, 1, np.empty(0)).ht.shape[0]

    p = nsbench.get_problem("one-dof", case=2, v0=3.0, F=0.4, Omega=1.3)
    sec = [level_crossing(p, "v1", 0.0, 0)]
    res = nsbench.simulate(p, "henon-rk4", 1000.0, options={"h": 0.02}, sections=sec)
    ref = nsbench.simulate(p, "exact", 1000.0, sections=sec)
    assert len(ref.events) == 0 and len(res.events) == 0
    assert len(ref.sections) > _HIT_BUFFER
    assert len(res.sections) == len(ref.sections)
    np.testing.assert_allclose(res.sections["t"], ref.sections["t"], atol=1e-6)


@pytest.mark.parametrize("h", [float("inf"), "inf", float("nan")])
def test_a_step_that_is_not_finite_is_refused(h):
    with pytest.raises(nsbench.ConfigError, match="h = .* must be a finite"):
        nsbench.get_integrator("henon-rk4", h=h)


@pytest.mark.parametrize(
    "h, why",
    [
        (1e300, "beyond RK4's stability limit"),
        (2.0, "beyond RK4's stability limit"),
        (1e-18, "too small to move the state"),
    ],
)
def test_a_step_rk4_cannot_take_on_the_problem_is_refused(case1, h, why):
    # case 1's fastest rate is the golden ratio 1.618 (kappa = mu = 1): RK4 is stable up to
    # h = 2 sqrt(2) / 1.618 = 1.748; a step of 1e-18 changes nothing (1.6e-18 < eps = 2.2e-16).
    # Before, both took one step over the whole span, found no event and said success.
    with pytest.raises(nsbench.ConfigError, match=why):
        nsbench.simulate(case1, "henon-rk4", 300.0, options={"h": h})
    # just inside the limit it runs; unchecked it says success with 1 event where exact has 8 over [0, 30],
    # so simulate's default check points end it 'event missed' (its steps jump over the sticks)
    assert nsbench.simulate(case1, "henon-rk4", 30.0, options={"h": 1.7}, check_points=0).ok
    assert nsbench.simulate(case1, "henon-rk4", 30.0, options={"h": 1.7}).status.value == "event missed"


def test_a_step_count_beyond_int64_ends_with_the_budget_not_in_one_step():
    # h just above the resolution limit (h * 1 > eps: one-dof's rate is 1) over a span of 3000:
    # 3000 / 2.3e-16 = 1.3e19 steps, past int64's 9.2e18; the count used to wrap around and the
    # arc ended in one step of 3000 with status success
    p = nsbench.get_problem("one-dof")
    res = nsbench.simulate(p, "henon-rk4", 3000.0, options={"h": 2.3e-16}, max_steps=1000)
    assert res.status == nsbench.Status.BUDGET_EXHAUSTED and res.t_final < 1e-9
