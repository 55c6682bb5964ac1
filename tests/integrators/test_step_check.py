"""The per-step test of the missed-crossing check (``integrators/_step_check.py``), on closed forms.

The whole check (every step of an arc tested, a flagged step integrated again) is tested through the
integrators: ``tests/test_engine.py`` (a loose dop853 run that steps over a stick) and the two points of
``tests/integrators/test_scipy.py`` and ``test_sundials.py``.
"""

from __future__ import annotations

import pytest

from nsbench.integrators._step_check import may_dip


def _ends(h, dh, t_a: float, t_b: float):
    """Values and step-scaled rates of ``h`` at the ends of ``[t_a, t_b]``."""
    dt = t_b - t_a
    return h(t_a), h(t_b), dt * dh(t_a), dt * dh(t_b)


@pytest.mark.parametrize("depth", [1e-2, 1e-6, 0.0])
def test_a_parabola_at_or_below_zero_inside_the_step_may_dip(depth):
    # h(t) = (t - 0.3)^2 - depth on [0, 1]: positive at both ends, its minimum -depth inside (a touch at 0)
    h_a, h_b, d_a, d_b = _ends(lambda t: (t - 0.3) ** 2 - depth, lambda t: 2.0 * (t - 0.3), 0.0, 1.0)
    assert h_a > 0 and h_b > 0 and may_dip(h_a, h_b, d_a, d_b)


def test_a_guard_far_from_zero_against_its_slopes_is_not_flagged():
    assert not may_dip(1.0, 0.8, -0.1, -0.1)
    # h = (t - 0.5)^2 + c on [0, 1]: end slopes -1, 1 (reach 2), the cubic is h itself, minimum c: flagged
    # within MARGIN * reach = 0.25 of zero (room for the cubic's error on a real step), not above
    for c, flagged in ((0.3, False), (0.2, True)):
        h_a, h_b, d_a, d_b = _ends(lambda t: (t - 0.5) ** 2 + c, lambda t: 2.0 * (t - 0.5), 0.0, 1.0)
        assert may_dip(h_a, h_b, d_a, d_b) is flagged
    # monotone through the step, nearly zero at its end: no interior minimum, the cubic stays above zero
    assert not may_dip(0.5, 1e-3, -0.6, -0.4)


def test_a_dip_between_two_extrema_is_seen_from_the_cubic():
    # h(s) = 0.02 + s - 3 s^2 + 2 s^3 on [0, 1]: rising at both ends (h' = 1 there), a maximum then a
    # minimum below zero at s = (3 + sqrt(3)) / 6 (h = -0.076): the end rates alone do not change sign
    assert may_dip(0.02, 0.02, 1.0, 1.0)
