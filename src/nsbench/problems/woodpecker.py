"""``woodpecker``: Glocker's woodpecker toy, a multibody system with impacts and friction together.

A sleeve (mass ``mM``, inertia ``JM``) slides down a pole with a little clearance
(hole radius ``rM``, pole radius ``r0``, half-height ``hM``); a bird (``mS``,
``JS``) is tied to it by a torsion spring ``c_phi``. Coordinates ``q = (y, phiM,
phiS)``: the sleeve's height, its tilt, the bird's angle. With the small-angle
kinematics of Glocker's model (Pfeiffer and Glocker, *Multibody Dynamics with
Unilateral Contacts*, Wiley 1996, section 8.2; Glocker, *Set-Valued Force Laws*,
Springer 2001) the equations of motion are linear with constant coefficients,

    M q'' = h(q) + W_N lambda_N + W_T lambda_T,

    M = [[mS + mM, mS lM, mS lG], [mS lM, JM + mS lM^2, mS lM lG], [mS lG, mS lM lG, JS + mS lG^2]],
    h = [-(mS + mM) g, -c_phi (phiM - phiS) - mS lM g, -c_phi (phiS - phiM) - mS lG g],

with three unilateral contacts, each with Coulomb friction (``mu``):

| contact | gap ``g_N`` | normal direction ``w_N`` | tangential ``w_T`` | restitution |
|---|---|---|---|---|
| beak on the pole | ``lM + lG - lS - r0 - hS phiS`` | ``(0, 0, -hS)`` | ``(1, lM, lG - lS)`` | ``e_beak`` |
| sleeve tilted at ``-theta`` | ``rM - r0 + hM phiM`` | ``(0, hM, 0)`` | ``(1, rM, 0)`` | ``e_sleeve`` |
| sleeve tilted at ``+theta`` | ``rM - r0 - hM phiM`` | ``(0, -hM, 0)`` | ``(1, rM, 0)`` | ``e_sleeve`` |

(``theta = (rM - r0) / hM``). Every mode of this automaton (the sleeve free, or
on one diagonal sliding up, sliding down or jammed) is affine in the state and
every guard is linear in it: ``exact`` solves it, and ``reference`` is ``exact``.
It has no symbolic form for heyoka: a breakaway with one friction coefficient starts
the slide with a double zero of the slip velocity, and heyoka's symbolic path, which
has no rounding band for a guard that starts on its surface, then logs a zero-length
stick (docs/problems.md); so heyoka refuses it at set-up.
No closed form is known; the test's reference is an independent event-driven
solution in 40 digits (``tests/problems/woodpecker_mp.py``), written from the
equations above with Lagrange multipliers.

Units: the parameters are in SI (Glocker's values are the defaults). The state
and time are, by default, in the units of length ``L = rM - r0`` (the clearance;
angles in radians) and time ``T = sqrt((JS + mS lG^2) / c_phi)`` (the bird's swing
on a jammed sleeve, 17.5 ms), so that the fastest rate of the motion is of order
10 and the integrators' default steps fit it; ``dimensional=True`` runs it in SI.
The start parameters ``y_0 ... dphiS_0`` are in the problem's units.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from nsbench.errors import ConfigError
from nsbench.problems import woodpecker_spec as spec
from nsbench.problems.base import Guard, HybridProblem, Mode, NamedModes, Traits
from nsbench.problems.parameters import Bound, check_values

NAME = "woodpecker"
#: Glocker's parameters (SI), as the cardillo examples transcribe them (``WoodpeckerToy.py``, citing
#: Glocker 1995 and 2001): masses, inertias, spring, gravity, geometry, friction and restitution.
DEFAULTS = {
    "mM": 0.0003,
    "JM": 5.0e-9,
    "mS": 0.0045,
    "JS": 7.0e-7,
    "c_phi": 0.0056,
    "g": 9.81,
    "r0": 0.0025,
    "rM": 0.0031,
    "hM": 0.0058,
    "lM": 0.010,
    "lG": 0.015,
    "hS": 0.020,
    "lS": 0.0201,
    "mu": 0.3,
    "e_beak": 0.5,
    "e_sleeve": 0.0,
}
#: The start of the same examples (SI): the sleeve on its lower-tilt contact, sliding down.
GLOCKER_START_SI = {
    "y_0": 0.0,
    "phiM_0": -0.1036,
    "phiS_0": -0.2788,
    "dy_0": -0.3411,
    "dphiM_0": 0.0,
    "dphiS_0": -7.4583,
}
START_NAMES = tuple(GLOCKER_START_SI)
STATE_NAMES = ("y", "phiM", "phiS", "dy", "dphiM", "dphiS")
_POSITIVE = ("mM", "JM", "mS", "JS", "c_phi", "g", "r0", "rM", "hM", "lM", "lG", "hS", "lS")
BOUNDS = {
    **{name: Bound(0.0, False, name) for name in _POSITIVE},
    "mu": Bound(0.0, True, "friction coefficient mu"),
    "e_beak": Bound(0.0, False, "restitution of the beak e_beak"),
    "e_sleeve": Bound(0.0, True, "restitution of the sleeve e_sleeve"),
    **{name: Bound(-math.inf, False, f"start {name}") for name in START_NAMES},
}
#: A start this close to a tilt limit (relative to ``theta``) is put on it: the sleeve starts in contact.
SNAP = 1e-9


@dataclass(frozen=True)
class Units:
    """The problem's units in SI: length, time and mass."""

    length: float = 1.0
    time: float = 1.0
    mass: float = 1.0


