"""The law of the oscillator with a circular switching surface, compiled (:mod:`nsbench.problems.circle_oscillator`).

State ``[x1, x2]``; parameters ``[omega, radius]``. Inside the circle
``x1^2 + x2^2 < R^2`` the field is ``A_in x`` with ``A_in = [[1, -omega], [omega,
1]]`` (a spiral outwards, counter-clockwise), outside it ``A_out x`` with ``A_out =
[[1, omega], [-omega, 1]]`` (outwards, clockwise). The guard is ``c = x1^2 + x2^2 -
R^2``, negative inside and positive outside. Both fields have ``x . A x = |x|^2 >
0``, so every trajectory that reaches the circle crosses it outwards; the
transition changes the side, never the state.
"""

from __future__ import annotations

from nsbench.model.compile import hot
from nsbench.problems.circle_oscillator_spec import CIRCLE, EV_CROSS, INSIDE, OMEGA, OUTSIDE, RADIUS


@hot
def _turn(p, mode):
    """The signed rotation rate: ``+omega`` inside (counter-clockwise), ``-omega`` outside."""
    return p[OMEGA] if mode[0] == INSIDE else -p[OMEGA]


@hot
def rhs(p, mode, t, y, out):
    w = _turn(p, mode)
    out[0] = y[0] - w * y[1]
    out[1] = w * y[0] + y[1]


@hot
def jacobian(p, mode, t, y, out):
    w = _turn(p, mode)
    out[0, 0], out[0, 1] = 1.0, -w
    out[1, 0], out[1, 1] = w, 1.0


@hot
def guard_value(p, mode, kind, index, t, y):
    return y[0] * y[0] + y[1] * y[1] - p[RADIUS] * p[RADIUS]


@hot
def guard_rate(p, mode, kind, index, t, y, dy):
    return 2.0 * (y[0] * dy[0] + y[1] * dy[1])


@hot
def guards_of(p, mode, gk, gi, gs):
    gk[0], gi[0], gs[0] = CIRCLE, 0, (-1 if mode[0] == INSIDE else 1)
    return 1


@hot
def transition(p, mode, kind, index, t, y, fresh):
    """The circle reached: the other side's field, the same state (both fields carry the trajectory on outwards)."""
    fresh[0] = True
    mode[0] = OUTSIDE if mode[0] == INSIDE else INSIDE
    return EV_CROSS


@hot
def initial_mode(p, t, y, mode):
    """Inside if ``|x| < R``; on the circle or beyond, outside (where both fields carry the state)."""
    mode[0] = INSIDE if y[0] * y[0] + y[1] * y[1] < p[RADIUS] * p[RADIUS] else OUTSIDE


@hot
def start_fresh(p, mode, t, y, fresh):
    fresh[0] = y[0] * y[0] + y[1] * y[1] == p[RADIUS] * p[RADIUS]


@hot
def accumulation_limit(p, mode, kind, index, t, y):
    return -1
