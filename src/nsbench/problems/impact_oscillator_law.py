"""The law of the impact oscillator, compiled (:mod:`nsbench.problems.impact_oscillator`).

State ``[x, v]``; parameters ``[zeta, F, w, sigma, r]``. Mode vector ``[FREE]``
or ``[STUCK]``. Free: ``x' = v``, ``v' = -x - 2 zeta v + F cos(w t)``, with one
guard, the gap ``sigma - x >= 0``. An impact resets ``x = sigma``,
``v -> -r v``; a mass that arrives with no speed (or with ``r = 0``) and is
pressed on the stop by the force sticks there. Stuck: ``x' = v' = 0`` with one
guard, the pressing force ``-sigma + F cos(w t)`` (the free acceleration at the
stop), ``>= 0``; when it turns the mass is released. A chattering sequence of
impacts accumulates at a finite time (Zeno); the limit the core applies there
(:func:`accumulation_limit`) is the mass stuck on the stop.
"""

from __future__ import annotations

import math

from nsbench.model.compile import hot
from nsbench.problems.impact_oscillator_spec import (
    AMP,
    EV_IMPACT,
    EV_RELEASE,
    EV_STICK,
    FREE,
    FREQ,
    GAP,
    PRESS,
    RESTITUTION,
    STOP,
    STUCK,
    ZETA,
)


@hot
def _accel(p, t, x, v):
    return -x - 2.0 * p[ZETA] * v + p[AMP] * math.cos(p[FREQ] * t)


@hot
def rhs(p, mode, t, y, out):
    if mode[0] == FREE:
        out[0] = y[1]
        out[1] = _accel(p, t, y[0], y[1])
    else:
        out[0] = 0.0
        out[1] = 0.0


@hot
def jacobian(p, mode, t, y, out):
    free = mode[0] == FREE
    out[0, 0] = 0.0
    out[0, 1] = 1.0 if free else 0.0
    out[1, 0] = -1.0 if free else 0.0
    out[1, 1] = -2.0 * p[ZETA] if free else 0.0


@hot
def guard_value(p, mode, kind, index, t, y):
    if kind == GAP:
        return p[STOP] - y[0]
    return _accel(p, t, y[0], y[1])


@hot
def guard_rate(p, mode, kind, index, t, y, dy):
    if kind == GAP:
        return -dy[0]
    return -dy[0] - 2.0 * p[ZETA] * dy[1] - p[AMP] * p[FREQ] * math.sin(p[FREQ] * t)


@hot
def guards_of(p, mode, gk, gi, gs):
    gk[0], gi[0], gs[0] = (GAP if mode[0] == FREE else PRESS), 0, 1
    return 1


@hot
def transition(p, mode, kind, index, t, y, fresh):
    """An impact (``x = sigma``, ``v -> -r v``; a mass left without speed and pressed on the stop sticks),
    or a release from the stop."""
    y[0] = p[STOP]
    if kind == PRESS:
        y[1] = 0.0
        mode[0] = FREE
        fresh[0] = True
        return EV_RELEASE
    y[1] = -p[RESTITUTION] * y[1]
    if y[1] == 0.0:
        y[1] = 0.0  # no -0.0
        if _accel(p, t, y[0], 0.0) > 0.0:
            mode[0] = STUCK
            fresh[0] = True
            return EV_STICK
    fresh[0] = True
    return EV_IMPACT


@hot
def initial_mode(p, t, y, mode):
    """Stuck if the mass rests on the stop pressed by the force; free otherwise."""
    stuck = y[0] == p[STOP] and y[1] == 0.0 and _accel(p, t, y[0], 0.0) > 0.0
    mode[0] = STUCK if stuck else FREE


@hot
def start_fresh(p, mode, t, y, fresh):
    fresh[0] = mode[0] == FREE and y[0] == p[STOP] and y[1] <= 0.0


@hot
def accumulation_limit(p, mode, kind, index, t, y):
    """Impacts accumulate (chattering): from the accumulation time on, the mass is stuck on the stop."""
    if kind != GAP or _accel(p, t, p[STOP], 0.0) <= 0.0:
        return -1  # not a mass pressed on the stop: no sticking limit to apply
    mode[0] = STUCK
    y[0] = p[STOP]
    y[1] = 0.0
    return EV_STICK
