"""Compiled search for the first crossing of a fresh velocity guard on one heyoka step (double precision).

:meth:`nsbench.integrators.heyoka_.HeyokaIntegrator._first_step` keeps a guard that
starts an arc on its own surface off heyoka's event detection for the first step and
looks for its crossing on the step's Taylor polynomial: 32 samples for the first turn
to the guard's right side, then Illinois' method on the bracket. For a velocity guard
``sign * (v_i - v0)`` in double precision the polynomial is the step's Taylor
coefficients of ``v_i`` (heyoka's ``tc``, what its dense output evaluates), so the
whole search runs here, compiled, instead of one Python call per evaluation.
"""

from __future__ import annotations

from nsbench.model.compile import hot

#: Outcomes of :func:`velocity_crossing`.
NONE, ROOT, AT_START, ON_SURFACE = 0, 1, 2, 3


@hot
def _value(coeffs, hi0, lo0, sign, v0, t):
    """``sign * (v(t) - v0)``, ``v`` the Taylor polynomial in ``t - (hi0 + lo0)`` (Horner's scheme)."""
    h = (t - hi0) - lo0
    acc = 0.0
    for j in range(coeffs.shape[0] - 1, -1, -1):
        acc = acc * h + coeffs[j]
    return sign * (acc - v0)


@hot
def _illinois(coeffs, hi0, lo0, sign, v0, a, fa, b, fb):
    """Root in ``[a, b]`` with ``fa > 0 >= fb``, as :func:`nsbench.integrators._heyoka_model.illinois`."""
    side = 0
    for _ in range(100):
        if fb == 0.0:
            break
        c = (a * fb - b * fa) / (fb - fa)
        if not a < c < b:
            c = a + (b - a) / 2.0  # the secant lands on an end: halve (see _heyoka_model.illinois)
            if not a < c < b:
                break
        fc = _value(coeffs, hi0, lo0, sign, v0, c)
        if fc > 0.0:
            a, fa = c, fc
            if side == 1:
                fb = fb / 2.0
            side = 1
        else:
            b, fb = c, fc
            if side == -1:
                fa = fa / 2.0
            side = -1
    return b


@hot
def velocity_crossing(coeffs, hi0, lo0, t_start, t_end, sign, v0, out):
    """The first zero of ``sign * (v - v0)`` in ``(t_start, t_end]`` after it turned positive.

    ``coeffs``: the step's Taylor coefficients of ``v`` (lowest order first); ``(hi0, lo0)``:
    heyoka's double-length time where the step started. Returns :data:`ROOT` (the time in
    ``out[0]``), :data:`NONE` (no crossing), :data:`AT_START` (on its wrong side: at once)
    or :data:`ON_SURFACE` (still exactly on its surface: undecided).
    """
    lo, g_lo, positive, negative = t_start, 0.0, False, False
    span = t_end - t_start
    for k in range(1, 33):
        t = t_start + span * (k / 32.0)
        g = _value(coeffs, hi0, lo0, sign, v0, t)
        if g > 0.0:
            lo, g_lo, positive = t, g, True
        elif positive:
            out[0] = _illinois(coeffs, hi0, lo0, sign, v0, lo, g_lo, t, g)
            return ROOT
        negative = negative or g < 0.0
    g_end = _value(coeffs, hi0, lo0, sign, v0, t_end)
    if positive or g_end > 0.0:
        return NONE
    if negative or g_end < 0.0:
        return AT_START
    return ON_SURFACE


_WARM: list[bool] = []


def warm_up() -> None:
    """Compile (or load from the disk cache) :func:`velocity_crossing` for heyoka's read-only ``tc`` rows."""
    if _WARM:
        return
    import numpy as np

    coeffs = np.array([1.0, -1.0])
    coeffs.flags.writeable = False
    velocity_crossing(coeffs, 0.0, 0.0, 0.0, 2.0, 1.0, 0.0, np.zeros(1))
    _WARM.append(True)
