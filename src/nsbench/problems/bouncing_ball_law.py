"""The law of the bouncing ball, compiled (:mod:`nsbench.problems.bouncing_ball`).

State ``[x, v]`` (height, velocity); parameters ``[g, e]`` (gravity, Newton's
restitution). Mode vector ``[FLIGHT]`` or ``[REST]``. In flight ``x' = v, v' =
-g`` with one guard, the contact ``x >= 0``; an impact resets ``x = 0, v =
-e v`` and the ball leaves the ground on its contact surface (``fresh``). At
rest ``x' = v' = 0`` and no guard. The impacts of a ball that keeps bouncing
accumulate at a finite time (Zeno); the limit behaviour the core applies there
(:func:`accumulation_limit`) is rest on the ground.
"""

from __future__ import annotations

from nsbench.model.compile import hot
from nsbench.problems.bouncing_ball_spec import CONTACT, EV_IMPACT, EV_REST, FLIGHT, G, REST, RESTITUTION


@hot
def rhs(p, mode, t, y, out):
    if mode[0] == FLIGHT:
        out[0] = y[1]
        out[1] = -p[G]
    else:
        out[0] = 0.0
        out[1] = 0.0


@hot
def jacobian(p, mode, t, y, out):
    out[0, 0] = 0.0
    out[0, 1] = 1.0 if mode[0] == FLIGHT else 0.0
    out[1, 0] = 0.0
    out[1, 1] = 0.0


@hot
def guard_value(p, mode, kind, index, t, y):
    return y[0]


@hot
def guard_rate(p, mode, kind, index, t, y, dy):
    return dy[0]


@hot
def guards_of(p, mode, gk, gi, gs):
    if mode[0] != FLIGHT:
        return 0
    gk[0], gi[0], gs[0] = CONTACT, 0, 1
    return 1


@hot
def transition(p, mode, kind, index, t, y, fresh):
    """An impact: ``x = 0``, ``v = -e v``; a ball that does not leave the ground (``e v = 0``) rests."""
    y[0] = 0.0
    y[1] = -p[RESTITUTION] * y[1]
    if y[1] > 0.0:
        fresh[0] = True
        return EV_IMPACT
    y[1] = 0.0
    mode[0] = REST
    fresh[0] = False
    return EV_REST


@hot
def initial_mode(p, t, y, mode):
    """In flight, unless the ball lies on the ground at rest."""
    mode[0] = REST if (y[0] == 0.0 and y[1] == 0.0) else FLIGHT


@hot
def start_fresh(p, mode, t, y, fresh):
    fresh[0] = mode[0] == FLIGHT and y[0] == 0.0 and y[1] > 0.0


@hot
def accumulation_limit(p, mode, kind, index, t, y):
    """Impacts accumulate: from the accumulation time on, the ball lies on the ground."""
    mode[0] = REST
    y[0] = 0.0
    y[1] = 0.0
    return EV_REST
