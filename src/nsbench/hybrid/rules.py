"""The hybrid rules of MODEL.md section 1, compiled: the one definition every part of nsbench calls.

A mode is an int64 array with one phase per block: 0 stick, +1 slip+ (faster
than the belt), -1 slip-. A guard is ``(kind, block, expected sign)`` with kind
:data:`VELOCITY` (``v_i - v0``, a slip phase), :data:`UPPER` (``R_i - fr_i``) or
:data:`LOWER` (``R_i + fr_i``, both during stick) and a 0-based block; the mode
holds while ``sign * guard > 0``. Guards are listed block by block (stick:
upper then lower), which is also the tie order: an exact tie goes to the
lowest block (MODEL.md).

The settle step applies the transition of the guard that fired, records the
event, and fires at once any guard of the new mode that is already on its
wrong side (degenerate points only), until none is left; it stops a run on an
event storm (more than ``zeno_events`` consecutive events within a short span)
or on the event budget. The Python engine, the compiled loop, the problem's
Python interface and the energy check all call these functions.
"""

from __future__ import annotations

import numpy as np

from nsbench.hybrid.abi import hot, inline
from nsbench.problems.kernels import guard_rate, guard_value, restoring, rhs

VELOCITY, UPPER, LOWER = 0, 1, 2
#: Event kinds, in the order of :data:`nsbench.problems.modes.EVENT_KINDS`.
EV_STICK, EV_SLIP, EV_REVERSE = 0, 1, 2
#: Outcomes of :func:`settle`.
SETTLED, STORM, EVENT_BUDGET = 0, 1, 2
_EPS = np.finfo(np.float64).eps

# Slots of the integer state ``si`` that settle updates (the loop owns the rest).
SI_EVENTS = 0      # events applied in the whole run
SI_RECORDED = 1    # events stored in the event buffers
SI_RING = 2        # events pushed into the storm ring
SI_STOP_SEEN = 3   # events of the stop kind at t >= record_from
N_SETTLE_SLOTS = 4


@inline
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


@hot
def initial_mode(p, t, y, mode):
    """The mode of a state into ``mode``: slip with ``sign(v - v0)``, or stick if friction holds."""
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


@inline
def transition(p, mode, kind, block, t, y):
    """Apply the transition of guard ``(kind, block)`` to ``mode`` and ``y`` in place; return the event kind.

    Slip guard: ``v = v0`` exactly, then stick if ``|R| <= fr``, else reverse with
    ``s = -sign(R)``. Stick guard: slip with ``s = -sign(R)`` (-1 at the upper limit,
    +1 at the lower one); ``v = v0`` only removes rounding.
    """
    nb = int(p[0])
    y[2 * block + 1] = p[3 + 6 * nb]
    if kind == VELOCITY:
        r = restoring(p, t, y, block)
        if abs(r) <= p[1 + 5 * nb + block]:
            mode[block] = 0
            return EV_STICK
        mode[block] = -1 if r > 0 else 1
        return EV_REVERSE
    mode[block] = -1 if kind == UPPER else 1
    return EV_SLIP


@inline
def wrong_side(p, kind, block, sign, t, y, dy):
    """Whether a guard is already past its surface, or on it (within rounding) and heading the wrong way."""
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


@hot
def pending_guard(p, mode, t, y, fresh, gk, gb, gs, dy):
    """Index (into the guards of ``mode``) of the first guard that must fire at once, or -1.

    ``fresh[i]`` marks a block that just started a slip phase whose direction the
    transition rule chose from the forces: its velocity guard is zero by
    construction and is not re-tested.
    """
    ng = guards_of(mode, gk, gb, gs)
    have_dy = False
    for q in range(ng):
        if gk[q] == VELOCITY and fresh[gb[q]]:
            continue
        if not have_dy:
            rhs(p, mode, t, y, dy)
            have_dy = True
        if wrong_side(p, gk[q], gb[q], gs[q], t, y, dy):
            return q
    return -1


@inline
def start_fresh(p, mode, y, fresh):
    """The rule at the start of a run: a slipping block exactly at the belt speed is fresh."""
    nb = int(p[0])
    v0 = p[3 + 6 * nb]
    for i in range(nb):
        fresh[i] = mode[i] != 0 and y[2 * i + 1] == v0


@hot
def settle(p, mode, t, y, q, fresh, gk, gb, gs, dy, ring, zeno_span, max_events, record_from,
           stop_kind, ev_t, ev_kind, ev_block, ev_y, ev_mode, si):
    """Apply guard ``q`` of ``mode`` (an index into its guards) and every guard that must follow at ``t``.

    ``mode``, ``y`` and ``fresh`` are updated in place; the guards of the final mode
    are left in ``gk, gb, gs``. Events at ``t >= record_from`` are appended to the
    event buffers (the caller guarantees room for ``ring.size + 1`` of them); ``si``
    counts them (:data:`SI_EVENTS`, ...). ``ring`` holds the times of the last
    ``ring.size`` events: ``ring.size`` events within ``zeno_span`` are a storm.
    Returns :data:`SETTLED`, :data:`STORM` or :data:`EVENT_BUDGET`.
    """
    nring = ring.shape[0]
    while q >= 0:
        kind, block = gk[q], gb[q]
        ev = transition(p, mode, kind, block, t, y)
        si[SI_EVENTS] += 1
        if t >= record_from:
            k = si[SI_RECORDED]
            ev_t[k] = t
            ev_kind[k] = ev
            ev_block[k] = block + 1
            for i in range(y.shape[0]):
                ev_y[k, i] = y[i]
            for i in range(mode.shape[0]):
                ev_mode[k, i] = mode[i]
            si[SI_RECORDED] = k + 1
            if ev == stop_kind:
                si[SI_STOP_SEEN] += 1
        # the oldest of the last nring events, then this one in its place
        oldest = ring[si[SI_RING] % nring]
        full = si[SI_RING] >= nring
        ring[si[SI_RING] % nring] = t
        si[SI_RING] += 1
        if si[SI_EVENTS] >= max_events:
            return EVENT_BUDGET
        if full and t - oldest <= zeno_span:
            return STORM
        fresh[block] = mode[block] != 0
        q = pending_guard(p, mode, t, y, fresh, gk, gb, gs, dy)
    return SETTLED
