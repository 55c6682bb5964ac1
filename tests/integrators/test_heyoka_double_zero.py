"""heyoka at a double zero: a slip that starts at ``fs = fr`` (the block's acceleration is zero there).

The velocity guard of such a slip starts with value and slope both zero. heyoka
alone (the guard of :meth:`HeyokaIntegrator._first_step` off, ``fresh_steps = 0``)
reports that zero itself as a root: the transitions then cycle stick/slip at one
instant (an event storm) and the run departs from ``exact``. With the guard the
heyoka integrators give ``exact``'s event sequence on Coulomb cases with
``fs = fr`` (piecewise linear, so ``exact`` is the reference), within the
arithmetic's bound (tests/conftest.precision_bound).
"""

from __future__ import annotations

import numpy as np
import pytest

import nsbench
from nsbench.integrators.heyoka_ import HeyokaIntegrator
from tests.conftest import max_time_error, precision_bound, same_sequence

T_END = 300.0
#: fs = fr: every stick-to-slip switch starts its slip at a double zero of the velocity guard
CASES = {
    "two-dof case 2, r_f = 1": ("two-dof", {"case": 2, "r_f": 1.0}),
    "one-dof case 2, r_f = 1": ("one-dof", {"case": 2, "r_f": 1.0}),
}
HEYOKAS = {"heyoka": np.finfo(float).eps, "heyoka-ld": np.finfo(np.longdouble).eps, "heyoka-q": 1.93e-34}


@pytest.fixture(scope="module", params=list(CASES))
def case(request):
    name, params = CASES[request.param]
    problem = nsbench.get_problem(name, **params)
    exact = nsbench.simulate(problem, "exact", T_END)
    from nsbench.bench.reference import conditioning

    kappa, note = conditioning(problem, nsbench.get_integrator("reference").config(), 0.0, T_END, exact.events)
    assert np.isfinite(kappa), note
    assert exact.ok and len(exact.events) > 90 and (exact.events["kind"] == "slip").sum() > 20
    return problem, exact, kappa


@pytest.mark.parametrize("name", list(HEYOKAS))
def test_heyoka_gives_exacts_sequence_at_double_zeros(case, name):
    problem, exact, kappa = case
    res = nsbench.simulate(problem, name, T_END)
    assert res.ok, res.message
    assert same_sequence(res.events, exact.events)
    bound = precision_bound(exact.events["t"], kappa, max(HEYOKAS[name], np.finfo(float).eps), res.counters.nsteps)
    assert max_time_error(res.events, exact.events) <= bound


@pytest.mark.parametrize("name", list(HEYOKAS))
def test_without_the_guard_heyoka_departs_from_exact(case, name, monkeypatch):
    """The pitfall itself: this test fails if heyoka ever handles the double zero alone (then the guard
    could go)."""
    problem, exact, _ = case
    monkeypatch.setattr(HeyokaIntegrator, "fresh_steps", 0)
    res = nsbench.simulate(problem, name, T_END)
    assert not (res.ok and same_sequence(res.events, exact.events))


@pytest.mark.parametrize("name", list(HEYOKAS))
def test_a_run_that_ends_just_after_a_double_zero_logs_no_event_there(name):
    """The first step of the slip is cut to 1e-9 by the run's end: the guard is still exactly on its surface
    (the velocity has moved by about 1e-19), which is no event; the guard used to fire it at once."""
    problem = nsbench.get_problem("one-dof", case="leine")
    first = nsbench.simulate(problem, "reference", 6.0).events
    t_slip = float(first["t"].iloc[1])
    assert first["kind"].tolist()[:2] == ["stick", "slip"]
    res = nsbench.simulate(problem, name, t_slip + 1e-9)
    assert res.ok, res.message
    assert res.events["kind"].tolist() == ["stick", "slip"]
