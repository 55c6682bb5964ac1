"""Compiled transition rules of MODEL.md section 1, for the hybrid loop of the fast path.

These mirror :mod:`nsbench.engine` and :meth:`FrictionOscillator.transition`
line for line: the guards of a mode (per block; stick: upper then lower,
slip: velocity), the transition map, the initial mode of a state, and the
"guard already on its wrong side fires at once" test with the engine's
tolerance. Modes are int64 phase arrays; guards are (kind, block, sign).
"""

from __future__ import annotations

import numpy as np

from nsbench.problems.kernels import guard_rate, guard_value, jit, restoring, rhs

_EPS = np.finfo(np.float64).eps
VELOCITY, UPPER, LOWER = 0, 1, 2
KIND_STICK, KIND_SLIP, KIND_REVERSE = 0, 1, 2


@jit
def mode_index(mode):
    """Index of ``mode`` in ``problem.modes`` (block 1 varies slowest)."""
    idx = 0
    for b in range(mode.shape[0]):
        idx = idx * 3 + (mode[b] + 1)
    return idx


@jit
def guards_of(mode, gk, gb, gs):
    """Fill the guards of ``mode`` (kinds, 0-based blocks, expected signs); return their number."""
    ng = 0
    for b in range(mode.shape[0]):
        if mode[b] == 0:
            gk[ng], gb[ng], gs[ng] = UPPER, b, -1
            ng += 1
            gk[ng], gb[ng], gs[ng] = LOWER, b, 1
            ng += 1
        else:
            gk[ng], gb[ng], gs[ng] = VELOCITY, b, mode[b]
            ng += 1
    return ng


@jit
def initial_mode(p, t, y, mode):
    """The mode of a state (slip with sign(v - v0), or stick if friction holds) into ``mode``."""
    nb = int(p[0])
    v0 = p[3 + 6 * nb]
    for i in range(nb):
        v = y[2 * i + 1]
        if v != v0:
            mode[i] = 1 if v > v0 else -1
        else:
            r = restoring(p, t, y, i)
            if abs(r) <= p[1 + 5 * nb + i]:
                mode[i] = 0
            else:
                mode[i] = -1 if r > 0 else 1


@jit
def transition(p, mode, kind, block, t, y):
    """Apply the transition of guard ``(kind, block)`` in place; return the event kind code."""
    nb = int(p[0])
    v0 = p[3 + 6 * nb]
    y[2 * block + 1] = v0
    if kind == VELOCITY:
        r = restoring(p, t, y, block)
        if abs(r) <= p[1 + 5 * nb + block]:
            mode[block] = 0
            return KIND_STICK
        mode[block] = -1 if r > 0 else 1
        return KIND_REVERSE
    mode[block] = -1 if kind == UPPER else 1
    return KIND_SLIP


@jit
def wrong_side(p, kind, block, sign, t, y, dy):
    """Whether a guard is already past its surface, or on it and heading the wrong way."""
    g = guard_value(p, kind, block, t, y)
    phi = sign * g
    ymax = 0.0
    for j in range(y.shape[0]):
        ymax = max(ymax, abs(y[j]))
    tol = 64.0 * _EPS * max(1.0, abs(g), ymax)
    if phi < -tol:
        return True
    if abs(phi) <= tol:
        return sign * guard_rate(p, kind, block, t, y, dy) < 0.0
    return False


@jit
def pending_guard(p, mode, t, y, fresh, gk, gb, gs, dy):
    """Index (into the guards of ``mode``) of the first guard that must fire at once, or -1.

    ``fresh`` is a bit mask of blocks that just started a slip phase whose
    velocity guard is zero by construction and is not re-tested.
    """
    ng = guards_of(mode, gk, gb, gs)
    have_dy = False
    for q in range(ng):
        if gk[q] == VELOCITY and (fresh >> gb[q]) & 1:
            continue
        if not have_dy:
            rhs(p, mode, t, y, dy)
            have_dy = True
        if wrong_side(p, gk[q], gb[q], gs[q], t, y, dy):
            return q
    return -1
