"""The law of the Henon-Heiles problem, compiled (:mod:`nsbench.problems.henon_heiles`).

State ``[x, y, px, py]``; parameter ``[coupling]`` (``a``). One smooth field,
``x' = px, y' = py, px' = -x - 2 a x y, py' = -y - a (x^2 - y^2)``; the mode only
records which side of the plane ``x = 0`` the orbit is on, so that each crossing
of the plane is an event: ``section`` going to ``x > 0`` (``px > 0``, a point of
the Poincare section), ``return`` going back. A transition changes nothing in the
state.
"""

from __future__ import annotations

from nsbench.model.compile import hot
from nsbench.problems.henon_heiles_spec import COUPLING, EV_RETURN, EV_SECTION, LEFT, PLANE, RIGHT


@hot
def rhs(p, mode, t, y, out):
    a = p[COUPLING]
    out[0] = y[2]
    out[1] = y[3]
    out[2] = -y[0] - 2.0 * a * y[0] * y[1]
    out[3] = -y[1] - a * (y[0] * y[0] - y[1] * y[1])


@hot
def jacobian(p, mode, t, y, out):
    a = p[COUPLING]
    for i in range(4):
        for j in range(4):
            out[i, j] = 0.0
    out[0, 2] = 1.0
    out[1, 3] = 1.0
    out[2, 0] = -1.0 - 2.0 * a * y[1]
    out[2, 1] = -2.0 * a * y[0]
    out[3, 0] = -2.0 * a * y[0]
    out[3, 1] = -1.0 + 2.0 * a * y[1]


@hot
def guard_value(p, mode, kind, index, t, y):
    return y[0]


@hot
def guard_rate(p, mode, kind, index, t, y, dy):
    return dy[0]


@hot
def guards_of(p, mode, gk, gi, gs):
    gk[0], gi[0], gs[0] = PLANE, 0, (-1 if mode[0] == LEFT else 1)
    return 1


@hot
def transition(p, mode, kind, index, t, y, fresh):
    """A crossing of ``x = 0``: the side changes, the state does not."""
    fresh[0] = True
    if mode[0] == LEFT:
        mode[0] = RIGHT
        return EV_SECTION
    mode[0] = LEFT
    return EV_RETURN


@hot
def initial_mode(p, t, y, mode):
    """The side of ``x = 0``; on the plane, the side ``px`` points to."""
    if y[0] < 0.0 or (y[0] == 0.0 and y[2] < 0.0):
        mode[0] = LEFT
    else:
        mode[0] = RIGHT


@hot
def start_fresh(p, mode, t, y, fresh):
    fresh[0] = y[0] == 0.0


@hot
def accumulation_limit(p, mode, kind, index, t, y):
    return -1
