"""``block-on-ground``: the Siconos friction oscillator's reversals and its rest, against the closed form."""

from __future__ import annotations

import math

import numpy as np
import pytest

import nsbench
from nsbench.problems.block_on_ground import closed_form_events


def test_exact_meets_every_event_and_the_rest_in_closed_form():
    p = nsbench.get_problem("block-on-ground")
    events, x_rest = closed_form_events(p)
    # from (12, 6): amplitude sqrt(13^2 + 6^2) about -1 first, falling by 2 at every reversal
    assert events[0][0] == pytest.approx(math.atan2(6, 13), rel=1e-15)
    assert [k for _, k in events] == ["reverse"] * 7 + ["stick"]
    assert x_rest == pytest.approx(15 - math.sqrt(205), rel=1e-14)
    res = nsbench.simulate(p, "exact", 60.0)
    assert res.ok, res.message
    assert list(res.events["kind"]) == [k for _, k in events]
    np.testing.assert_allclose(res.events["t"], [t for t, _ in events], rtol=0, atol=1e-12)
    assert abs(res.y_final[0] - x_rest) <= 1e-12 and res.y_final[1] == 0.0 and res.mode_final == (0,)


@pytest.mark.parametrize("name, bound", [("ofapi", 1e-10), ("heyoka", 1e-12), ("cvode-bdf", 1e-5), ("henon-rk4", 1e-7)])
def test_other_integrators_reach_the_same_rest(name, bound):
    p = nsbench.get_problem("block-on-ground")
    events, x_rest = closed_form_events(p)
    res = nsbench.simulate(p, name, 60.0)
    assert res.ok, res.message
    assert list(res.events["kind"]) == [k for _, k in events]
    assert np.abs(res.events["t"].to_numpy() - [t for t, _ in events]).max() <= bound


def test_parameters_and_the_start_state():
    p = nsbench.get_problem("block-on-ground", x1_0=-5.0, v1_0=-1.0, fs=0.5, fr=0.8, m=2.0)
    events, x_rest = closed_form_events(p)
    res = nsbench.simulate(p, "exact", 100.0)
    np.testing.assert_allclose(res.events["t"], [t for t, _ in events], rtol=0, atol=1e-12)
    assert abs(res.y_final[0] - x_rest) <= 1e-12
    with pytest.raises(nsbench.ConfigError, match="kinetic friction fs must be <= static friction"):
        nsbench.get_problem("block-on-ground", fs=2.0)
    with pytest.raises(nsbench.ConfigError, match="unknown parameter 'x2_0'"):
        nsbench.get_problem("block-on-ground", x2_0=1.0)


def _forced_slip_velocity(t, x0, v0, s, m, k, fs, F, w, mp):
    """Velocity of a slip of direction ``s`` started at ``(0, x0, v0)``: the forced harmonic oscillator in closed form.

    ``m x'' + k x = -s fs + F cos(w t)``: ``x = x_c + a cos(W t) + b sin(W t) + P cos(w t)`` with
    ``W = sqrt(k / m)``, ``x_c = -s fs / k`` and ``P = F / (k - m w^2)`` (``w != W``).
    """
    W = mp.sqrt(k / m)
    xc = -s * fs / k
    P = F / (k - m * w * w)
    a = x0 - xc - P
    b = v0 / W
    return -a * W * mp.sin(W * t) + b * W * mp.cos(W * t) - P * w * mp.sin(w * t)


def test_the_forced_block_meets_its_first_reversal_in_closed_form_and_an_independent_integrator():
    """F cos(w t) on the block (F = 1.5 > fr: a stick-slip cycle, 32 events over [0, 100])."""
    mp = pytest.importorskip("mpmath")
    mp.mp.dps = 40
    p = nsbench.get_problem("block-on-ground", F=1.5, w=0.5)
    res = nsbench.simulate(p, "exact", 100.0)
    assert res.ok, res.message
    kinds = list(res.events["kind"])
    assert len(kinds) == 32 and kinds.count("stick") == 13 and kinds.count("slip") == 13
    # the first slip (v > 0 from (12, 6)) ends where its closed-form velocity is zero
    t1 = mp.findroot(lambda t: _forced_slip_velocity(t, 12, 6, 1, 1, 1, 1, mp.mpf("1.5"), mp.mpf("0.5"), mp), 0.48)
    assert kinds[0] == "reverse"
    assert abs(res.events["t"].iloc[0] - float(t1)) <= 1e-13  # exact's arcs are exact to rounding
    # every event against heyoka's Taylor method (an independent integrator; 1e-12 as for the unforced block)
    other = nsbench.simulate(p, "heyoka", 100.0)
    assert other.ok and list(other.events["kind"]) == kinds
    assert np.abs(other.events["t"].to_numpy() - res.events["t"].to_numpy()).max() <= 1e-12


def test_an_unknown_parameter_lists_every_allowed_name():
    with pytest.raises(nsbench.ConfigError) as info:
        nsbench.get_problem("block-on-ground", omega=1.0)
    message = str(info.value)
    assert "unknown parameter 'omega'" in message
    for name in ("m", "c", "k", "fs", "fr", "F", "w", "x1_0", "v1_0", "law"):
        assert f" {name}," in message or message.endswith(f" {name}"), name
    with pytest.raises(nsbench.ConfigError, match="forcing frequency w"):
        nsbench.get_problem("block-on-ground", F=1.0, w=-0.5)
    with pytest.raises(ValueError, match="closed form is for the undamped, unforced"):
        closed_form_events(nsbench.get_problem("block-on-ground", F=1.0))
