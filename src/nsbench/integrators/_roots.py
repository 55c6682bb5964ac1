"""Bracketing of guard crossings on a sampled smooth function, tangential touches included.

Shared by the integrators that can evaluate a guard anywhere in an interval
(closed-form flows, dense interpolants). ``phi`` is ``expected_sign * guard``:
positive while the mode is valid; the event is its first zero after the start.
"""

from __future__ import annotations

from typing import Callable

import numpy as np
from scipy.optimize import brentq

_EPS = np.finfo(float).eps
Scalar = Callable[[float], float]


def bracketed_root(f: Scalar, a: float, b: float) -> float:
    """Root of ``f`` in ``[a, b]`` where ``f`` changes sign, to a few ulps (Brent).

    The bracket comes from vectorised samples; re-evaluated one at a time, an
    end value within rounding of zero can come out with the other sign (at a
    grazing start, for instance). Then the end closer to zero is the root.
    """
    try:
        return brentq(f, a, b, xtol=1e-300, rtol=4 * _EPS, maxiter=200)
    except ValueError:  # f(a) and f(b) have the same sign: rounding noise at an end
        fa, fb = f(a), f(b)
        return a if abs(fa) <= abs(fb) else b


_root = bracketed_root  # phi(a) > 0 >= phi(b)
_extremum = bracketed_root  # the derivative psi changes sign in [a, b]


def first_zero(phi: Scalar, psi: Scalar, a: float, b: float, phi_a: float, phi_b: float,
               psi_a: float, psi_b: float, *, start: bool = False,
               subdivisions: int = 16) -> float | None:
    """First ``s`` in ``(a, b]`` where ``phi`` reaches zero, or ``None``.

    Assumes ``[a, b]`` is short enough that ``phi`` has at most one extremum in
    it (callers sample at a fraction of the shortest time scale); a tangential
    touch or a double crossing between the samples is caught through the sign
    change of the derivative ``psi``. With ``start=True``, ``a`` is the start of
    an arc where ``phi`` may be exactly zero (the phase starts on its surface),
    so the zero sought is the first one after ``phi`` has become positive.

    Parameters
    ----------
    phi, psi
        Scalar functions: the signed guard and its time derivative.
    a, b, phi_a, phi_b, psi_a, psi_b
        The interval and the sampled values at its ends.
    start
        Whether ``a`` is the start of the arc.
    subdivisions
        Samples used when the interval is ambiguous.
    """
    if phi_a <= 0.0:
        if not start:
            return a
        if psi_a > 0.0 and psi_b < 0.0:
            s_max = _extremum(psi, a, b)
            if phi(s_max) > 0.0:
                return _root(phi, s_max, b) if phi_b <= 0.0 else None
        elif psi_a > 0.0 and phi_b > 0.0:
            return None  # leaves the surface and keeps rising through the interval
        return _subdivide(phi, psi, a, b, subdivisions)
    if phi_b <= 0.0:
        return _root(phi, a, b)
    if psi_a < 0.0 < psi_b:
        s_min = _extremum(psi, a, b)
        phi_min = phi(s_min)
        if phi_min <= 0.0:
            return s_min if phi_min == 0.0 else _root(phi, a, s_min)
    return None


def _subdivide(phi: Scalar, psi: Scalar, a: float, b: float, n: int) -> float | None:
    """Resolve an ambiguous start interval by sampling ``n`` sub-intervals.

    If ``phi`` never becomes positive, the phase is invalid from its start and
    the event is at ``a`` (a zero-length phase, left to the engine's rules).
    """
    s = np.linspace(a, b, n + 1)
    values = [phi(float(x)) for x in s]
    rates = [psi(float(x)) for x in s]
    first_positive = next((j for j, v in enumerate(values) if v > 0.0), None)
    if first_positive is None:
        return a
    for j in range(first_positive, n):
        hit = first_zero(phi, psi, float(s[j]), float(s[j + 1]), values[j], values[j + 1],
                         rates[j], rates[j + 1])
        if hit is not None:
            return hit
    return None
