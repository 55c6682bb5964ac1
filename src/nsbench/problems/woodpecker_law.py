"""The law of the woodpecker toy, compiled (:mod:`nsbench.problems.woodpecker`).

State ``[y, phiM, phiS, y', phiM', phiS']``; the parameter vector holds, per mode,
the accelerations and the normal force as affine maps of ``q = (y, phiM, phiS)``,
the contacts' directions, the tilt and beak limits, and the impulse matrices, all computed in
Python from the mechanical model (:mod:`nsbench.problems.woodpecker_spec` names
the slots). Modes: the sleeve free, or in contact ``j`` (1: tilted at ``phiM =
-theta``, 2: at ``+theta``) sliding up, sliding down or stuck.

Guards: while free, the three gaps (beak, both sleeve diagonals); in contact ``j``,
the beak's gap, the normal force (the contact opens where it falls to 0), and
either the slip velocity ``gamma_T`` (sliding; its sign is the mode's) or the
friction limits (stuck). A force or a friction limit is written as the
acceleration it is a positive multiple of (:mod:`nsbench.problems.woodpecker_spec`
says which), so that the mode that begins where it vanishes starts exactly at
rest relative to its own guard. Transitions:

- a gap closes: an impact, Newton's law with restitution ``e`` in the normal
  direction and Coulomb's law on the impulses (no tangential restitution), solved
  over the contacts involved (the one that closes and, for a peck while the
  sleeve is in contact, the sleeve's) by trying each contact's status (closed and
  stuck, closed and sliding either way, open) in that order and taking the first
  consistent one; then the sleeve's contact mode (below);
- the normal force reaches 0: ``release`` (free);
- the slip velocity reaches 0: ``stick`` if friction can hold the sleeve, else
  ``reverse``;
- a friction limit is reached: ``slip`` in the direction the force pushes.

The contact mode of a closed sleeve contact (after an impact or a stop) is the
consistent one at acceleration level: free if the free motion opens the gap,
else sliding with the slip velocity's sign, else stuck if the stuck forces lie
in the friction cone, else sliding where the tangential force pushes.
"""

from __future__ import annotations

import numpy as np

from nsbench.model.compile import hot
from nsbench.problems.woodpecker_spec import (
    ACC0,
    CLOSED_POS,
    CLOSED_STICK,
    IMP1,
    IMP1_SIZE,
    IMP2,
    IMP2_SIZE,
    N_IMPACT_STATUS,
    N_PAIR_COMBOS,
    NORMAL,
    NORMAL_STUCK,
    OPEN,
    ACC_ROW,
    ACC_SIZE,
    BEAK,
    BEAK_ANGLE,
    DEL0,
    E0,
    EV_IMPACT,
    EV_PECK,
    EV_RELEASE,
    EV_REVERSE,
    EV_SLIP,
    EV_STICK,
    FORCE_SIZE,
    FREE,
    GAP,
    LAM0,
    LIMIT_NEG,
    LIMIT_POS,
    MU,
    MW0,
    N_CONTACTS,
    N_DOF,
    SLIP,
    SLIP_NEG,
    SLIP_POS,
    STICK,
    THETA,
    WN0,
    WT0,
)

#: Relative slack of the impact's consistency tests (rounding of a 4 x 4 solve).
_SLACK = 1e-11


@hot
def _contact(mode):
    """The closed sleeve contact of ``mode`` (1 or 2), or 0 when free."""
    return 0 if mode[0] == FREE else 1 + (mode[0] - 1) // 3


@hot
def _status(mode):
    return (mode[0] - 1) % 3


@hot
def _code(contact, status):
    return 1 + 3 * (contact - 1) + status


@hot
def _acc(p, m, i, y):
    """``q''_i`` in mode code ``m``."""
    o = ACC0 + ACC_SIZE * m + ACC_ROW * i
    return p[o] * y[0] + p[o + 1] * y[1] + p[o + 2] * y[2] + p[o + 3]


@hot
def _force(p, m, y):
    """``lambda_N`` of the closed contact in mode code ``m``."""
    o = LAM0 + FORCE_SIZE * m
    return p[o] * y[0] + p[o + 1] * y[1] + p[o + 2] * y[2] + p[o + 3]


@hot
def _acc_rate(p, m, i, dy):
    """The rate of ``q''_i`` of mode code ``m`` along ``dy`` (its coefficients on ``q`` times ``q'``)."""
    o = ACC0 + ACC_SIZE * m + ACC_ROW * i
    return p[o] * dy[0] + p[o + 1] * dy[1] + p[o + 2] * dy[2]


