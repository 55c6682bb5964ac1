"""The vocabulary of the woodpecker toy, without numba: parameter layout, modes, guard and event kinds.

The law reads per-mode affine maps that :mod:`nsbench.problems.woodpecker` computes from the
mechanical model (mass matrix, forces, contact directions) in Python, by name: the slots are
generated here, mode by mode and entry by entry.
"""

from __future__ import annotations

from nsbench.model.layout import Layout

#: Contacts: 0 the beak with the pole, 1 and 2 the sleeve's two diagonals (tilted at ``phiM = -theta``,
#: ``+theta``). Degrees of freedom ``q = (y, phiM, phiS)``; the state is ``(q, q')``.
N_CONTACTS, N_DOF = 3, 3
BEAK = 0
#: Sleeve contact statuses: sliding up (``gamma_T > 0``), down, or stuck (jammed).
SLIP_POS, SLIP_NEG, STICK = 0, 1, 2
STATUS_NAMES = ("slip+", "slip-", "stick")
CONTACT_NAMES = ("beak", "tilt-", "tilt+")
#: The mode vector's one entry: ``FREE`` (the sleeve touches the pole nowhere), or ``1 + 3 (j - 1) +
#: status`` for the sleeve in contact ``j`` (1 or 2) with that status.
FREE = 0
N_MODES = 1 + 3 * (N_CONTACTS - 1)


def mode_code(contact: int, status: int) -> int:
    """The mode of the sleeve in ``contact`` (1 or 2) with ``status``."""
    return 1 + 3 * (contact - 1) + status


MODE_NAMES = {FREE: "free"} | {
    mode_code(j, s): f"{CONTACT_NAMES[j]}/{STATUS_NAMES[s]}" for j in (1, 2) for s in (SLIP_POS, SLIP_NEG, STICK)
}
#: Guards (index: the contact), each fixed by its kind and contact whatever the mode:
#:
#: - ``gap``: a gap over its lever, the angle left before the beak (``beak - phiS``) or a sleeve diagonal
#:   (``theta -+ phiM``) touches the pole: zero exactly on the limit an impact puts the angle on;
#: - ``normal``: the normal force of a sliding sleeve contact, written as the quantity it is a positive
#:   multiple of, ``-sigma phiM''`` of the free motion (``sigma`` the sign of the contact's ``w_N``): the
#:   acceleration that would open the gap, reversed;
#: - ``normal/stick``: the normal force ``lambda_N`` of a jammed sleeve;
#: - ``slip``: the slip velocity ``gamma_T`` of a sliding sleeve;
#: - ``limit+``, ``limit-``: the friction limits of a jammed sleeve, written as the quantities they are
#:   positive multiples of: ``y''`` of sliding down, ``-y''`` of sliding up (``mu lambda_N - lambda_T``
#:   reaches 0 exactly where sliding down starts with zero acceleration, ``mu lambda_N + lambda_T``
#:   where sliding up does).
#:
#: Written so, a guard that ends a mode is the very acceleration that starts the next one: at a
#: breakaway or a release the next mode's slip velocity (gap) starts with a double (triple) zero in the
#: problem's own numbers, not with a rounding-level rate of either sign.
GAP, NORMAL, NORMAL_STUCK, SLIP, LIMIT_POS, LIMIT_NEG = 0, 1, 2, 3, 4, 5
GUARD_KINDS = ("gap", "normal", "normal/stick", "slip", "limit+", "limit-")
#: ``peck``: the beak hits the pole; ``impact``: a sleeve diagonal hits it; ``stick``, ``slip``,
#: ``reverse``: the sleeve's friction; ``release``: the sleeve's contact opens.
EV_PECK, EV_IMPACT, EV_STICK, EV_SLIP, EV_REVERSE, EV_RELEASE = 0, 1, 2, 3, 4, 5
EVENT_KINDS = ("peck", "impact", "stick", "slip", "reverse", "release")

#: Per mode: the accelerations ``q'' = ACC q + acc0`` (3 rows of 3 coefficients and a constant) and the
#: normal force ``lambda_N`` of the closed contact, affine in ``q`` (4).
ACC_ROW, ACC_SIZE = N_DOF + 1, N_DOF * (N_DOF + 1)
FORCE_SIZE = N_DOF + 1
_SCALARS = ("mu", "e0", "e1", "e2", "theta", "beak")
_WN = tuple(f"wn_{c}_{i}" for c in range(N_CONTACTS) for i in range(N_DOF))
_WT = tuple(f"wt_{c}_{i}" for c in range(N_CONTACTS) for i in range(N_DOF))
_ACC = tuple(f"acc_{m}_{i}_{j}" for m in range(N_MODES) for i in range(N_DOF) for j in range(N_DOF + 1))
_LAM = tuple(f"lam_{m}_{k}" for m in range(N_MODES) for k in range(FORCE_SIZE))
#: Impulses: ``M^-1 W`` (3 x 6: columns normal, tangential of contact 0, 1, 2) and ``W^T M^-1 W`` (6 x 6).
_MW = tuple(f"mw_{i}_{k}" for i in range(N_DOF) for k in range(2 * N_CONTACTS))
_DEL = tuple(f"del_{k}_{m}" for k in range(2 * N_CONTACTS) for m in range(2 * N_CONTACTS))
#: The statuses of a contact in an impact, in the order they are tried: closed and stuck, closed and
#: sliding (``gamma_T+ > 0``, ``< 0``), open.
CLOSED_STICK, CLOSED_POS, CLOSED_NEG, OPEN = 0, 1, 2, 3
N_IMPACT_STATUS = 4
#: The impulses of each combination of statuses, ``Lambda = S xi-`` (``xi-``: the normal and tangential
#: velocities of the contacts involved before the impact): for one contact (``imp1``: contact, status;
#: 2 x 2) and for the beak with a closed sleeve contact ``j`` (``imp2``: ``j - 1``, the beak's status + 4
#: times the sleeve's; 4 x 4). NaN where the combination's equations are singular.
IMP1_SIZE, IMP2_SIZE = 4, 16
N_PAIR_COMBOS = N_IMPACT_STATUS * N_IMPACT_STATUS
_IMP1 = tuple(
    f"imp1_{c}_{st}_{k}" for c in range(N_CONTACTS) for st in range(N_IMPACT_STATUS) for k in range(IMP1_SIZE)
)
_IMP2 = tuple(f"imp2_{j}_{combo}_{k}" for j in range(2) for combo in range(N_PAIR_COMBOS) for k in range(IMP2_SIZE))
LAYOUT = Layout(tail=_SCALARS + _WN + _WT + _ACC + _LAM + _MW + _DEL + _IMP1 + _IMP2)
MU, E0, THETA, BEAK_ANGLE = (LAYOUT.offset(name) for name in ("mu", "e0", "theta", "beak"))
WN0, WT0 = LAYOUT.offset("wn_0_0"), LAYOUT.offset("wt_0_0")
ACC0, LAM0, MW0, DEL0 = (LAYOUT.offset(name) for name in ("acc_0_0_0", "lam_0_0", "mw_0_0", "del_0_0"))
IMP1, IMP2 = LAYOUT.offset("imp1_0_0_0"), LAYOUT.offset("imp2_0_0_0")
