"""The Zeno rule's geometric tail and its error estimate (nsbench.model.rules), against series summed in closed form."""

from __future__ import annotations

import mpmath as mp
import pytest

from nsbench.engine import MAX_ACCUMULATION
from nsbench.model.rules import ACCUMULATION_RATIO, rounding_error, tail_estimate

#: The rule's functions as plain Python (the compiled ones are inlined into the core), run here on mp numbers
#: so that the tests see the estimate itself, not the rounding of doubles.
_tail = tail_estimate.py_func
_rounding = rounding_error.py_func


def _times(a, r, c, q, n, count=4):
    """``count`` consecutive event times from event ``n`` of a streak with intervals ``a r^k (1 + c q^k)``
    (ratios that converge to ``r`` geometrically, at the rate ``q``), from ``t = 0``, and its exact
    accumulation time ``a / (1 - r) + a c / (1 - r q)`` (two geometric series)."""
    t = mp.mpf(0)
    out = []
    for k in range(n + count):
        if k >= n:
            out.append(t)
        t += a * r**k * (1 + c * q**k)
    return out, a / (1 - r) + a * c / (1 - r * q)


def test_an_exactly_geometric_tail_is_its_accumulation_time():
    # the bouncing ball's flights: every ratio is e, so the tail is exact and the ratios' change is 0
    with mp.workdps(50):
        times, t_z = _times(mp.mpf(1), mp.mpf("0.8"), 0, 0, 3)
        got, err, ratio = _tail(*times, ACCUMULATION_RATIO)
        assert abs(got - t_z) <= mp.mpf("1e-45") and err <= mp.mpf("1e-45") and abs(ratio - mp.mpf("0.8")) < 1e-45


@pytest.mark.parametrize("r", ["0.3", "0.5", "0.8", "0.95"])
@pytest.mark.parametrize("c", ["0.5", "-0.3", "2"])
@pytest.mark.parametrize("q_power", [1, 2])
def test_the_estimate_covers_the_tail_when_the_ratios_converge_geometrically(r, c, q_power):
    # the docstring's assumption: the ratios converge at the rate r (q = r; a chattering mass's next speed
    # is r times its last one up to a term of the order of that speed) or faster (q = r^2). The estimate
    # is asymptotic: at a streak's first events (c q^n of order 1) it can be below the error (measured:
    # 0.50 for 0.59 at n = 0, r = 0.3, c = 2), but there it is far above any tolerance the rule takes
    # (MAX_ACCUMULATION = 1e-4, relative to max(1, |t|)). Every estimate within that must cover the true
    # accumulation time (measured: the error at most 0.50 of the estimate; the rule's rounding term at this
    # test's working precision added: 70 digits, the
    # deepest intervals ~1e-20), and it must shrink with the depth.
    with mp.workdps(70):
        r_, c_ = mp.mpf(r), mp.mpf(c)
        q = r_**q_power
        errors = []
        depth = int(20 / -mp.log10(r_)) + 4  # down to intervals of ~1e-20: far above this test's rounding
        for n in range(0, depth, max(1, depth // 20)):
            times, t_z = _times(mp.mpf(1), r_, c_, q, n)
            got, err, ratio = _tail(*times, ACCUMULATION_RATIO)
            if not err <= MAX_ACCUMULATION * max(1, abs(times[-1])):  # the rule would not extrapolate: no claim
                continue
            err += _rounding(times[-1], ratio, mp.eps)
            assert abs(got - t_z) <= err, (n, got - t_z, err)
            errors.append(err)
        assert len(errors) >= 8 and errors[-1] < errors[0] * mp.mpf("1e-2")


def test_intervals_that_do_not_shrink_are_no_accumulation():
    for times in ([0.0, 1.0, 2.0, 3.0], [0.0, 1.0, 1.5, 2.5], [0.0, 0.0, 1.0, 1.5]):
        t_z, err, _ = tail_estimate(*times, ACCUMULATION_RATIO)
        assert t_z != t_z and err == float("inf")


def test_the_rounding_term_is_the_sum_of_the_derivatives():
    # t_Z = t3 + d3^2 / (d2 - d3): moving t1, t2, t3 by +u, -u, +u (the signs of the derivatives r^2,
    # -2r, 1 over (1 - r)^2) moves t_Z by ((1 + r) / (1 - r))^2 u to first order
    with mp.workdps(50):
        times, _ = _times(mp.mpf(1), mp.mpf("0.6"), 0, 0, 2)
        t0, t1, t2, t3 = times
        u = mp.mpf("1e-30")
        base, _, ratio = _tail(t0, t1, t2, t3, ACCUMULATION_RATIO)
        moved, _, _ = _tail(t0, t1 + u, t2 - u, t3 + u, ACCUMULATION_RATIO)
        expected = _rounding(t3, ratio, u) / max(1, abs(t3))
        assert abs((moved - base) / expected - 1) < mp.mpf("1e-20")