@hot
def _sigma(p, j):
    """The sign of sleeve contact ``j``'s normal direction on the tilt (its gap is ``g0 + sigma hM phiM``)."""
    return 1.0 if p[WN0 + N_DOF * j + 1] > 0.0 else -1.0


@hot
def _gap(p, c, y):
    """The gap of contact ``c`` over its lever (``hS``, ``hM``): the angle left before the beak (``beak - phiS``)
    or a sleeve diagonal (``theta -+ phiM``) touches the pole, zero exactly on the limit a transition puts the
    angle on."""
    if c == BEAK:
        return p[BEAK_ANGLE] - y[2]
    return p[THETA] + y[1] if c == 1 else p[THETA] - y[1]


@hot
def _gap_rate(c, dy):
    if c == BEAK:
        return -dy[2]
    return dy[1] if c == 1 else -dy[1]


@hot
def _normal_velocity(p, c, y):
    o = WN0 + N_DOF * c
    return p[o] * y[3] + p[o + 1] * y[4] + p[o + 2] * y[5]


@hot
def _slip_velocity(p, c, y):
    o = WT0 + N_DOF * c
    return p[o] * y[3] + p[o + 1] * y[4] + p[o + 2] * y[5]


@hot
def rhs(p, mode, t, y, out):
    m = mode[0]
    for i in range(N_DOF):
        out[i] = y[N_DOF + i]
        out[N_DOF + i] = _acc(p, m, i, y)


@hot
def jacobian(p, mode, t, y, out):
    m = mode[0]
    for i in range(2 * N_DOF):
        for j in range(2 * N_DOF):
            out[i, j] = 0.0
    for i in range(N_DOF):
        out[i, N_DOF + i] = 1.0
        o = ACC0 + ACC_SIZE * m + ACC_ROW * i
        for j in range(N_DOF):
            out[N_DOF + i, j] = p[o + j]


@hot
def guard_value(p, mode, kind, index, t, y):
    if kind == GAP:
        return _gap(p, index, y)
    if kind == SLIP:
        return _slip_velocity(p, index, y)
    if kind == NORMAL:
        return -_sigma(p, index) * _acc(p, FREE, 1, y)
    if kind == NORMAL_STUCK:
        return _force(p, _code(index, STICK), y)
    if kind == LIMIT_POS:
        return _acc(p, _code(index, SLIP_NEG), 0, y)
    return -_acc(p, _code(index, SLIP_POS), 0, y)


@hot
def guard_rate(p, mode, kind, index, t, y, dy):
    if kind == GAP:
        return _gap_rate(index, dy)
    if kind == SLIP:
        o = WT0 + N_DOF * index
        return p[o] * dy[3] + p[o + 1] * dy[4] + p[o + 2] * dy[5]
    if kind == NORMAL:
        return -_sigma(p, index) * _acc_rate(p, FREE, 1, dy)
    if kind == NORMAL_STUCK:
        o = LAM0 + FORCE_SIZE * _code(index, STICK)
        return p[o] * dy[0] + p[o + 1] * dy[1] + p[o + 2] * dy[2]
    if kind == LIMIT_POS:
        return _acc_rate(p, _code(index, SLIP_NEG), 0, dy)
    return -_acc_rate(p, _code(index, SLIP_POS), 0, dy)


@hot
def guards_of(p, mode, gk, gi, gs):
    gk[0], gi[0], gs[0] = GAP, BEAK, 1
    j = _contact(mode)
    if j == 0:
        for c in range(1, N_CONTACTS):
            gk[c], gi[c], gs[c] = GAP, c, 1
        return N_CONTACTS
    status = _status(mode)
    gk[1], gi[1], gs[1] = (NORMAL_STUCK if status == STICK else NORMAL), j, 1
    if status == STICK:
        gk[2], gi[2], gs[2] = LIMIT_POS, j, 1
        gk[3], gi[3], gs[3] = LIMIT_NEG, j, 1
        return 4
    gk[2], gi[2], gs[2] = SLIP, j, (1 if status == SLIP_POS else -1)
    return 3


@hot
def _contact_mode(p, y, j):
    """The mode of the sleeve whose contact ``j`` is closed (gap and normal velocity zero) at ``y``.

    Free unless the free motion would close the gap (the ``normal`` guard positive); then sliding with
    the slip velocity's sign; at zero slip velocity, jammed if both friction limits hold, else sliding
    the way the limit that fails points. Each test is the guard the mode it picks ends on, so a mode is
    never entered on the wrong side of its own guard.
    """
    if -_sigma(p, j) * _acc(p, FREE, 1, y) <= 0.0:  # the normal guard: no force needed
        return FREE
    slip = _slip_velocity(p, j, y)
    if slip > 0.0:
        return _code(j, SLIP_POS)
    if slip < 0.0:
        return _code(j, SLIP_NEG)
    down, up = _acc(p, _code(j, SLIP_NEG), 0, y), -_acc(p, _code(j, SLIP_POS), 0, y)
    if down >= 0.0 and up >= 0.0:
        return _code(j, STICK)
    return _code(j, SLIP_NEG if down < 0.0 else SLIP_POS)


