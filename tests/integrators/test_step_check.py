"""The per-step missed-crossing check of the library integrators (``integrators/_step_check.py``), on closed forms."""

from __future__ import annotations

import math

import numpy as np
import pytest

from nsbench.integrators._step_check import dip_root, may_dip


def _sol(t):
    """A one-state "dense output" ``y(t) = t``, shaped as scipy's: ``(1,)`` at a time, ``(1, k)`` at k times."""
    return np.array([t], dtype=float) if np.ndim(t) == 0 else np.asarray(t, dtype=float)[None, :]


def _ends(h, dh, t_a: float, t_b: float):
    """Values and step-scaled rates of ``h`` at the ends of ``[t_a, t_b]``."""
    dt = t_b - t_a
    return h(t_a), h(t_b), dt * dh(t_a), dt * dh(t_b)


@pytest.mark.parametrize("depth", [1e-2, 1e-6])
def test_a_parabola_dipping_below_zero_inside_the_step_is_found_and_located(depth):
    # h(t) = (t - 0.3)^2 - depth on [0, 1]: positive at both ends, below zero on (0.3 - sqrt(depth), 0.3 + ...);
    # its first zero is 0.3 - sqrt(depth) exactly (a closed form)
    def h(t):
        return (t - 0.3) ** 2 - depth

    def dh(t):
        return 2.0 * (t - 0.3)

    h_a, h_b, d_a, d_b = _ends(h, dh, 0.0, 1.0)
    assert h_a > 0 and h_b > 0 and may_dip(h_a, h_b, d_a, d_b, False)
    tau = dip_root(lambda t, y: h(float(y[0])), _sol, 0.0, 1.0, h_a, 1e-15)
    # Brent's method to 4 ulp (xtol = rtol = 4 eps): within 1e-15 of the closed form at t ~ 0.3
    assert tau is not None and abs(tau - (0.3 - math.sqrt(depth))) <= 1e-15


def test_a_guard_that_stays_on_its_side_is_not_searched_or_not_found():
    # far from zero against its slopes: no search at all (most steps)
    assert not may_dip(1.0, 0.8, -0.1, -0.1, False)

    # a minimum above zero (the parabola lifted): searched when near zero, but no crossing
    def h(t):
        return (t - 0.5) ** 2 + 1e-3

    h_a, h_b, d_a, d_b = _ends(h, lambda t: 2.0 * (t - 0.5), 0.0, 1.0)
    assert may_dip(h_a, h_b, d_a, d_b, False)
    assert dip_root(lambda t, y: h(float(y[0])), _sol, 0.0, 1.0, h_a, 1e-15) is None


def test_a_dip_between_two_extrema_is_seen_from_the_cubic():
    # h(s) = 0.02 + s - 3 s^2 + 2 s^3: rising at both ends (h' = 1 there), a maximum then a minimum
    # below zero at s = (3 + sqrt(3)) / 6 (h = -0.076): the rates alone do not change sign
    h_a, h_b, d_a, d_b = 0.02, 0.02, 1.0, 1.0
    assert d_a > 0 and d_b > 0 and may_dip(h_a, h_b, d_a, d_b, False)


def test_a_start_on_the_surface_is_not_a_dip_but_a_later_one_is():
    # an arc's first step starts on the guard's own surface (h_a = 0) moving away from it: no dip
    assert not may_dip(0.0, 0.5, 1.0, 0.2, True)
    # moving away, then back below zero and up again inside the step (h = s (s - 0.5) (s - 0.9) + ...):
    # h(s) = 2 s^3 - 2.8 s^2 + 0.9 s, zero at 0 and at 0.5, 0.9; h(1) = 0.1 > 0, h'(0) = 0.9 > 0
    h_a, h_b, d_a, d_b = 0.0, 0.1, 0.9, 6 - 5.6 + 0.9
    assert may_dip(h_a, h_b, d_a, d_b, True)
