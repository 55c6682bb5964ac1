"""Extended-precision helpers for the reference solvers: compensated sums, a long-double matrix exponential.

``numpy.longdouble`` is the 80-bit x87 format on x86 (64-bit mantissa, about
three more digits than double); on platforms where it equals double these
helpers still work, without the extra digits.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:  # pragma: no cover
    from nsbench.problems.oscillator import FrictionOscillator

EXTENDED = np.longdouble  # 80-bit extended precision on x86; equal to double elsewhere


def expm_extended(m: np.ndarray) -> np.ndarray:
    """Matrix exponential in extended precision: scaled Taylor series, then squaring."""
    norm = float(np.max(np.sum(np.abs(m.astype(float)), axis=1)))
    squarings = max(0, math.ceil(math.log2(norm))) if norm > 1.0 else 0
    a = m / EXTENDED(2.0) ** squarings
    term = np.eye(m.shape[0], dtype=EXTENDED)
    out = term.copy()
    for k in range(1, 30):  # 1 / 30! is far below the extended epsilon
        term = (term @ a) / EXTENDED(k)
        out = out + term
    for _ in range(squarings):
        out = out @ out
    return out


def guard_row(problem: FrictionOscillator, guard) -> np.ndarray:
    """``q`` with ``guard.value(t, y) = q . [y, 1, cos(w t), sin(w t)]`` (linear problems)."""
    n = problem.n_states
    q = np.zeros(n + 3)
    i = guard.block - 1
    if guard.kind == "velocity":
        q[2 * i + 1], q[n] = 1.0, -problem.v0
        return q
    zero = np.zeros(n)
    for j in range(n):
        unit = zero.copy()
        unit[j] = 1.0
        q[j] = float(problem.restoring_force(guard.block, 0.0, unit)
                     - problem.restoring_force(guard.block, 0.0, zero))
    fr = problem.coefficients.fr[i]
    q[n] = -fr if guard.kind == "upper" else fr
    if i == problem.n_blocks - 1:
        q[n + 1] = -problem.coefficients.F
    return q


def two_sum(a: float, b: float) -> tuple[float, float]:
    """``(hi, lo)`` with ``hi = fl(a + b)`` and ``hi + lo = a + b`` exactly (Knuth)."""
    hi = a + b
    bb = hi - a
    return hi, (a - (hi - bb)) + (b - bb)
