"""stats: the exact Mann-Whitney distribution, the Moses ratio interval, the median interval, the test."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from scipy.stats import binom, mannwhitneyu

from nsbench.bench.stats import median_interval, ratio_interval, relative_spread, slower_p, smallest_p, u_distribution


def _enumerated(n: int, m: int) -> np.ndarray:
    """P(U = u) by listing every placement of the n values of A among n + m ranks (independent of the
    Gaussian-binomial recurrence)."""
    counts = np.zeros(n * m + 1)
    for ranks in itertools.combinations(range(n + m), n):
        taken = set(ranks)
        counts[sum(sum(1 for j in range(i) if j not in taken) for i in ranks)] += 1
    return counts / counts.sum()


@pytest.mark.parametrize("n, m", [(1, 1), (2, 3), (3, 3), (5, 5), (4, 7), (6, 2)])
def test_u_distribution_matches_enumeration(n, m):
    assert np.allclose(u_distribution(n, m), _enumerated(n, m), rtol=0, atol=1e-15)


@pytest.mark.parametrize("n, m", [(3, 3), (5, 5), (4, 7), (8, 6), (20, 20)])
def test_slower_p_matches_scipy(n, m):
    rng = np.random.default_rng(n * 100 + m)
    for shift in (0.0, 0.2, 1.0):
        a, b = rng.lognormal(0, 0.2, n), rng.lognormal(shift, 0.2, m)
        expected = mannwhitneyu(b, a, alternative="greater", method="exact").pvalue
        assert slower_p(a, b) == pytest.approx(expected, rel=1e-12)


def test_smallest_p_is_reached_by_separated_samples():
    a, b = [1.0, 1.1, 1.2, 1.3, 1.4], [2.0, 2.1, 2.2, 2.3, 2.4]
    assert slower_p(a, b) == pytest.approx(smallest_p(5, 5)) == pytest.approx(1 / 252)
    assert slower_p(b, a) == pytest.approx(1.0)  # B faster: no evidence of a slowdown
    assert smallest_p(3, 3) == pytest.approx(0.05)  # 3 a side cannot reach 99 %
    assert math.isnan(slower_p([], [1.0]))


def test_ratio_interval_of_a_planted_factor():
    a = [1.00, 1.10, 1.05, 0.98, 1.02]
    est = ratio_interval(a, [2.0 * t for t in a])
    assert est.estimate == pytest.approx(2.0) and est.low < 2.0 < est.high
    # 5 a side: the 2 smallest and 2 largest of the 25 pairwise ratios are dropped (P(U <= 2) = 4/252)
    assert est.coverage == pytest.approx(1 - 2 * 4 / 252)
    ratios = np.sort([2.0 * y / x for x in a for y in a])
    assert est.low == pytest.approx(ratios[2]) and est.high == pytest.approx(ratios[-3])
    same = ratio_interval(a, a)
    assert same.estimate == pytest.approx(1.0) and same.contains(1.0)


def test_ratio_interval_covers_the_true_ratio():
    # Seeded draws, no clock: the interval must hold the true ratio in at least its stated share of
    # trials. 2000 trials: the binomial sd of the observed share is 0.004, the margin 0.95 vs 0.968.
    rng = np.random.default_rng(7)
    hits = 0
    for _ in range(2000):
        a = rng.lognormal(0.0, 0.3, 5)
        b = 1.5 * rng.lognormal(0.0, 0.3, 5)
        hits += ratio_interval(a, b).contains(1.5)
    assert hits / 2000 >= 0.95


def test_too_few_samples_give_the_widest_interval_with_its_coverage():
    est = ratio_interval([1.0, 1.1, 1.2], [1.0, 1.3, 1.2])
    assert est.coverage == pytest.approx(1 - 2 / 20)  # the full range of 9 pairwise ratios
    assert est.low == pytest.approx(1.0 / 1.2) and est.high == pytest.approx(1.3)
    assert not ratio_interval([], [1.0]).known


def test_median_interval_order_statistics():
    x = [5.0, 1.0, 3.0, 2.0, 4.0]
    est = median_interval(x)
    assert (est.estimate, est.low, est.high) == (3.0, 1.0, 5.0)
    assert est.coverage == pytest.approx(1 - 2 / 32)  # 5 samples cannot reach 95 %: the range
    many = median_interval(range(1, 21))
    # the largest j with 1 - 2 P(Bin(20, 1/2) <= j - 1) >= 0.95
    j = max(j for j in range(1, 11) if 1 - 2 * binom.cdf(j - 1, 20, 0.5) >= 0.95)
    assert (many.low, many.high) == (float(j), float(21 - j)) and many.coverage >= 0.95
    assert median_interval([0.0, math.nan, 2.0]).estimate == 2.0  # no measurement in 0 or NaN


def test_overlap_and_spread():
    a, b = median_interval([1.0, 1.2, 1.1]), median_interval([1.15, 1.3, 1.4])
    assert a.overlaps(b) and b.overlaps(a)
    assert not a.overlaps(median_interval([2.0, 2.1, 2.2]))
    assert relative_spread([1.0, 2.0, 1.5]) == pytest.approx(1.0 / 1.5)
    assert math.isnan(relative_spread([1.0]))
