"""The missed-crossing check on every accepted step of a library integrator (scipy, SUNDIALS per arc).

A library's root finding stops at a sign change of a guard between two step
ends; a guard that leaves its side and comes back inside one step (a short
excursion: a slip of a few hundredths, a stick shorter than the step) is
stepped over. So each step is checked here, guard by guard, from what the
step already has: the guard's signed value ``h`` (positive on its own side) and
its rate ``h'`` at both ends (the rate from the field at the step's end states).

1. :func:`may_dip`, a test on those four numbers. Scaled to the step
   (``d = dt h'``), ``h`` cannot reach zero inside when both ends are farther
   from it than the end slopes reach (``min(h_a, h_b) > |d_a| + |d_b|``: most
   steps end here, at a few float operations). Otherwise the step may hold a
   dip when its cubic Hermite interpolant of ``h`` has an interior minimum at
   or below zero, or when ``h`` falls at the start and rises at the end (an
   interior minimum for certain) with zero within the ends' reach.
2. :func:`dip_root`, only for such steps: ``h`` on the step's own interpolant
   (the solver's dense output) at 7 interior points; a point below zero (by
   more than rounding, as in the core's own check) brackets the crossing with
   the point before it; otherwise the smallest point's neighbourhood is searched
   for the minimum (bounded Brent), and a minimum below zero brackets it. The
   crossing is then located on the interpolant as the library locates its own
   (Brent's method to 4 ulp), and the arc ends there: the excursion is an event
   of the run, not a gap in it.

The test of step 1 misses a dip only where ``h`` has two or more extrema inside
one step and stays above zero at the ends with slopes that point away from it:
a guard whose variation inside a step is not resolved by the step, which the
step-size control of the field does not allow except while the field is
constant (every block stuck); there the step is capped at a fraction of the
forcing period (:mod:`nsbench.integrators.scipy_`) or the forcing is a state of
the step-size control (``cvode-*``).
"""

from __future__ import annotations

from typing import Callable

import numpy as np

from nsbench.model.compile import hot

_EPS = float(np.finfo(float).eps)
#: Interior points of the step's interpolant examined when a step may hold a dip.
SAMPLES = 7


def rounding(y: np.ndarray) -> float:
    """What a guard's value may be off by from rounding alone at the state ``y`` (the core's own measure)."""
    return 64.0 * _EPS * max(1.0, float(np.max(np.abs(y))) if y.size else 1.0)


@hot
def may_dip(h_a, h_b, d_a, d_b, fresh):
    """Whether a guard with values ``h_a, h_b > 0`` and step-scaled rates ``d_a, d_b`` at a step's ends may go
    below zero inside the step (see the module docstring); compiled, for the loops of the SUNDIALS path too.

    ``fresh``: the step starts on the guard's own surface (``h_a = 0``, an arc's first step); minima within a
    millionth of the step from its start are then the start itself, not a dip.
    """
    if min(h_a, h_b) > abs(d_a) + abs(d_b):
        return False
    if not fresh and d_a < 0.0 < d_b:  # an interior minimum, with zero within the reach of the end slopes
        return True
    # the cubic Hermite p(s) = ((a s + b) s + d_a) s + h_a on s in [0, 1], and its critical points
    a = 2.0 * h_a - 2.0 * h_b + d_a + d_b
    b = -3.0 * h_a + 3.0 * h_b - 2.0 * d_a - d_b
    qa, qb, qc = 3.0 * a, 2.0 * b, d_a
    r0, r1 = -1.0, -1.0
    if qa == 0.0:
        if qb != 0.0:
            r0 = -qc / qb
    else:
        disc = qb * qb - 4.0 * qa * qc
        if disc < 0.0:
            return False
        sq = np.sqrt(disc)
        r0, r1 = (-qb - sq) / (2.0 * qa), (-qb + sq) / (2.0 * qa)
    skip = 1e-6 if fresh else 0.0
    for k in range(2):
        s = r0 if k == 0 else r1
        if skip < s < 1.0 and 6.0 * a * s + 2.0 * b > 0.0 and ((a * s + b) * s + d_a) * s + h_a <= 0.0:
            return True
    return False


def dip_root(
    h: Callable[[float, np.ndarray], float], sol, t_a: float, t_b: float, h_a: float, tol: float
) -> float | None:
    """The time a guard ``h(t, y)`` (positive on its side; ``h_a`` at ``t_a``) first goes below ``-tol`` on the
    interpolant ``sol`` of the step ``[t_a, t_b]``, located to 4 ulp, or ``None`` if it does not.

    ``sol(t)`` gives the state at ``t`` (and, for an array of times, the states as columns). The crossing
    is bracketed by the last point before the dip where the guard is on its side (``t_a`` itself when
    ``h_a > 0``); a guard that starts on its surface and is below it at every point before its minimum
    gives ``None`` (it leaves at once: the start rule's case, not a dip).
    """
    from scipy.optimize import brentq, minimize_scalar

    def value(t: float) -> float:
        return h(t, sol(t))

    def low_end(upto: int) -> float | None:
        for j in range(upto - 1, -1, -1):
            if values[j] > 0.0:
                return float(times[j])
        return t_a if h_a > 0.0 else None

    times = np.linspace(t_a, t_b, SAMPLES + 2)[1:-1]
    states = np.asarray(sol(times))
    values = [h(float(t), states[:, j]) for j, t in enumerate(times)]
    below = next((j for j, v in enumerate(values) if v < -tol), None)
    if below is None:
        j = int(np.argmin(values))
        lo = float(times[j - 1]) if j else t_a
        hi = float(times[j + 1]) if j + 1 < times.size else t_b
        found = minimize_scalar(value, bounds=(lo, hi), method="bounded", options={"xatol": 1e-12 * (t_b - t_a)})
        if not float(found.fun) < -tol:
            return None
        times = np.append(times[:j], float(found.x))  # the minimum takes the place of the points from j on
        values = values[:j] + [float(found.fun)]
        below = j
    start = low_end(below)
    if start is None:
        return None
    return float(brentq(value, start, float(times[below]), xtol=4 * _EPS, rtol=4 * _EPS))