@hot
def _impulse(p, off, size, r, x0, x1, x2, x3):
    """Row ``r`` of ``S xi-`` for the combination whose matrix ``S`` (``size x size``) starts at ``off``."""
    o = off + size * r
    s = p[o] * x0 + p[o + 1] * x1
    if size == 4:
        s += p[o + 2] * x2 + p[o + 3] * x3
    return s


@hot
def _delassus(p, row, c):
    """``W^T M^-1 W`` times the impulse of contact ``c``: the entries of row ``row`` on its normal, tangential parts."""
    o = DEL0 + 2 * N_CONTACTS * row + 2 * c
    return p[o], p[o + 1]


@hot
def _violation(p, off, first, second, combo, x0, x1, x2, x3):
    """How far the impulses of status combination ``combo`` (matrix at ``off``) are from consistent (<= 0: they are).

    ``xi- = (x0, x1)`` of contact ``first`` and ``(x2, x3)`` of ``second`` (-1: none). Closed: ``Lambda_N >= 0``;
    stuck: ``|Lambda_T| <= mu Lambda_N``; sliding: ``gamma_T+`` of the status's sign. Open: ``gamma_N+ >= -e
    gamma_N-``. Each test has a relative slack for the rounding of the impulses.
    """
    n = 1 if second < 0 else 2
    size = 2 * n
    if np.isnan(p[off]):
        return np.inf
    scale = abs(x0) + abs(x1) + abs(x2) + abs(x3)
    l0 = _impulse(p, off, size, 0, x0, x1, x2, x3)
    l1 = _impulse(p, off, size, 1, x0, x1, x2, x3)
    l2 = _impulse(p, off, size, 2, x0, x1, x2, x3) if n == 2 else 0.0
    l3 = _impulse(p, off, size, 3, x0, x1, x2, x3) if n == 2 else 0.0
    bad = -np.inf
    for k in range(n):
        c = first if k == 0 else second
        st = combo % N_IMPACT_STATUS if k == 0 else combo // N_IMPACT_STATUS
        pre_n, pre_t = (x0, x1) if k == 0 else (x2, x3)
        lam_n, lam_t = (l0, l1) if k == 0 else (l2, l3)
        dn0, dt0 = _delassus(p, 2 * c, first)
        post_n = pre_n + dn0 * l0 + dt0 * l1
        dn0, dt0 = _delassus(p, 2 * c + 1, first)
        post_t = pre_t + dn0 * l0 + dt0 * l1
        if n == 2:
            dn1, dt1 = _delassus(p, 2 * c, second)
            post_n += dn1 * l2 + dt1 * l3
            dn1, dt1 = _delassus(p, 2 * c + 1, second)
            post_t += dn1 * l2 + dt1 * l3
        v_tol = _SLACK * (scale + abs(post_n) + abs(post_t))
        f_tol = _SLACK * (abs(lam_n) + abs(lam_t))
        if st == OPEN:
            bad = max(bad, -(post_n + p[E0 + c] * pre_n) - v_tol)
        else:
            bad = max(bad, -lam_n - f_tol)
            if st == CLOSED_STICK:
                bad = max(bad, abs(lam_t) - p[MU] * lam_n - f_tol)
            elif st == CLOSED_POS:
                bad = max(bad, -post_t - v_tol)
            else:
                bad = max(bad, post_t - v_tol)
    return bad


