"""The law of Casella's sliding test, compiled (:mod:`nsbench.problems.casella_sliding`).

State ``[x, y]``; parameters ``[a1, a2, b1, b2, weight]``. Off the surface the
field is constant: ``(a1, b2)`` where ``x > y`` (mode ``ABOVE``), ``(a2, b1)``
where ``x < y`` (``BELOW``); the guard is ``s = x - y``, positive in ``ABOVE``,
negative in ``BELOW``. On ``s = 0`` the trajectory crosses if the far side's
field carries it on, and slides otherwise: Filippov's field there is
``lambda f_above + (1 - lambda) f_below`` with ``lambda = s'_below / (s'_below -
s'_above)`` (``weight``, fixed by the parameters), which keeps ``s' = 0``. A
sliding region ends where a side's weight reaches 0; with constant fields the
weights are constants, so a trajectory that slides slides for ever and the
sliding mode has no guard.
"""

from __future__ import annotations

from nsbench.model.compile import hot
from nsbench.problems.casella_sliding_spec import (
    A1,
    A2,
    ABOVE,
    B1,
    B2,
    BELOW,
    EV_CROSS,
    EV_SLIDE,
    SLIDE,
    SWITCH,
    WEIGHT,
)


@hot
def _rate_above(p):
    """``s' = (x - y)'`` on the side ``x > y``."""
    return p[A1] - p[B2]


@hot
def _rate_below(p):
    """``s'`` on the side ``x < y``."""
    return p[A2] - p[B1]


@hot
def rhs(p, mode, t, y, out):
    if mode[0] == ABOVE:
        out[0], out[1] = p[A1], p[B2]
    elif mode[0] == BELOW:
        out[0], out[1] = p[A2], p[B1]
    else:
        lam = p[WEIGHT]
        out[0] = lam * p[A1] + (1.0 - lam) * p[A2]
        out[1] = lam * p[B2] + (1.0 - lam) * p[B1]


@hot
def jacobian(p, mode, t, y, out):
    for i in range(2):
        for j in range(2):
            out[i, j] = 0.0


@hot
def guard_value(p, mode, kind, index, t, y):
    return y[0] - y[1]


@hot
def guard_rate(p, mode, kind, index, t, y, dy):
    return dy[0] - dy[1]


@hot
def guards_of(p, mode, gk, gi, gs):
    if mode[0] == SLIDE:  # both weights are constant and positive: the sliding never ends, no guard
        return 0
    gk[0], gi[0], gs[0] = SWITCH, 0, (1 if mode[0] == ABOVE else -1)
    return 1


@hot
def _on_surface(p, mode):
    """The mode on ``x = y``: across if the far side's field carries on, sliding if both fields point at it."""
    above, below = _rate_above(p), _rate_below(p)
    if above > 0.0 and below > 0.0:
        mode[0] = ABOVE
    elif above < 0.0 and below < 0.0:
        mode[0] = BELOW
    else:
        mode[0] = SLIDE


@hot
def transition(p, mode, kind, index, t, y, fresh):
    """The surface reached: cross if the far side's field carries on, slide if both fields point at it."""
    fresh[0] = True
    _on_surface(p, mode)
    return EV_SLIDE if mode[0] == SLIDE else EV_CROSS


@hot
def initial_mode(p, t, y, mode):
    s = y[0] - y[1]
    if s > 0.0:
        mode[0] = ABOVE
    elif s < 0.0:
        mode[0] = BELOW
    else:
        _on_surface(p, mode)


@hot
def start_fresh(p, mode, t, y, fresh):
    fresh[0] = y[0] == y[1]


@hot
def accumulation_limit(p, mode, kind, index, t, y):
    return -1
