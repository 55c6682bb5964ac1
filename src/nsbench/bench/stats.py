"""Statistics of timing samples: intervals for a median and for a cost ratio, and a test of a slowdown.

Pure functions of lists of seconds, so they are tested on constructed samples.
Every method here is distribution-free (it assumes nothing about the shape of
the timing noise, which on a shared machine is skewed and heavy-tailed) and
exact for the small sample counts a benchmark takes (3 to a few dozen):

- the interval of a median is a pair of order statistics, whose coverage
  follows from the binomial distribution (:func:`median_interval`);
- a cost ratio ``B / A`` is the Hodges-Lehmann estimate (the median of the
  ratios of every pair of samples, one from each side) and its interval the
  Moses interval: order statistics of those pairwise ratios chosen from the
  exact null distribution of the Mann-Whitney statistic (:func:`ratio_interval`);
- "B is slower than A" is the one-sided Mann-Whitney test, exact
  (:func:`slower_p`). It asks whether B's samples tend to exceed A's, not by
  how much; :mod:`nsbench.bench.compare` pairs it with the ratio.

The ratio model is a shift of the logarithm of the time (a slowdown
multiplies every run's time by the same factor), which is how code changes
and machine load act on a run's duration.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache
from typing import Iterable

import numpy as np

#: Largest ``n * m`` for which the Mann-Whitney distribution is computed exactly; beyond it,
#: the normal approximation (with 20+ samples a side, it is within 1e-3 of the exact tail).
EXACT_LIMIT = 2500


def _positive(values: Iterable[float]) -> np.ndarray:
    """The finite, positive samples (a time of 0 or NaN is no measurement), as an array."""
    x = np.asarray([float(v) for v in values], dtype=float)
    return x[np.isfinite(x) & (x > 0)]


@lru_cache(maxsize=256)
def u_distribution(n: int, m: int) -> tuple[float, ...]:
    """``P(U = u)`` for ``u = 0 .. n*m``: the exact null distribution of the Mann-Whitney statistic.

    ``U`` counts the pairs ``(a_i, b_j)`` with ``b_j < a_i`` among ``n`` and
    ``m`` exchangeable values. The number of orderings with ``U = u`` is the
    coefficient of ``q^u`` in the Gaussian binomial ``[n + m choose n]_q =
    prod_{i=1..n} (1 - q^(m+i)) / (1 - q^i)``, computed here in exact integers.
    """
    if n < 0 or m < 0:
        raise ValueError(f"sample sizes must be >= 0, got {n} and {m}")
    degree = n * m
    coeff = [0] * (degree + 1)
    coeff[0] = 1
    for i in range(1, n + 1):
        up = m + i
        for u in range(degree, up - 1, -1):  # times (1 - q^(m+i))
            coeff[u] -= coeff[u - up]
        for u in range(i, degree + 1):  # divided by (1 - q^i): a running sum with stride i
            coeff[u] += coeff[u - i]
    total = math.comb(n + m, n)
    return tuple(c / total for c in coeff)


def _u_cdf(n: int, m: int) -> np.ndarray:
    """``P(U <= u)`` for ``u = 0 .. n*m`` (exact up to :data:`EXACT_LIMIT`, normal beyond)."""
    if n * m <= EXACT_LIMIT:
        return np.cumsum(u_distribution(n, m))
    from scipy.stats import norm

    mean, sd = n * m / 2.0, math.sqrt(n * m * (n + m + 1) / 12.0)
    return norm.cdf((np.arange(n * m + 1) + 0.5 - mean) / sd)


@dataclass(frozen=True)
class Interval:
    """An estimate with its interval and the interval's actual coverage probability.

    ``coverage`` is what the method guarantees for these sample sizes; it is
    below the confidence asked for when there are too few samples to reach it
    (then the interval is the widest the samples allow). NaN everywhere when
    there is nothing to estimate from.
    """

    estimate: float
    low: float
    high: float
    coverage: float

    @property
    def known(self) -> bool:
        return math.isfinite(self.estimate)

    def contains(self, value: float) -> bool:
        return self.low <= value <= self.high

    def overlaps(self, other: "Interval") -> bool:
        return self.known and other.known and self.low <= other.high and other.low <= self.high


NAN_INTERVAL = Interval(math.nan, math.nan, math.nan, math.nan)


def median_interval(samples: Iterable[float], confidence: float = 0.95) -> Interval:
    """The median of ``samples`` and a distribution-free interval for the median of their population.

    The interval is ``[x_(j), x_(n+1-j)]`` (order statistics) with the largest
    ``j`` whose coverage ``1 - 2 P(Bin(n, 1/2) <= j - 1)`` is at least
    ``confidence``. With 5 samples no such ``j`` exists for 95 %: the interval is
    then the range of the samples, with its coverage 1 - 2/32 = 94 %.
    """
    x = np.sort(_positive(samples))
    n = x.size
    if n == 0:
        return NAN_INTERVAL
    if n == 1:
        return Interval(float(x[0]), float(x[0]), float(x[0]), 0.0)
    j, coverage = _median_order(n, float(confidence))
    return Interval(float(np.median(x)), float(x[j - 1]), float(x[n - j]), coverage)


@lru_cache(maxsize=None)
def _median_order(n: int, confidence: float) -> tuple[int, float]:
    """``(j, coverage)`` of :func:`median_interval` for ``n`` samples: the binomial sums in exact integers
    (a report asks for hundreds of intervals of a few sample counts; scipy's ``binom.cdf`` took a few ms each)."""

    def cdf(k: int) -> float:  # P(Bin(n, 1/2) <= k)
        return sum(math.comb(n, i) for i in range(k + 1)) / 2**n

    j = 1
    while j + 1 <= (n + 1) // 2 and 1.0 - 2.0 * cdf(j) >= confidence:
        j += 1
    return j, 1.0 - 2.0 * cdf(j - 1)


def _log_differences(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.sort((np.log(b)[None, :] - np.log(a)[:, None]).ravel())


def ratio_interval(a: Iterable[float], b: Iterable[float], confidence: float = 0.95) -> Interval:
    """The cost ratio ``B / A`` of two samples of times, with its Moses interval.

    The estimate is ``exp(median(log b_j - log a_i))`` over every pair (the
    Hodges-Lehmann estimate of the ratio); the interval is ``exp`` of the
    ``k``-th smallest and ``k``-th largest of those ``n*m`` differences, ``k``
    the largest with ``P(U <= k - 1) <= (1 - confidence) / 2`` under the exact
    Mann-Whitney distribution. With 5 samples a side, the 95 % interval drops
    the 2 smallest and 2 largest of the 25 pairwise ratios (coverage 96.8 %).
    Too few samples for the confidence (3 a side: at most 90 %) give the range
    of the pairwise ratios with its lower coverage.
    """
    xa, xb = _positive(a), _positive(b)
    n, m = xa.size, xb.size
    if n == 0 or m == 0:
        return NAN_INTERVAL
    d = _log_differences(xa, xb)
    estimate = float(np.exp(np.median(d)))
    cdf = _u_cdf(n, m)
    alpha = (1.0 - confidence) / 2.0
    k = int(np.searchsorted(cdf, alpha, side="right"))  # P(U <= k-1) <= alpha < P(U <= k)
    k = max(k, 1)
    coverage = max(0.0, 1.0 - 2.0 * float(cdf[k - 1])) if n * m > 1 else 0.0
    return Interval(estimate, float(np.exp(d[k - 1])), float(np.exp(d[d.size - k])), coverage)


def slower_p(a: Iterable[float], b: Iterable[float]) -> float:
    """One-sided p-value of "B's times tend to be larger than A's" (Mann-Whitney, exact when small).

    Small when (nearly) every sample of B exceeds every sample of A. With ``n``
    and ``m`` samples the smallest possible value is ``1 / C(n + m, n)``: 0.05
    with 3 a side, 0.004 with 5 a side. NaN without samples on both sides.
    """
    xa, xb = _positive(a), _positive(b)
    n, m = xa.size, xb.size
    if n == 0 or m == 0:
        return math.nan
    # U_b: pairs where b exceeds a (ties count one half); large U_b is evidence that B is slower
    greater = (xb[None, :] > xa[:, None]).sum() + 0.5 * (xb[None, :] == xa[:, None]).sum()
    u_small = n * m - greater  # pairs against it: P(U <= u_small) under H0
    if n * m <= EXACT_LIMIT:
        dist = np.cumsum(u_distribution(n, m))
        return float(min(1.0, dist[int(math.floor(u_small))]))
    return float(_u_cdf(n, m)[int(math.floor(u_small))])


def smallest_p(n: int, m: int) -> float:
    """The smallest p-value :func:`slower_p` can give with ``n`` and ``m`` samples."""
    return 1.0 / math.comb(n + m, n) if n > 0 and m > 0 else math.nan


def tied_with(fast: Iterable[float], other: Iterable[float], confidence: float = 0.95) -> bool:
    """Whether ``other``'s times cannot be told from the faster ``fast``'s.

    Tied when either side has fewer than two samples (no spread to judge by),
    when the two medians' distribution-free intervals overlap
    (:func:`median_interval`), or when the interval of the cost ratio holds 1
    (:func:`ratio_interval`). The report's answer, its class answer and its
    ranking all judge ties by this rule.
    """
    fast, other = list(fast), list(other)
    if len(fast) < 2 or len(other) < 2:
        return True
    a, b = median_interval(fast, confidence), median_interval(other, confidence)
    return a.overlaps(b) or ratio_interval(fast, other, confidence).contains(1.0)


def relative_spread(samples: Iterable[float]) -> float:
    """``(max - min) / median`` of the samples (NaN with fewer than two)."""
    x = _positive(samples)
    if x.size < 2:
        return math.nan
    return float((x.max() - x.min()) / np.median(x))
