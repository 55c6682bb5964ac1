"""Compiled (numba) location of guard and section zeros on a converged Chebyshev segment.

Every function takes the segment as ``(t_a, w, nodes, weights, D, base, comp)``,
the interpolant being
``y(tau) = base + (p_D(tau) + comp)`` with ``p_D`` the barycentric interpolant of
the increments ``D`` and ``comp`` the compensated-summation remainder of the
start state. Values are signed so that the valid side is positive; derivatives
are taken in ``tau`` through the ODE (``dy/dtau = w g(y, t)``), never by
differentiating the polynomial.
"""

from __future__ import annotations

import numpy as np

from nsbench.integrators._chebyshev import barycentric
from nsbench.model.compile import hot
from nsbench.model.law import guard_rate, guard_value, rhs
from nsbench.model.records import linear_section_rate, linear_section_value

_EPS = np.finfo(np.float64).eps
SECTION = -1  # ``target`` code of a linear section (guards use their kind codes >= 0)


@hot
def state_at(nodes, weights, D, base, comp, tau, out):
    """The interpolated state at ``tau`` into ``out``."""
    barycentric(nodes, weights, D, tau, out)
    for i in range(out.shape[0]):
        out[i] = base[i] + (out[i] + comp[i])


@hot
def evaluate(p, mode, target, index, sign, sec_coeffs, sec_levels, t_a, w, nodes, weights, D, base,
             comp, tau, y, dy, want_rate):
    """``sign *`` guard (kind ``target``, block ``index``) or section ``index`` at ``tau``.

    Returns ``(value, d value / d tau)``; the rate (one field evaluation) only if ``want_rate``.
    """
    state_at(nodes, weights, D, base, comp, tau, y)
    t = t_a + w * (tau + 1.0)
    if target >= 0:
        f = sign * guard_value(p, mode, target, index, t, y)
    else:
        f = sign * linear_section_value(sec_coeffs[index], sec_levels[index], y)
    if not want_rate:
        return f, 0.0
    rhs(p, mode, t, y, dy)
    if target >= 0:
        d = sign * guard_rate(p, mode, target, index, t, y, dy)
    else:
        d = sign * linear_section_rate(sec_coeffs[index], dy)
    return f, w * d


@hot
def root(p, mode, target, index, sign, sec_coeffs, sec_levels, t_a, w, nodes, weights, D, base, comp,
         lo, hi, f_lo, f_hi, y, dy):
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
        f, d = evaluate(p, mode, target, index, sign, sec_coeffs, sec_levels, t_a, w, nodes, weights,
                        D, base, comp, tau, y, dy, True)
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
def extremum(p, mode, kind, block, sign, sec_coeffs, sec_levels, t_a, w, nodes, weights, D, base, comp,
             lo, hi, minimum, y, dy):
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
        f, d = evaluate(p, mode, kind, block, sign, sec_coeffs, sec_levels, t_a, w, nodes, weights,
                        D, base, comp, mid, y, dy, True)
        nfev += 1
        if (minimum and f <= 0.0) or (not minimum and f > 0.0) or hi - lo <= 1e-10:
            break
        if flip * d < 0.0:
            lo = mid
        else:
            hi = mid
    return mid, f, nfev


@hot
def first_zero(p, mode, kind, block, sign, sec_coeffs, sec_levels, t_a, w, nodes, weights, D, base, comp,
               a, b, fa, fb, da, db, y, dy):
    """First zero of a signed guard in the node interval ``[a, b]`` from its end values and rates.

    ``fa > 0`` is the usual case: a sign change is a crossing; equal signs with
    the rate turning from negative to positive may hide a tangential touch,
    decided by the minimum. ``fa <= 0`` happens only at a phase start, on the
    guard's own surface. Returns ``(found, tau, nfev)``.
    """
    if fa > 0.0:
        if fb <= 0.0:
            tau, nf = root(p, mode, kind, block, sign, sec_coeffs, sec_levels, t_a, w, nodes, weights, D,
                           base, comp, a, b, fa, fb, y, dy)
            return True, tau, nf
        if da < 0.0 and db > 0.0:
            m, fm, nf = extremum(p, mode, kind, block, sign, sec_coeffs, sec_levels, t_a, w, nodes, weights,
                                 D, base, comp, a, b, True, y, dy)
            if fm <= 0.0:
                tau, nf2 = root(p, mode, kind, block, sign, sec_coeffs, sec_levels, t_a, w, nodes, weights,
                                D, base, comp, a, m, fa, fm, y, dy)
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
        m, fm, nf = extremum(p, mode, kind, block, sign, sec_coeffs, sec_levels, t_a, w, nodes, weights,
                             D, base, comp, a, b, True, y, dy)
        scale = 1.0
        for i in range(base.shape[0]):
            scale = max(scale, abs(base[i]))
        if fm < -64.0 * _EPS * scale:  # a genuine dip: it leaves its valid side at once
            return True, a, nf
        return False, b, nf
    if da == 0.0 and fb == 0.0:
        return True, a, 0
    # not positive at the node: did it rise and come back within the first interval?
    m, fm, nf = extremum(p, mode, kind, block, sign, sec_coeffs, sec_levels, t_a, w, nodes, weights,
                         D, base, comp, a, b, False, y, dy)
    if fm > 0.0:
        tau, nf2 = root(p, mode, kind, block, sign, sec_coeffs, sec_levels, t_a, w, nodes, weights,
                        D, base, comp, m, b, fm, fb, y, dy)
        return True, tau, nf + nf2
    return True, a, nf
