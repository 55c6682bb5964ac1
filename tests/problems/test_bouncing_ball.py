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
    # good to a few ulps of t ~ 4, far inside 1e-12.
    p = nsbench.get_problem("bouncing-ball")
    res = nsbench.simulate(p, "exact", 10.0)
    assert res.ok, res.message
    ev = res.events
    impacts = ev[ev["kind"] == "impact"]
    assert list(ev["kind"]) == ["impact"] * len(impacts) + ["rest"] and len(impacts) >= 5
    np.testing.assert_allclose(impacts["t"], p.impact_times(len(impacts)), rtol=0, atol=1e-12)
    t1, v1 = math.sqrt(2 * 1.0 / 9.81), math.sqrt(2 * 9.81 * 1.0)
    assert p.accumulation_time() == pytest.approx(t1 + 2 * 0.8 * v1 / (9.81 * 0.2), rel=1e-15)
    assert abs(ev["t"].iloc[-1] - p.accumulation_time()) <= 1e-12
    # after the rest event the ball lies still, on the ground, to the end of the run
    assert res.mode_final == (1,) and res.y_final.tolist() == [0.0, 0.0]
    assert list(impacts["v"]) == pytest.approx(math.sqrt(2 * 9.81) * 0.8 ** np.arange(1, len(impacts) + 1), rel=1e-13)


def test_a_thrown_ball_and_another_restitution():
    p = nsbench.get_problem("bouncing-ball", x0=0.5, v0=2.0, e=0.5, g=1.6)
    res = nsbench.simulate(p, "exact", 20.0, accumulation=4)
    impacts = res.events[res.events["kind"] == "impact"]
    assert len(impacts) == 5  # four intervals shrink geometrically: then the accumulation is extrapolated
    np.testing.assert_allclose(impacts["t"], p.impact_times(5), rtol=0, atol=1e-12)
    assert abs(res.events["t"].iloc[-1] - p.accumulation_time()) <= 1e-12


@pytest.mark.parametrize(
    "name, bound",
    [("ofapi", 1e-12), ("scipy-radau", 1e-10), ("henon-rk4", 1e-5), ("heyoka", 1e-12), ("heyoka-q", 1e-12)],
)
def test_other_integrators_find_the_same_impacts(name, bound):
    p = nsbench.get_problem("bouncing-ball")
    ref = nsbench.simulate(p, "exact", 10.0).events
    res = nsbench.simulate(p, name, 10.0)
    assert res.ok, res.message
    assert list(res.events["kind"]) == list(ref["kind"])
    assert np.abs(res.events["t"].to_numpy() - ref["t"].to_numpy()).max() <= bound


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
        with pytest.raises(UnsupportedProblemError, match="friction family"):
            nsbench.get_integrator(name).setup(p)
