"""The law of the friction family (blocks on a belt, MODEL.md sections 1, 4 and 7), compiled: written once.

A chain of ``n`` blocks; block 1 tied to the ground, block ``i`` to block
``i - 1``; the harmonic force on the last block; friction with stiction against a
belt at speed ``v0`` (``v0 = 0``: fixed ground): Coulomb, or a slip force that
depends on the slip speed (:func:`slip_level`: weakening, Stribeck), with the
static limit ``fr`` in every law. The mode vector has
one phase per block: ``STICK`` (0), ``+1`` (slipping faster than the belt),
``-1``. Guards: ``VELOCITY`` (``v_i - v0``, in slip) and ``UPPER``/``LOWER``
(``R_i -+ fr_i``, in stick), listed block by block (the tie order: the lowest
block first). Event kinds: ``STICK``, ``SLIP``, ``REVERSE``.

These functions are the problem's law (:mod:`nsbench.model.law`); every other
form of the field is derived from them (the numpy form by calling them,
:class:`~nsbench.problems.oscillator.FrictionOscillator`) or checked against
them by a test (heyoka's expressions, the SUNDIALS formulations).
"""

from __future__ import annotations

import numpy as np

from nsbench.model.compile import hot, inline, small
from nsbench.problems.friction_spec import (  # noqa: F401 - the family's vocabulary, re-exported
    C,
    COULOMB,
    CV,
    DELTA,
    EV_REVERSE,
    EV_SLIP,
    EV_STICK,
    EVENT_KINDS,
    F_AMP,
    F_FREQ,
    FR,
    FK,
    FS,
    GUARD_KINDS,
    H,
    K,
    LAW,
    LAYOUT,
    LOWER,
    M,
    N_BLOCKS,
    SLIP_NEG,
    SLIP_POS,
    STICK,
    STRIBECK,
    UPPER,
    V0,
    VELOCITY,
    VS,
    WEAKENING,
)

_HEAD = LAYOUT.head_size
_NF = len(LAYOUT.fields)


# ---------------------------------------------------------------------- the layout, by name
@small
def n_blocks(p):
    return int(p[N_BLOCKS])


@small
def block(p, field, i):
    """Field ``field`` (``M``, ``C``, ...) of block ``i`` (0-based)."""
    return p[_HEAD + field * int(p[N_BLOCKS]) + i]


@small
def scalar(p, which):
    """Tail scalar ``which`` (``F_AMP``, ``F_FREQ``, ``V0``)."""
    return p[_HEAD + _NF * int(p[N_BLOCKS]) + which]


@small
def v0_of(p):
    return scalar(p, V0)


# ---------------------------------------------------------------------- forces
@inline
def link_tension(p, y, j):
    """Tension of spring link j (0: ground to block 1) and its stiffness d(tension)/d(extension)."""
    d = y[0] if j == 0 else y[2 * j] - y[2 * j - 2]
    k = block(p, K, j)
    h = block(p, H, j)
    if h != 0.0:
        return k * d + h * (d * d * d), k + 3.0 * h * d * d
    return k * d, k


@inline
def restoring(p, t, y, i):
    """R_i (0-based block i): every force on block i except friction."""
    nb = n_blocks(p)
    s_i, _ = link_tension(p, y, i)
    r = block(p, C, i) * y[2 * i + 1] + s_i
    if i + 1 < nb:
        s_next, _ = link_tension(p, y, i + 1)
        r -= s_next
    if i == nb - 1:
        F = scalar(p, F_AMP)
        if F != 0.0:
            r -= F * np.cos(scalar(p, F_FREQ) * t)
    return r


@inline
def restoring_rate(p, t, y, dy, i):
    """dR_i/dt along the direction dy, including the forcing's explicit time dependence."""
    nb = n_blocks(p)
    _, k_i = link_tension(p, y, i)
    out = block(p, C, i) * dy[2 * i + 1] + k_i * dy[2 * i]
    if i > 0:
        out -= k_i * dy[2 * i - 2]
    if i + 1 < nb:
        _, k_next = link_tension(p, y, i + 1)
        out += k_next * (dy[2 * i] - dy[2 * i + 2])
    if i == nb - 1:
        F = scalar(p, F_AMP)
        if F != 0.0:
            w = scalar(p, F_FREQ)
            out += F * w * np.sin(w * t)
    return out


# ---------------------------------------------------------------------- the friction law of a slip
@small
def law_of(p):
    """The friction law's code (``COULOMB``, ``WEAKENING``, ``STRIBECK``)."""
    return int(scalar(p, LAW))


@small
def slip_level(p, i, u):
    """Magnitude of block i's slip friction at slip speed ``u = s (v - v0)`` (``|v - v0|`` in the phase).

    ``fs`` (Coulomb); ``fs / (1 + delta u)`` (weakening); ``fk + (fs - fk) exp(-(u / vs)^2) + cv u``
    (Stribeck). Written on ``u`` rather than ``|v - v0|`` so that each slip phase's field is smooth.
    """
    law = law_of(p)
    fs = block(p, FS, i)
    if law == COULOMB:
        return fs
    if law == WEAKENING:
        return fs / (1.0 + block(p, DELTA, i) * u)
    fk = block(p, FK, i)
    q = u / block(p, VS, i)
    return fk + (fs - fk) * np.exp(-q * q) + block(p, CV, i) * u


