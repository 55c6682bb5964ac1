"""``cyrk-*`` (CyRK's C++ step loop with events) against ``exact`` and the closed forms.

Skipped with the reason where CyRK (the extra ``[cyrk]``) is not installed. The bounds: an event
error of an adaptive method at ``rtol`` grows along a run of a few hundred events to about 10-100
``rtol`` (measured on 2-DOF case 2 over [0, 300] at ``rtol = 1e-9``: 1.2e-8 for RK45, 6.1e-9 for
DOP853, 3.9e-9 for Tsit5, 4.6e-10 for Vern7); each bound is 100 ``rtol``, which the measured errors
meet with a factor 8 or more to spare.
"""

from __future__ import annotations

import numpy as np
import pytest

import nsbench
from nsbench.integrators.cyrk_ import CyRKDOP853
from nsbench.status import Status
from tests.conftest import exact_events, max_time_error, same_sequence

REASON = CyRKDOP853.unavailable()
needs_cyrk = pytest.mark.skipif(REASON is not None, reason=f"CyRK unavailable: {REASON}")
CYRK = ["cyrk-rk45", "cyrk-dop853", "cyrk-tsit5", "cyrk-vern7"]


@needs_cyrk
@pytest.mark.parametrize("name", CYRK)
def test_every_method_has_exacts_sequence_on_the_forced_two_dof(name):
    p = nsbench.get_problem("two-dof", case=2)
    res = nsbench.simulate(p, name, 300.0, options={"rtol": 1e-9, "atol": 1e-11})
    ref = exact_events("two-dof", 2)
    assert res.ok, res.message
    assert same_sequence(res.events, ref)
    assert max_time_error(res.events, ref) <= 1e-7
    assert res.counters.nfev > 0 and res.counters.nsteps > 0


@needs_cyrk
@pytest.mark.parametrize(
    ("problem", "params", "t_end"), [("two-dof", {"case": 2}, 300.0), ("block-on-ground", {}, 60.0)]
)
def test_rk45_takes_scipys_steps(problem, params, t_end):
    # the same tableau and error control as scipy's RK45: the same evaluations on every arc where scipy's
    # own step check integrates no step again (check_reruns = 0; on the relay it re-runs 12 flagged steps
    # with smaller ones, 630 more evaluations, which CyRK's path leaves to the engine's check points), and
    # the event times agree to the root finders' tolerance (Brent's to 4 eps in both)
    p = nsbench.get_problem(problem, **params)
    opts = {"rtol": 1e-9, "atol": 1e-11}
    ours = nsbench.simulate(p, "cyrk-rk45", t_end, options=opts)
    theirs = nsbench.simulate(p, "scipy-rk45", t_end, options=opts)
    assert theirs.counters.extra["check_reruns"] == 0
    assert ours.counters.nfev == theirs.counters.nfev
    assert same_sequence(ours.events, theirs.events)
    assert max_time_error(ours.events, theirs.events) <= 1e-12


@needs_cyrk
def test_rk45_has_scipys_events_on_the_relay():
    p = nsbench.get_problem("relay-feedback")
    opts = {"rtol": 1e-9, "atol": 1e-11}
    ours = nsbench.simulate(p, "cyrk-rk45", 60.0, options=opts)
    theirs = nsbench.simulate(p, "scipy-rk45", 60.0, options=opts)
    assert same_sequence(ours.events, theirs.events)
    assert max_time_error(ours.events, theirs.events) <= 1e-12


@needs_cyrk
@pytest.mark.parametrize("name", CYRK)
def test_the_balls_impacts_match_the_closed_form(name):
    # a flight is a quadratic in time, which every method of order >= 2 follows to rounding: the impacts'
    # errors are the root finder's (4 eps) carried through the sequence, 1e-14 to 6e-13 measured; bound 1e-11.
    # How many impacts precede the rest is the core's Zeno rule's (decided by the tail's accuracy): at least
    # the four its first estimate needs
    p = nsbench.get_problem("bouncing-ball")
    res = nsbench.simulate(p, name, 6.0, options={"rtol": 1e-10, "atol": 1e-12})
    assert res.ok, res.message
    impacts = res.events[res.events["kind"] == "impact"]["t"].to_numpy()
    assert list(res.events["kind"]) == ["impact"] * len(impacts) + ["rest"] and len(impacts) >= 4
    assert np.max(np.abs(impacts - p.impact_times(len(impacts)))) <= 1e-11
    assert res.events["kind"].iloc[-1] == "rest"
    assert abs(res.events["t"].iloc[-1] - p.accumulation_time()) <= 1e-9  # extrapolated from the last flights


@needs_cyrk
def test_relay_sliding_events_against_exact():
    p = nsbench.get_problem("relay-feedback")
    ref = nsbench.simulate(p, "exact", 60.0)
    res = nsbench.simulate(p, "cyrk-vern7", 60.0, options={"rtol": 1e-12, "atol": 1e-14})
    assert same_sequence(res.events, ref.events)
    assert max_time_error(res.events, ref.events) <= 1e-10  # measured 1.7e-12


@needs_cyrk
def test_budget_is_a_status():
    p = nsbench.get_problem("two-dof", case=2)
    res = nsbench.simulate(p, "cyrk-dop853", 300.0, max_steps=5)
    assert not res.ok and res.status is Status.BUDGET_EXHAUSTED and res.message
    assert res.counters.nsteps <= 5 and res.t_final < 300.0
