"""The law of the relay feedback system, compiled (:mod:`nsbench.problems.relay_feedback`).

State ``x`` (3); parameters the plant's ``A``, ``B``, ``C`` (row-major, with
``C B > 0``). Modes: ``UP`` (``u = +1``, guard ``C x`` kept negative), ``DOWN``
(``u = -1``, ``C x`` kept positive), ``SLIDE`` (Filippov sliding on ``C x = 0``
with Utkin's equivalent control ``u_eq = -C A x / C B``, guards ``1 - u_eq`` and
``1 + u_eq`` kept positive). Reaching the surface, the trajectory crosses if the
field on the far side carries it on, and slides otherwise; a sliding trajectory
exits to the side whose field turns away when ``|u_eq|`` reaches 1. A
trajectory that touches the surface tangentially from a side whose field turns
back stays on that side (``touch``).
"""

from __future__ import annotations

from nsbench.model.compile import hot
from nsbench.problems.relay_feedback_spec import (
    A0,
    B0,
    C0,
    DOWN,
    EV_CROSS,
    EV_EXIT,
    EV_SLIDE,
    EV_TOUCH,
    LIMIT_DOWN,
    LIMIT_UP,
    SLIDE,
    SWITCH,
    UP,
)


@hot
def _cx(p, y):
    return p[C0] * y[0] + p[C0 + 1] * y[1] + p[C0 + 2] * y[2]


@hot
def _cb(p):
    return p[C0] * p[B0] + p[C0 + 1] * p[B0 + 1] + p[C0 + 2] * p[B0 + 2]


@hot
def _cax(p, y):
    """``C A x``."""
    s = 0.0
    for i in range(3):
        row = 0.0
        for j in range(3):
            row += p[A0 + 3 * i + j] * y[j]
        s += p[C0 + i] * row
    return s


@hot
def _control(p, mode, y):
    if mode[0] == UP:
        return 1.0
    if mode[0] == DOWN:
        return -1.0
    return -_cax(p, y) / _cb(p)


@hot
def rhs(p, mode, t, y, out):
    u = _control(p, mode, y)
    for i in range(3):
        s = p[B0 + i] * u
        for j in range(3):
            s += p[A0 + 3 * i + j] * y[j]
        out[i] = s


@hot
def jacobian(p, mode, t, y, out):
    cb = _cb(p)
    for i in range(3):
        for j in range(3):
            out[i, j] = p[A0 + 3 * i + j]
    if mode[0] == SLIDE:  # A - B (C A) / (C B)
        for j in range(3):
            ca = p[C0] * p[A0 + j] + p[C0 + 1] * p[A0 + 3 + j] + p[C0 + 2] * p[A0 + 6 + j]
            for i in range(3):
                out[i, j] -= p[B0 + i] * ca / cb


@hot
def guard_value(p, mode, kind, index, t, y):
    if kind == SWITCH:
        return _cx(p, y)
    ratio = _cax(p, y) / _cb(p)  # -u_eq
    return 1.0 + ratio if kind == LIMIT_UP else 1.0 - ratio


@hot
def guard_rate(p, mode, kind, index, t, y, dy):
    if kind == SWITCH:
        return _cx(p, dy)
    ratio = _cax(p, dy) / _cb(p)
    return ratio if kind == LIMIT_UP else -ratio


@hot
def guards_of(p, mode, gk, gi, gs):
    if mode[0] == SLIDE:
        gk[0], gi[0], gs[0] = LIMIT_UP, 0, 1
        gk[1], gi[1], gs[1] = LIMIT_DOWN, 0, 1
        return 2
    gk[0], gi[0], gs[0] = SWITCH, 0, (-1 if mode[0] == UP else 1)
    return 1


@hot
def _on_surface(p, y, mode):
    """The mode on ``C x = 0``: across if the far side's field carries on, sliding otherwise."""
    cax, cb = _cax(p, y), _cb(p)
    if cax - cb > 0.0:  # C(Ax - B) > 0: the field of u = -1 leaves into C x > 0
        mode[0] = DOWN
    elif cax + cb < 0.0:  # C(Ax + B) < 0: the field of u = +1 leaves into C x < 0
        mode[0] = UP
    else:
        mode[0] = SLIDE


@hot
def transition(p, mode, kind, index, t, y, fresh):
    """The surface reached (cross or slide), or a sliding limit reached (exit to the side that turns away)."""
    fresh[0] = True
    if kind == SWITCH:
        before = mode[0]
        _on_surface(p, y, mode)
        if mode[0] == SLIDE:
            return EV_SLIDE
        if mode[0] == before:  # a tangential touch: the trajectory stays on its side
            return EV_TOUCH
        return EV_CROSS
    mode[0] = UP if kind == LIMIT_UP else DOWN
    return EV_EXIT


@hot
def initial_mode(p, t, y, mode):
    cx = _cx(p, y)
    if cx < 0.0:
        mode[0] = UP
    elif cx > 0.0:
        mode[0] = DOWN
    else:
        _on_surface(p, y, mode)


@hot
def start_fresh(p, mode, t, y, fresh):
    fresh[0] = _cx(p, y) == 0.0


@hot
def accumulation_limit(p, mode, kind, index, t, y):
    return -1
