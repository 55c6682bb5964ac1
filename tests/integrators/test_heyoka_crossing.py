"""The compiled search for a fresh velocity guard's crossing on one heyoka step, against closed forms.

:func:`nsbench.integrators._heyoka_crossing.velocity_crossing` reads the step's Taylor
coefficients of a velocity. Here the velocity is a polynomial in time (``x' = 1``,
``v' = a - 2 b x`` from ``x = 0``: ``v = a t - b t^2``), so heyoka's Taylor series is
the velocity itself and one step spans the whole interval; the root ``t = a / b`` is
known exactly. The search refines it by Illinois' method on a polynomial evaluated in
double, so it lands within a few ulps of the root (bound: 8 ulps of ``t``).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

hy = pytest.importorskip("heyoka")

from nsbench.integrators import _heyoka_crossing as crossing  # noqa: E402


def _step(a: float, b: float, t_start: float, span: float):
    """One heyoka step of ``v = a (t - t_start) - b (t - t_start)^2``: its ``v`` coefficients and times."""
    x, v = hy.make_vars("x", "v")
    ta = hy.taylor_adaptive([(x, 1.0 + 0.0 * v), (v, a - 2.0 * b * x)], [0.0, 0.0], time=t_start)
    start = ta.dtime
    outcome, h = ta.step(span, write_tc=True)
    assert h == span  # the series ends: heyoka takes the whole span at once
    return np.array(ta.tc[1]), start, ta.time


@pytest.mark.parametrize("a, b, t_start", [(1.0, 1.0 / 1.3, 0.0), (2.5, 1.5, 10.0), (1e-3, 1e-3 / 0.77, 3.25)])
def test_the_root_of_a_slip_that_ends_inside_the_step(a, b, t_start):
    coeffs, start, t_end = _step(a, b, t_start, 2.0)
    out = np.zeros(1)
    found = crossing.velocity_crossing(coeffs, start[0], start[1], t_start, t_end, 1.0, 0.0, out)
    assert found == crossing.ROOT
    root = t_start + a / b
    assert abs(out[0] - root) <= 8 * math.ulp(root)


def test_no_crossing_a_wrong_side_and_a_guard_on_its_surface():
    out = np.zeros(1)
    coeffs, start, t_end = _step(1.0, 0.1, 0.0, 2.0)  # the root at t = 10: not in this step
    assert crossing.velocity_crossing(coeffs, *start, 0.0, t_end, 1.0, 0.0, out) == crossing.NONE
    # the guard -(v - v0) goes negative at once: a phase on its wrong side ends at its start
    assert crossing.velocity_crossing(coeffs, *start, 0.0, t_end, -1.0, 0.0, out) == crossing.AT_START
    coeffs, start, t_end = _step(0.0, 0.0, 0.0, 2.0)  # v stays exactly v0 = 0
    assert crossing.velocity_crossing(coeffs, *start, 0.0, t_end, 1.0, 0.0, out) == crossing.ON_SURFACE
