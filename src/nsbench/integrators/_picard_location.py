"""Compiled (numba) location of guard and section zeros on a converged Chebyshev segment.

Every function takes the segment as a :class:`Segment` ``(t_a, w, nodes,
weights, D, base, comp)`` and what it looks for as a :class:`Target`, the
interpolant being
``y(tau) = base + (p_D(tau) + comp)`` with ``p_D`` the barycentric interpolant of
the increments ``D`` and ``comp`` the compensated-summation remainder of the
start state. Values are signed so that the valid side is positive; derivatives
are taken in ``tau`` through the ODE (``dy/dtau = w g(y, t)``), never by
differentiating the polynomial.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from nsbench.integrators._chebyshev import barycentric
from nsbench.model.compile import hot
from nsbench.model.law import guard_rate, guard_value, rhs
from nsbench.model.records import linear_section_rate, linear_section_value

_EPS = np.finfo(np.float64).eps
SECTION = -1  # ``target`` code of a linear section (guards use their kind codes >= 0)


class Segment(NamedTuple):
    """A converged segment: ``y(tau) = base + (p_D(tau) + comp)`` at ``t = t_a + w (tau + 1)``."""

    t_a: float
    w: float
    nodes: np.ndarray
    weights: np.ndarray
    D: np.ndarray
    base: np.ndarray
    comp: np.ndarray


class Target(NamedTuple):
    """What is located: guard ``(kind, index)`` (``kind >= 0``) or section ``index`` (``kind = SECTION``),
    signed by ``sign`` so that its valid side is positive."""

    kind: int
    index: int  # type: ignore[assignment]  # shadows tuple.index: the kernels read it by name
    sign: float
    sec_coeffs: np.ndarray
    sec_levels: np.ndarray


@hot
def state_at(nodes, weights, D, base, comp, tau, out):
    """The interpolated state at ``tau`` into ``out``."""
    barycentric(nodes, weights, D, tau, out)
    for i in range(out.shape[0]):
        out[i] = base[i] + (out[i] + comp[i])


@hot
def evaluate(p, mode, tg, seg, tau, y, dy, want_rate):
    """``sign *`` the target at ``tau`` of the segment; ``(value, d value / d tau)``, the rate (one field
    evaluation) only if ``want_rate``."""
    state_at(seg.nodes, seg.weights, seg.D, seg.base, seg.comp, tau, y)
    t = seg.t_a + seg.w * (tau + 1.0)
    if tg.kind >= 0:
        f = tg.sign * guard_value(p, mode, tg.kind, tg.index, t, y)
    else:
        f = tg.sign * linear_section_value(tg.sec_coeffs[tg.index], tg.sec_levels[tg.index], y)
    if not want_rate:
        return f, 0.0
    rhs(p, mode, t, y, dy)
    if tg.kind >= 0:
        d = tg.sign * guard_rate(p, mode, tg.kind, tg.index, t, y, dy)
    else:
        d = tg.sign * linear_section_rate(tg.sec_coeffs[tg.index], dy)
    return f, seg.w * d


@hot
def root(p, mode, tg, seg, lo, hi, f_lo, f_hi, y, dy):
    """Zero in ``[lo, hi]`` where ``f_lo > 0 >= f_hi``: Newton from the secant point, bracket kept.

    A Newton step that leaves the bracket is replaced by bisection. Stops when
    the step is below 1e-15 in ``tau`` (about one ulp) or the value is exactly
    zero. Returns ``(tau, nfev)``.
    """
    if f_hi == 0.0:
        return hi, 0
    tau = lo + (hi - lo) * (f_lo / (f_lo - f_hi))
    if not lo < tau < hi:
        tau = 0.5 * (lo + hi)
    nfev = 0
    for _ in range(100):
        f, d = evaluate(p, mode, tg, seg, tau, y, dy, True)
        nfev += 1
        if f == 0.0:
            return tau, nfev
        if f > 0.0:
            lo = tau
        else:
            hi = tau
        new = tau - f / d if d != 0.0 else np.nan
        if not lo < new < hi:
            new = 0.5 * (lo + hi)
        if abs(new - tau) <= 1e-15 or hi - lo <= 4e-16:
            return new, nfev
        tau = new
    return tau, nfev


@hot
def extremum(p, mode, tg, seg, lo, hi, minimum, y, dy):
    """Bisection on the sign of the rate for the minimum (or maximum) of a guard in ``[lo, hi]``.

    Stops early at a point that settles the question (value <= 0 when looking
    for a minimum, > 0 for a maximum), else at width 1e-10. Returns ``(tau, value, nfev)``.
    """
    flip = 1.0 if minimum else -1.0
    nfev = 0
    mid = 0.5 * (lo + hi)
    f = 0.0
    while True:
        mid = 0.5 * (lo + hi)
        f, d = evaluate(p, mode, tg, seg, mid, y, dy, True)
        nfev += 1
        if (minimum and f <= 0.0) or (not minimum and f > 0.0) or hi - lo <= 1e-10:
            break
        if flip * d < 0.0:
            lo = mid
        else:
            hi = mid
    return mid, f, nfev


@hot
def first_zero(p, mode, tg, seg, a, b, fa, fb, da, db, y, dy):
    """First zero of a signed guard in the node interval ``[a, b]`` from its end values and rates.

    ``fa > 0`` is the usual case: a sign change is a crossing; equal signs with
    the rate turning from negative to positive may hide a tangential touch,
    decided by the minimum. ``fa <= 0`` happens only at a phase start, on the
    guard's own surface. Returns ``(found, tau, nfev)``.
    """
    if fa > 0.0:
        if fb <= 0.0:
            tau, nf = root(p, mode, tg, seg, a, b, fa, fb, y, dy)
            return True, tau, nf
        if da < 0.0 and db > 0.0:
            m, fm, nf = extremum(p, mode, tg, seg, a, b, True, y, dy)
            if fm <= 0.0:
                tau, nf2 = root(p, mode, tg, seg, a, m, fa, fm, y, dy)
                return True, tau, nf + nf2
            return False, b, nf
        return False, b, 0
    # A phase start on the guard's own surface. When the start rate is zero in exact
    # arithmetic (kinetic friction equal to static: a block breaks away with zero
    # acceleration) its computed sign is rounding, so the sign of the rate alone does
    # not decide; as in ``exact``, the values on the interval do: the phase ends at
    # once only if the guard goes below zero by more than rounding before it rises.
    if fb > 0.0:
        if da >= 0.0:
            return False, b, 0
        m, fm, nf = extremum(p, mode, tg, seg, a, b, True, y, dy)
        scale = 1.0
        for i in range(seg.base.shape[0]):
            scale = max(scale, abs(seg.base[i]))
        if fm < -64.0 * _EPS * scale:  # a genuine dip: it leaves its valid side at once
            return True, a, nf
        return False, b, nf
    if da == 0.0 and fb == 0.0:
        return True, a, 0
    # not positive at the node: did it rise and come back within the first interval?
    m, fm, nf = extremum(p, mode, tg, seg, a, b, False, y, dy)
    if fm > 0.0:
        tau, nf2 = root(p, mode, tg, seg, m, b, fm, fb, y, dy)
        return True, tau, nf + nf2
    return True, a, nf