@hot
def _impact(p, y, first, second):
    """Apply the impulses of an impact of contact ``first`` (and ``second``, a closed sleeve contact; -1: none);
    return the status combination applied.

    Each contact involved takes one status (:data:`~nsbench.problems.woodpecker_spec.CLOSED_STICK` ..
    ``OPEN``); the combinations are tried in order (the first contact's status varying fastest) and the
    first consistent one (:func:`_violation`) is applied to ``y``'s velocities. Its impulses ``Lambda = S
    xi-`` come from the matrices the problem computed for each combination in Python. If none passes the
    tests (rounding at a degenerate impact) the least inconsistent one is applied.
    """
    x0, x1 = _normal_velocity(p, first, y), _slip_velocity(p, first, y)
    x2, x3 = 0.0, 0.0
    if second >= 0:
        x2, x3 = _normal_velocity(p, second, y), _slip_velocity(p, second, y)
        base, size, n_combos = IMP2 + N_PAIR_COMBOS * IMP2_SIZE * (second - 1), 4, N_PAIR_COMBOS
    else:
        base, size, n_combos = IMP1 + N_IMPACT_STATUS * IMP1_SIZE * first, 2, N_IMPACT_STATUS
    step = size * size
    best, best_bad = 0, np.inf
    for combo in range(n_combos):
        bad = _violation(p, base + step * combo, first, second, combo, x0, x1, x2, x3)
        if bad <= 0.0:
            best = combo
            break
        if bad < best_bad:
            best, best_bad = combo, bad
    off = base + step * best
    l0 = _impulse(p, off, size, 0, x0, x1, x2, x3)
    l1 = _impulse(p, off, size, 1, x0, x1, x2, x3)
    l2 = _impulse(p, off, size, 2, x0, x1, x2, x3) if size == 4 else 0.0
    l3 = _impulse(p, off, size, 3, x0, x1, x2, x3) if size == 4 else 0.0
    for i in range(N_DOF):
        o = MW0 + 2 * N_CONTACTS * i
        dv = p[o + 2 * first] * l0 + p[o + 2 * first + 1] * l1
        if second >= 0:
            dv += p[o + 2 * second] * l2 + p[o + 2 * second + 1] * l3
        y[N_DOF + i] += dv
    return best


@hot
def _on_sleeve_contact(p, y, j, status):
    """The sleeve's contact ``j`` is closed after an impact with ``status``: put it exactly on the constraint."""
    y[1] = -p[THETA] if j == 1 else p[THETA]
    y[4] = 0.0  # gamma_N = 0 on the closed contact
    if status == CLOSED_STICK:
        y[3] = 0.0  # gamma_T = 0: jammed


@hot
def transition(p, mode, kind, index, t, y, fresh):
    """A gap closed (an impact), the normal force vanished, the slip stopped or a friction limit was reached."""
    j = _contact(mode)
    if kind == GAP:
        c = j if index == BEAK else index  # the sleeve contact involved (0: none, a peck while free)
        approach = _normal_velocity(p, c, y) if c > 0 else 0.0
        combo = _impact(p, y, index, -1 if j == 0 else j)
        fresh[index] = True
        kind_code = EV_PECK if index == BEAK else EV_IMPACT
        if index == BEAK:
            y[2] = p[BEAK_ANGLE]
        if c == 0:
            return kind_code
        st = combo // N_IMPACT_STATUS if index == BEAK else combo % N_IMPACT_STATUS
        if j == 0:
            y[1] = -p[THETA] if c == 1 else p[THETA]  # the diagonal that hit is on the pole
        leaves = _normal_velocity(p, c, y) > 0.0 if st == OPEN else approach < 0.0 and p[E0 + c] != 0.0
        if leaves:  # the sleeve leaves the pole (an open contact, or a sleeve that bounces: e > 0)
            mode[0] = FREE
            fresh[c] = True
            return kind_code
        _on_sleeve_contact(p, y, c, st)
        mode[0] = _contact_mode(p, y, c)
        fresh[c] = True
        return kind_code
    fresh[j] = True
    if kind == NORMAL or kind == NORMAL_STUCK:  # the normal force fell to zero
        mode[0] = FREE
        return EV_RELEASE
    if kind == SLIP:
        y[3], y[4] = 0.0, 0.0  # gamma_T = 0 (and gamma_N = 0 on the closed contact)
        mode[0] = _contact_mode(p, y, j)
        if mode[0] == FREE:
            return EV_RELEASE
        return EV_STICK if _status(mode) == STICK else EV_REVERSE
    mode[0] = _code(j, SLIP_NEG if kind == LIMIT_POS else SLIP_POS)
    return EV_SLIP


@hot
def initial_mode(p, t, y, mode):
    """In contact ``j`` if the sleeve starts exactly at its tilt limit with no tilt rate, free otherwise."""
    if y[4] == 0.0 and (y[1] == -p[THETA] or y[1] == p[THETA]):
        mode[0] = _contact_mode(p, y, 1 if y[1] < 0.0 else 2)
    else:
        mode[0] = FREE


@hot
def start_fresh(p, mode, t, y, fresh):
    fresh[BEAK] = y[2] == p[BEAK_ANGLE]
    fresh[1] = y[1] == -p[THETA]
    fresh[2] = y[1] == p[THETA]


@hot
def accumulation_limit(p, mode, kind, index, t, y):
    return -1