@small
def slip_slope(p, i, u):
    """``d slip_level / du`` (0 for Coulomb)."""
    law = law_of(p)
    if law == COULOMB:
        return 0.0
    if law == WEAKENING:
        delta = block(p, DELTA, i)
        den = 1.0 + delta * u
        return -block(p, FS, i) * delta / (den * den)
    vs = block(p, VS, i)
    q = u / vs
    return -2.0 * (block(p, FS, i) - block(p, FK, i)) * q / vs * np.exp(-q * q) + block(p, CV, i)


@small
def slip_force(p, i, phase, v):
    """Friction force on slipping block i (phase ``s = +-1``): ``-s slip_level(s (v - v0))``."""
    return -slip_level(p, i, phase * (v - v0_of(p))) * phase


# ---------------------------------------------------------------------- the law
@inline
def rhs(p, mode, t, y, out):
    """Frozen-mode vector field into ``out``."""
    nb = n_blocks(p)
    v0 = v0_of(p)
    for i in range(nb):
        phase = mode[i]
        if phase == STICK:
            out[2 * i] = v0
            out[2 * i + 1] = 0.0
        else:
            r = restoring(p, t, y, i)
            out[2 * i] = y[2 * i + 1]
            out[2 * i + 1] = (-r - slip_level(p, i, phase * (y[2 * i + 1] - v0)) * phase) / block(p, M, i)


@hot
def jacobian(p, mode, t, y, out):
    """Frozen-mode Jacobian into ``out`` (n x n)."""
    nb = n_blocks(p)
    n = 2 * nb
    for a in range(n):
        for b in range(n):
            out[a, b] = 0.0
    for i in range(nb):
        if mode[i] == STICK:
            continue
        m = block(p, M, i)
        _, k_i = link_tension(p, y, i)
        diag = k_i
        if i > 0:
            out[2 * i + 1, 2 * i - 2] = k_i / m
        if i + 1 < nb:
            _, k_next = link_tension(p, y, i + 1)
            diag += k_next
            out[2 * i + 1, 2 * i + 2] = k_next / m
        out[2 * i, 2 * i + 1] = 1.0
        out[2 * i + 1, 2 * i] = -diag / m
        out[2 * i + 1, 2 * i + 1] = -block(p, C, i) / m
        if law_of(p) != COULOMB:  # d(-s level(s (v - v0)))/dv = -level'
            out[2 * i + 1, 2 * i + 1] -= slip_slope(p, i, mode[i] * (y[2 * i + 1] - v0_of(p))) / m


@inline
def guard_value(p, mode, kind, i, t, y):
    """Guard value: v_i - v0 (VELOCITY), R_i - fr_i (UPPER) or R_i + fr_i (LOWER)."""
    if kind == VELOCITY:
        return y[2 * i + 1] - v0_of(p)
    fr = block(p, FR, i)
    r = restoring(p, t, y, i)
    return r - fr if kind == UPPER else r + fr


@inline
def guard_rate(p, mode, kind, i, t, y, dy):
    """Time derivative of a guard along ``dy``."""
    if kind == VELOCITY:
        return dy[2 * i + 1]
    return restoring_rate(p, t, y, dy, i)


@hot
def guards_of(p, mode, gk, gi, gs):
    """The guards of ``mode`` (kinds, 0-based blocks, expected signs), block by block; their number."""
    ng = 0
    for b in range(mode.shape[0]):
        if mode[b] == STICK:
            gk[ng], gi[ng], gs[ng] = UPPER, b, -1
            ng += 1
            gk[ng], gi[ng], gs[ng] = LOWER, b, 1
            ng += 1
        else:
            gk[ng], gi[ng], gs[ng] = VELOCITY, b, mode[b]
            ng += 1
    return ng


@hot
def transition(p, mode, kind, i, t, y, fresh):
    """Apply the transition of guard ``(kind, i)`` to ``mode`` and ``y`` in place; return the event kind.

    Slip guard: ``v = v0`` exactly, then stick if ``|R| <= fr``, else reverse with
    ``s = -sign(R)``. Stick guard: slip with ``s = -sign(R)`` (-1 at the upper limit,
    +1 at the lower one); ``v = v0`` only removes rounding. A block that slips
    after the event starts on its own velocity surface, in the direction the
    forces chose: ``fresh``.
    """
    y[2 * i + 1] = v0_of(p)
    if kind == VELOCITY:
        r = restoring(p, t, y, i)
        if abs(r) <= block(p, FR, i):
            mode[i] = STICK
            code = EV_STICK
        else:
            mode[i] = SLIP_NEG if r > 0 else SLIP_POS
            code = EV_REVERSE
    else:
        mode[i] = SLIP_NEG if kind == UPPER else SLIP_POS
        code = EV_SLIP
    fresh[i] = mode[i] != STICK
    return code


@hot
def initial_mode(p, t, y, mode):
    """The mode of a state into ``mode``: slip with ``sign(v - v0)``, or stick if friction holds."""
    nb = n_blocks(p)
    v0 = v0_of(p)
    for i in range(nb):
        v = y[2 * i + 1]
        if v != v0:
            mode[i] = SLIP_POS if v > v0 else SLIP_NEG
        else:
            r = restoring(p, t, y, i)
            if abs(r) <= block(p, FR, i):
                mode[i] = STICK
            else:
                mode[i] = SLIP_NEG if r > 0 else SLIP_POS


@hot
def start_fresh(p, mode, t, y, fresh):
    """At the start of a run, a slipping block exactly at the belt speed is fresh."""
    v0 = v0_of(p)
    for i in range(mode.shape[0]):
        fresh[i] = mode[i] != STICK and y[2 * i + 1] == v0
