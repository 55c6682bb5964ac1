"""``bouncing-ball``: impacts and the Zeno accumulation against the closed form."""

from __future__ import annotations

import math

import numpy as np
import pytest

import nsbench
from nsbench.errors import ConfigError


def test_exact_meets_every_impact_time_and_the_accumulation_time():
    # Closed form (the module docstring): t1 = sqrt(2 x0 / g), flights 2 e^k v1 / g, t_Z = t1 + 2 e v1 / (g (1 - e)).
    # exact's flight is a polynomial evaluated through its matrix exponential: each impact time is
    # good to a few ulps of t ~ 4, far inside 1e-12. The flights are exactly geometric, so the Zeno
    # rule's estimate is at the rounding of the times from the first four impacts on: it extrapolates there.
    p = nsbench.get_problem("bouncing-ball")
    res = nsbench.simulate(p, "exact", 10.0)
    assert res.ok, res.message
    ev = res.events
    impacts = ev[ev["kind"] == "impact"]
    assert list(ev["kind"]) == ["impact"] * len(impacts) + ["rest"] and len(impacts) >= 4
    np.testing.assert_allclose(impacts["t"], p.impact_times(len(impacts)), rtol=0, atol=1e-12)
    t1, v1 = math.sqrt(2 * 1.0 / 9.81), math.sqrt(2 * 9.81 * 1.0)
    assert p.accumulation_time() == pytest.approx(t1 + 2 * 0.8 * v1 / (9.81 * 0.2), rel=1e-15)
    assert abs(ev["t"].iloc[-1] - p.accumulation_time()) <= 1e-12
    # after the rest event the ball lies still, on the ground, to the end of the run
    assert res.mode_final == (1,) and res.y_final.tolist() == [0.0, 0.0]
    assert list(impacts["v"]) == pytest.approx(math.sqrt(2 * 9.81) * 0.8 ** np.arange(1, len(impacts) + 1), rel=1e-13)


def test_a_thrown_ball_and_another_restitution():
    p = nsbench.get_problem("bouncing-ball", x0=0.5, v0=2.0, e=0.5, g=1.6)
    res = nsbench.simulate(p, "exact", 20.0)
    impacts = res.events[res.events["kind"] == "impact"]
    assert len(impacts) >= 4  # four times give the first estimate of the tail
    np.testing.assert_allclose(impacts["t"], p.impact_times(len(impacts)), rtol=0, atol=1e-12)
    assert abs(res.events["t"].iloc[-1] - p.accumulation_time()) <= 1e-12


@pytest.mark.parametrize("params", [{}, {"x0": 0.5, "v0": 2.0, "e": 0.5, "g": 1.6}, {"e": 0.9, "x0": 3.0}])
def test_the_rest_time_is_within_its_logged_estimate_of_the_closed_form(params):
    # the Zeno rule's error estimate (the event log's accumulation_error) against t_Z in closed form,
    # evaluated in 60 digits from the same doubles (tests/impact_reference.py); measured on the
    # defaults: 9.3e-15 off, estimate 7.2e-14; e = 0.9: 1.4e-14, 3.7e-13. The estimate's floor is the rounding of the times,
    # 16 ulps of t_Z through 1 / (1 - e)^3: 5e-11 at e = 0.9, t_Z = 15, below the 1e-10 asked here.
    from tests.impact_reference import bouncing_ball_events

    p = nsbench.get_problem("bouncing-ball", **params)
    ev = nsbench.simulate(p, "exact", 60.0).events
    rest = ev.iloc[-1]
    assert rest["kind"] == "rest" and ev["accumulation_error"].iloc[:-1].isna().all()
    _, t_z = bouncing_ball_events(p, 1)
    error = abs(float(t_z - rest["t"]))
    assert error <= rest["accumulation_error"] <= 1e-10


@pytest.mark.parametrize(
    "name, bound",
    [("ofapi", 1e-12), ("scipy-radau", 1e-10), ("henon-rk4", 1e-5), ("heyoka", 1e-12), ("heyoka-q", 1e-12)],
)
def test_other_integrators_find_the_same_impacts(name, bound):
    # the Zeno rule stops where each integrator's times stop improving its estimate: the tails are
    # compared as far as both resolved them (match_accumulation_tails), the rest events with each other
    from nsbench.hybrid.records import match_accumulation_tails

    p = nsbench.get_problem("bouncing-ball")
    ref = nsbench.simulate(p, "exact", 10.0).events
    res = nsbench.simulate(p, name, 10.0)
    assert res.ok, res.message
    ref, ev = match_accumulation_tails(ref, res.events)
    assert list(ev["kind"]) == list(ref["kind"]) and ev["kind"].iloc[-1] == "rest"
    assert np.abs(ev["t"].to_numpy() - ref["t"].to_numpy()).max() <= bound


def test_without_the_accumulation_rule_the_impacts_storm():
    p = nsbench.get_problem("bouncing-ball")
    res = nsbench.simulate(p, "exact", 10.0, accumulation=0)
    assert res.status is nsbench.Status.EVENT_STORM or not res.ok


@pytest.mark.parametrize(
    "params, message",
    [
        ({"e": 1.0}, "must be < 1"),
        ({"e": -0.1}, "restitution e must be >= 0"),
        ({"g": 0}, "gravity g must be > 0"),
        ({"x0": -1}, "start height x0 must be >= 0"),
        ({"mass": 1}, "unknown parameter 'mass'"),
        ({"v0": float("nan")}, "finite"),
    ],
)
def test_bad_parameters_are_refused(params, message):
    with pytest.raises(ConfigError, match=message):
        nsbench.get_problem("bouncing-ball", **params)


def test_integrators_without_a_form_for_it_refuse_at_setup():
    from nsbench.errors import UnsupportedProblemError

    p = nsbench.get_problem("bouncing-ball")
    for name in ("cvode-bdf", "ida"):
        with pytest.raises(
            UnsupportedProblemError, match=r"blocks on a belt \(the friction oscillators' formulation\) only"
        ):
            nsbench.get_integrator(name).setup(p)
