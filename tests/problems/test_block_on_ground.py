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