@dataclass(frozen=True)
class Model:
    """The mechanical model in the problem's units: ``M q'' = K q + h0 + W_N lambda_N + W_T lambda_T``."""

    M: np.ndarray
    K: np.ndarray
    h0: np.ndarray
    WN: np.ndarray  # rows: contacts; columns: dofs
    WT: np.ndarray
    g0: np.ndarray  # gap = g0 + WN q
    mu: float
    e: np.ndarray


def units_of(v: dict[str, float], dimensional: bool) -> Units:
    """SI (``dimensional``), or the clearance, the bird's swing time and the bird's mass."""
    if dimensional:
        return Units()
    return Units(v["rM"] - v["r0"], math.sqrt((v["JS"] + v["mS"] * v["lG"] ** 2) / v["c_phi"]), v["mS"])


def model_of(v: dict[str, float], u: Units) -> Model:
    """The matrices of the module docstring, from the SI parameters ``v``, in the units ``u``."""
    L, T, mass = u.length, u.time, u.mass
    mM, mS = v["mM"] / mass, v["mS"] / mass
    JM, JS = v["JM"] / (mass * L * L), v["JS"] / (mass * L * L)
    c_phi = v["c_phi"] * T * T / (mass * L * L)
    g = v["g"] * T * T / L
    r0, rM, hM, lM, lG, hS, lS = (v[k] / L for k in ("r0", "rM", "hM", "lM", "lG", "hS", "lS"))
    M = np.array(
        [
            [mS + mM, mS * lM, mS * lG],
            [mS * lM, JM + mS * lM * lM, mS * lM * lG],
            [mS * lG, mS * lM * lG, JS + mS * lG * lG],
        ]
    )
    K = np.array([[0.0, 0.0, 0.0], [0.0, -c_phi, c_phi], [0.0, c_phi, -c_phi]])
    h0 = np.array([-(mS + mM) * g, -mS * lM * g, -mS * lG * g])
    WN = np.array([[0.0, 0.0, -hS], [0.0, hM, 0.0], [0.0, -hM, 0.0]])
    WT = np.array([[1.0, lM, lG - lS], [1.0, rM, 0.0], [1.0, rM, 0.0]])
    g0 = np.array([lM + lG - lS - r0, rM - r0, rM - r0])
    return Model(M, K, h0, WN, WT, g0, v["mu"], np.array([v["e_beak"], v["e_sleeve"], v["e_sleeve"]]))


def mode_maps(model: Model, mode: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``(ACC, acc0, lamN, lamT)`` of a mode: ``q'' = ACC q + acc0``, the closed contact's forces ``lam . [q, 1]``.

    Free: ``q'' = M^-1 (K q + h0)``. In contact ``j`` the tilt is fixed (``phiM'' = 0``); sliding with
    sign ``s``: ``y''``, ``phiS''`` and ``lambda_N`` solve ``M q'' = K q + h0 + (w_N - s mu w_T)
    lambda_N``; jammed (``y'' = 0`` too): ``phiS''``, ``lambda_N`` and ``lambda_T`` solve ``M q'' =
    K q + h0 + w_N lambda_N + w_T lambda_T``.
    """
    M, K, h0 = model.M, model.K, model.h0
    rhs = np.column_stack([K, h0])  # K q + h0 as a 3 x 4 map of [q, 1]
    acc = np.zeros((3, 4))
    lam_n, lam_t = np.zeros(4), np.zeros(4)
    if mode == spec.FREE:
        acc = np.linalg.solve(M, rhs)
    else:
        j, status = 1 + (mode - 1) // 3, (mode - 1) % 3
        wn, wt = model.WN[j], model.WT[j]
        if status == spec.STICK:
            sol = np.linalg.solve(np.column_stack([M[:, 2], -wn, -wt]), rhs)
            acc[2], lam_n, lam_t = sol[0], sol[1], sol[2]
        else:
            s = 1.0 if status == spec.SLIP_POS else -1.0
            sol = np.linalg.solve(np.column_stack([M[:, 0], M[:, 2], -(wn - s * model.mu * wt)]), rhs)
            acc[0], acc[2], lam_n = sol[0], sol[1], sol[2]
            lam_t = -s * model.mu * lam_n
    return acc[:, :3], acc[:, 3], lam_n, lam_t


def pack(model: Model) -> np.ndarray:
    """The law's parameter vector (:mod:`nsbench.problems.woodpecker_spec` names every slot)."""
    values: dict[str, float] = {"mu": model.mu, "e0": model.e[0], "e1": model.e[1], "e2": model.e[2]}
    values["theta"] = model.g0[1] / model.WN[1, 1]
    values["beak"] = model.g0[0] / -model.WN[0, 2]
    for c in range(spec.N_CONTACTS):
        for i in range(spec.N_DOF):
            values[f"wn_{c}_{i}"], values[f"wt_{c}_{i}"] = model.WN[c, i], model.WT[c, i]
    for m in range(spec.N_MODES):
        acc, acc0, lam_n, lam_t = mode_maps(model, m)
        for i in range(spec.N_DOF):
            for j in range(spec.N_DOF):
                values[f"acc_{m}_{i}_{j}"] = acc[i, j]
            values[f"acc_{m}_{i}_{spec.N_DOF}"] = acc0[i]
        for k in range(4):
            values[f"lam_{m}_{k}"] = lam_n[k]
    W = np.empty((spec.N_DOF, 2 * spec.N_CONTACTS))  # columns: normal, tangential of each contact
    W[:, 0::2], W[:, 1::2] = model.WN.T, model.WT.T
    mw = np.linalg.solve(model.M, W)
    delassus = W.T @ mw
    for i in range(spec.N_DOF):
        for k in range(2 * spec.N_CONTACTS):
            values[f"mw_{i}_{k}"] = mw[i, k]
    for k in range(2 * spec.N_CONTACTS):
        for m in range(2 * spec.N_CONTACTS):
            values[f"del_{k}_{m}"] = delassus[k, m]
    for c in range(spec.N_CONTACTS):
        for st in range(spec.N_IMPACT_STATUS):
            s = impulse_matrix(model, delassus, (c,), (st,)).ravel()
            values.update({f"imp1_{c}_{st}_{k}": s[k] for k in range(spec.IMP1_SIZE)})
    for j in (1, 2):
        for combo in range(spec.N_PAIR_COMBOS):
            statuses = (combo % spec.N_IMPACT_STATUS, combo // spec.N_IMPACT_STATUS)
            s = impulse_matrix(model, delassus, (spec.BEAK, j), statuses).ravel()
            values.update({f"imp2_{j - 1}_{combo}_{k}": s[k] for k in range(spec.IMP2_SIZE)})
    return spec.LAYOUT.pack(values)


def impulse_matrix(
    model: Model, delassus: np.ndarray, contacts: tuple[int, ...], statuses: tuple[int, ...]
) -> np.ndarray:
    """``S`` with ``Lambda = S xi-`` for contacts with these impact statuses (NaN where the equations are singular).

    ``Lambda`` and ``xi-`` hold the normal and tangential impulse (velocity before the impact) of each contact
    in turn; ``xi+ = xi- + D Lambda`` with ``D`` the Delassus matrix of those contacts. Per contact: closed,
    ``gamma_N+ = -e gamma_N-`` and either ``gamma_T+ = 0`` (stuck) or ``Lambda_T = -+ mu Lambda_N`` (sliding
    with ``gamma_T+`` positive, negative); open, no impulse.
    """
    idx = [2 * c + d for c in contacts for d in (0, 1)]
    d = delassus[np.ix_(idx, idx)]
    size = len(idx)
    a, b = np.zeros((size, size)), np.zeros((size, size))
    for k, (c, st) in enumerate(zip(contacts, statuses)):
        rn, rt = 2 * k, 2 * k + 1
        if st == spec.OPEN:
            a[rn, rn] = a[rt, rt] = 1.0
            continue
        a[rn], b[rn, rn] = d[rn], -(1.0 + model.e[c])
        if st == spec.CLOSED_STICK:
            a[rt], b[rt, rt] = d[rt], -1.0
        else:
            a[rt, rt], a[rt, rn] = 1.0, (model.mu if st == spec.CLOSED_POS else -model.mu)
    if abs(np.linalg.det(a)) <= 1e-12 * max(1.0, float(np.abs(a).max())) ** size:
        return np.full((size, size), np.nan)
    return np.linalg.solve(a, b)


class Woodpecker(NamedModes, HybridProblem):
    """The woodpecker toy (see the module docstring)."""

    mode_names = spec.MODE_NAMES
    family = "multibody"
    traits = Traits(impacts=True)
    problem_class = "impact-friction"
    law_module = "nsbench.problems.woodpecker_law"
    guard_kinds = spec.GUARD_KINDS
    event_kinds = spec.EVENT_KINDS
    mode_columns = ("sleeve",)

    def __init__(self, params: dict[str, Any], parameters: dict[str, float], dimensional: bool) -> None:
        self._given(
            NAME,
            params,
            parameters,
            state_names=STATE_NAMES,
            position_rates={"y": "dy", "phiM": "dphiM", "phiS": "dphiS"},
        )
        self.dimensional = dimensional
        self.units = units_of(parameters, dimensional)
        self.model = model_of(parameters, self.units)
        self.packed = pack(self.model)
        self._maps = {m: mode_maps(self.model, m) for m in range(spec.N_MODES)}

    def initial_state(self) -> np.ndarray:
        return np.array([self.parameters[k] for k in START_NAMES])

    def guard_name(self, guard: Guard) -> str:
        return f"{guard.kind}:{spec.CONTACT_NAMES[guard.block - 1]}"

    @property
    def n_elements(self) -> int:
        return spec.N_CONTACTS

    @property
    def max_guards(self) -> int:
        return 4

    @property
    def time_scale(self) -> float:
        """The bird's swing time ``T`` in the problem's time unit (1 in the default units)."""
        return 1.0 if not self.dimensional else units_of(self.parameters, False).time

    @property
    def theta(self) -> float:
        """The sleeve's tilt at which a diagonal touches the pole."""
        return float(self.model.g0[1] / self.model.WN[1, 1])

    @property
    def beak_angle(self) -> float:
        """The bird's angle at which the beak touches the pole."""
        return float(self.model.g0[0] / -self.model.WN[0, 2])

    # ------------------------------------------------------------------ piecewise linear: exact's data
    @property
    def is_linear(self) -> bool:
        return True

    def linear_form(self, mode: Mode):
        acc, acc0, _, _ = self._maps[int(mode[0])]
        a = np.zeros((6, 6))
        a[:3, 3:] = np.eye(3)
        a[3:, :3] = acc
        b0 = np.zeros(6)
        b0[3:] = acc0
        return a, b0, np.zeros(6), np.zeros(6)

    def guard_row(self, mode: Mode, kind: int, index: int) -> np.ndarray:
        """``q`` with the guard ``= q . [y, 1, cos, sin]``."""
        row = np.zeros(9)
        if kind == spec.GAP:  # the gap over its lever: an angle margin (woodpecker_spec)
            lever = abs(self.model.WN[index]).max()
            row[:3], row[6] = np.round(self.model.WN[index] / lever), self.beak_angle if index == 0 else self.theta
        elif kind == spec.SLIP:
            row[3:6] = self.model.WT[index]
        elif kind == spec.NORMAL_STUCK:
            lam_n = self._maps[spec.mode_code(index, spec.STICK)][2]
            row[:3], row[6] = lam_n[:3], lam_n[3]
        else:  # an acceleration of a neighbouring mode (woodpecker_spec): the free tilt's, a slide's y''
            if kind == spec.NORMAL:
                m, i, sign = spec.FREE, 1, -np.sign(self.model.WN[index, 1])
            else:
                status = spec.SLIP_NEG if kind == spec.LIMIT_POS else spec.SLIP_POS
                m, i, sign = spec.mode_code(index, status), 0, (1.0 if kind == spec.LIMIT_POS else -1.0)
            acc, acc0, _, _ = self._maps[m]
            row[:3], row[6] = sign * acc[i], sign * acc0[i]
        return row

    # ------------------------------------------------------------------ what is known
    def energy(self, y):
        """Kinetic plus spring plus gravitational energy (in the problem's units); impacts and friction dissipate it."""
        y = np.asarray(y, dtype=float)
        q, u = y[:3], y[3:]
        kinetic = 0.5 * np.einsum("i...,ij,j...->...", u, self.model.M, u)
        spring = -0.5 * np.einsum("i...,ij,j...->...", q, self.model.K, q)
        return kinetic + spring - np.einsum("i,i...->...", self.model.h0, q)

    def to_si(self, t, y) -> tuple[np.ndarray, np.ndarray]:
        """Times and states of this problem's units in SI (s; m, rad, m/s, rad/s)."""
        u = self.units
        scale = np.array([u.length, 1.0, 1.0, u.length / u.time, 1.0 / u.time, 1.0 / u.time])
        y = np.asarray(y, dtype=float)
        return np.asarray(t, dtype=float) * u.time, y * scale.reshape((6,) + (1,) * (y.ndim - 1))


def _start(v: dict[str, float], given: dict[str, float], u: Units, theta: float, beak: float) -> dict[str, float]:
    """The start in the problem's units: the given values, else Glocker's start converted; ``phiM`` put on a
    tilt limit it lies within :data:`SNAP` of."""
    scale = {"y_0": u.length, "phiM_0": 1.0, "phiS_0": 1.0, "dy_0": u.length / u.time, "dphiM_0": 1 / u.time}
    scale["dphiS_0"] = 1 / u.time
    start = {k: given.get(k, GLOCKER_START_SI[k] / scale[k]) for k in START_NAMES}
    if "phiM_0" not in given:
        start["phiM_0"] = -theta  # Glocker's -0.1036 is the limit -theta = -0.10345 rounded: in contact
    for limit in (-theta, theta):
        if abs(start["phiM_0"] - limit) <= SNAP * theta:
            start["phiM_0"] = limit
    phi_m, dphi_m, phi_s, dphi_s = (start[k] for k in ("phiM_0", "dphiM_0", "phiS_0", "dphiS_0"))
    if abs(phi_m) > theta or (abs(phi_m) == theta and dphi_m * phi_m > 0.0):
        raise ConfigError(
            f"{NAME}: start phiM_0 = {phi_m:g}, dphiM_0 = {dphi_m:g} is beyond the sleeve's clearance: the tilt must "
            f"satisfy |phiM_0| <= theta = {theta:.6g} (rad), on a limit with dphiM_0 = 0 (in contact) or moving away"
        )
    if phi_s > beak or (phi_s == beak and dphi_s > 0.0):
        raise ConfigError(
            f"{NAME}: start phiS_0 = {phi_s:g}, dphiS_0 = {dphi_s:g} puts the beak into the pole: the bird's angle "
            f"must satisfy phiS_0 <= {beak:.6g} (rad), on it moving away"
        )
    return start


def woodpecker(case: int | str | None = None, dimensional: bool = False, **params: Any) -> Woodpecker:
    """Build the woodpecker toy (SI parameters ``mM JM mS JS c_phi g r0 rM hM lM lG hS lS mu e_beak e_sleeve``;
    start ``y_0 phiM_0 phiS_0 dy_0 dphiM_0 dphiS_0`` in the problem's units; see the module docstring).

    Raises
    ------
    ConfigError
        A case, an unknown parameter, a non-finite or out-of-range value, a pole wider than the sleeve's
        hole (``r0 >= rM``), a friction coefficient at which the sliding sleeve's contact force is not
        determined (Painleve's paradox), or a start that penetrates the pole.
    """
    if case not in (None, 1, "1"):
        raise ConfigError(f"{NAME}: unknown case {case!r}; the problem has no cases (give its parameters)")
    given = check_values(NAME, params, (*DEFAULTS, *START_NAMES), BOUNDS)
    v = {**DEFAULTS, **{k: x for k, x in given.items() if k in DEFAULTS}}
    if not v["r0"] < v["rM"]:
        raise ConfigError(
            f"{NAME}: r0 = {v['r0']:g} must be below rM = {v['rM']:g} (the pole passes through the sleeve)"
        )
    if v["e_beak"] > 1.0:
        raise ConfigError(f"{NAME}: parameter e_beak = {v['e_beak']:g} is out of range: restitution must be <= 1")
    units = units_of(v, dimensional)
    model = model_of(v, units)
    minv = np.linalg.inv(model.M)
    for j in (1, 2):
        for s in (1.0, -1.0):
            d = model.WN[j] @ minv @ (model.WN[j] - s * model.mu * model.WT[j])
            if not d > 0.0:
                raise ConfigError(
                    f"{NAME}: parameter mu = {model.mu:g} is out of range: the sliding sleeve's normal force is not "
                    "determined (Painleve's paradox); use a smaller mu"
                )
    theta = float(model.g0[1] / model.WN[1, 1])
    beak = float(model.g0[0] / -model.WN[0, 2])
    start = _start(v, {k: x for k, x in given.items() if k in START_NAMES}, units, theta, beak)
    return Woodpecker(params, {**v, **start}, dimensional)
