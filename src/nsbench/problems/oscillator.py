"""The friction family (MODEL.md): a chain of blocks on a belt, as a hybrid problem.

One class serves ``one-dof``, ``two-dof``, ``chain`` and ``block-on-ground``:
block 1 tied to the ground, each further block tied to the previous one, the
harmonic force on the last block, Coulomb friction with stiction against a
belt at speed ``v0`` (0: fixed ground). Its law is
:mod:`nsbench.problems.friction_law` (vocabulary: :mod:`nsbench.problems.friction_spec`); the vector field, Jacobian, guards,
transitions and initial mode come from it (:class:`~nsbench.problems.base.HybridProblem`).
This module adds what only this family has: the coefficients by name, the
sliding regions, the energy balance, the closed-form data ``exact`` uses, and the
start state as parameters (``x1_0``, ``v1_0``, ... in the problem's units).
"""

from __future__ import annotations

from typing import Any, Callable, Mapping, Sequence

import numpy as np

from nsbench.errors import ConfigError
from nsbench.problems import friction_spec as spec
from nsbench.problems.base import Guard, HybridProblem, Mode, Traits
from nsbench.problems.friction_laws import COULOMB_LAW, FrictionLaw, slip_level
from nsbench.problems.modes import PHASE_NAMES, STICK, all_modes
from nsbench.problems.parameters import Coefficients, Scales


def start_names(n_blocks: int) -> tuple[str, ...]:
    """Names of the start-state parameters: ``x1_0, v1_0, x2_0, v2_0, ...``."""
    return tuple(f"{q}{i}_0" for i in range(1, n_blocks + 1) for q in ("x", "v"))


def split_start(
    problem: str, params: Mapping[str, Any], n_blocks: int
) -> tuple[dict[str, Any], np.ndarray, dict[str, float]]:
    """``(the other parameters, the start state, the start parameters given)``; the start state is rest
    at the origin where not given. Refuses a non-finite or non-numeric start value by name."""
    names = start_names(n_blocks)
    rest = {k: v for k, v in params.items() if k not in names}
    y0 = np.zeros(2 * n_blocks)
    given: dict[str, float] = {}
    for j, name in enumerate(names):
        if name not in params:
            continue
        raw = params[name]
        try:
            value = float(raw) if not isinstance(raw, bool) else float("nan")
        except (TypeError, ValueError):
            raise ConfigError(f"{problem}: parameter {name} = {raw!r} is not a number") from None
        if not np.isfinite(value):
            raise ConfigError(f"{problem}: parameter {name} = {raw!r} is not allowed: the start state must be finite")
        y0[j] = given[name] = value
    bad = [k for k in rest if k.endswith("_0") and k[:1] in "xv"]
    if bad:
        raise ConfigError(
            f"{problem}: unknown parameter {bad[0]!r}; the start state of {n_blocks} block(s) is {', '.join(names)}"
        )
    return rest, y0, given


class FrictionOscillator(HybridProblem):
    """A chain of blocks on a moving belt with Coulomb friction and stiction.

    Parameters
    ----------
    coefficients
        Masses, damping, springs, friction levels, forcing and belt speed, in
        the problem's own units (dimensionless unless ``dimensional``).
    name
        Registry name (``'one-dof'``, ``'two-dof'``, ``'chain'``, ``'block-on-ground'``).
    case
        Preset 1..4 the problem was built from, or ``None``.
    dimensional
        Whether ``coefficients`` are dimensional.
    params
        The user's parameter overrides (what rebuilds the problem with ``case``).
    parameters
        Every parameter value after presets and shorthands, in the user's vocabulary.
    scales
        Scales that convert this problem's units to the dimensionless form.
    y0
        The start state (default: every block at rest at the origin).
    law
        The friction law of a slipping block (:mod:`nsbench.problems.friction_laws`; default Coulomb).
    cases
        The cases the problem's factory names (:attr:`HybridProblem.cases`).

    Notes
    -----
    State ``y = [x1, v1, x2, v2, ...]``. Arrays of states are column-stacked:
    ``y`` of shape ``(n,)`` or ``(n, k)`` with ``t`` a scalar or shape ``(k,)``,
    the convention of ``scipy.integrate.solve_ivp(vectorized=True)``.
    """

    family = "friction"
    traits = Traits(belt_blocks=True)
    law_module = "nsbench.problems.friction_law"
    guard_kinds = spec.GUARD_KINDS
    event_kinds = spec.EVENT_KINDS

    def __init__(
        self,
        coefficients: Coefficients,
        *,
        name: str,
        case: int | str | None,
        dimensional: bool,
        params: dict[str, float],
        parameters: dict[str, float],
        scales: Scales,
        y0: np.ndarray | None = None,
        law: FrictionLaw = COULOMB_LAW,
        cases: tuple[int | str, ...] = (),
    ) -> None:
        self.coefficients = coefficients
        self.name = name
        self.case = case
        self.cases = tuple(cases)
        self.dimensional = dimensional
        self.params = dict(params)
        self.parameters = dict(parameters)
        self.scales = scales
        nb = coefficients.n_blocks
        self.n_blocks = nb
        self.state_names = tuple(f"{q}{i}" for i in range(1, nb + 1) for q in ("x", "v"))
        self.position_rates = {f"x{i}": f"v{i}" for i in range(1, nb + 1)}
        self.mode_columns = tuple(f"phase{i}" for i in range(1, nb + 1))
        self._y0 = np.zeros(2 * nb) if y0 is None else np.array(y0, dtype=float)
        self.law_spec = law
        c = coefficients
        self.packed = spec.LAYOUT.pack(
            {
                "n_blocks": nb,
                "m": c.m,
                "c": c.c,
                "k": c.k,
                "h": c.h,
                "fs": c.fs,
                "fr": c.fr,
                **law.fields(c.fs),
                "F": c.F,
                "w": c.w,
                "v0": c.v0,
                "law": law.code,
            },
            nb,
        )

    # ------------------------------------------------------------------ identity
    @property
    def modes(self) -> tuple[Mode, ...]:
        """All ``3**n_blocks`` modes (for small problems: tests, tables; the core never enumerates them)."""
        if self.n_blocks > 10:
            raise ValueError(f"{self.name} has 3**{self.n_blocks} modes: too many to list")
        return all_modes(self.n_blocks)

    @property
    def is_linear(self) -> bool:
        """True when every cubic coefficient is zero and friction is Coulomb's (the exact solver applies)."""
        return self.coefficients.is_linear and self.law_spec.is_coulomb

    @property
    def nonlinear_reason(self) -> str:
        """Why the problem is not piecewise linear ('' if it is)."""
        reasons = []
        if not self.coefficients.is_linear:
            reasons.append("cubic springs")
        if not self.law_spec.is_coulomb:
            reasons.append(f"the {self.law_spec.name} friction law (a slip force that varies with the slip speed)")
        return " and ".join(reasons)

    @property
    def is_forced(self) -> bool:
        return self.coefficients.is_forced

    @property
    def v0(self) -> float:
        return self.coefficients.v0

    @property
    def forcing_frequency(self) -> float:
        return self.coefficients.w

    @property
    def time_scale(self) -> float:
        return self.scales.time if self.dimensional else 1.0

    def __repr__(self) -> str:
        units = "dimensional" if self.dimensional else "dimensionless"
        case = f", case={self.case!r}" if self.case is not None else ""
        extra = f", params={self.params}" if self.params else ""
        return f"<{self.name}{case}, {units}{extra}>"

    def initial_state(self) -> np.ndarray:
        """The start state: the ``x1_0, v1_0, ...`` parameters, every block at rest at the origin by default."""
        return self._y0.copy()

    def mode_name(self, mode: Mode) -> str:
        """Readable name of a mode, e.g. ``'slip-|stick'``."""
        return "|".join(PHASE_NAMES[int(p)] for p in mode)

    def parse_mode(self, text: str) -> Mode:
        codes = {name: phase for phase, name in PHASE_NAMES.items()}
        return tuple(codes[part] for part in text.split("|"))

    def guard_name(self, guard: Guard) -> str:
        i = guard.block
        return {"velocity": f"v{i}-v0", "upper": f"R{i}-fr{i}", "lower": f"R{i}+fr{i}"}[guard.kind]

    # ------------------------------------------------------------------ forces (any arithmetic)
    def link_forces(self, x: Sequence[Any]) -> list[Any]:
        """Tension of each spring link: link 0 ties block 1 to the ground.

        Written with plain arithmetic (cubes as ``d*d*d``) so the same code
        evaluates numpy arrays, floats or symbolic (heyoka) expressions.
        """
        c = self.coefficients
        out = []
        for j in range(self.n_blocks):
            d = x[j] - x[j - 1] if j > 0 else x[0]
            s = c.k[j] * d
            if c.h[j] != 0.0:
                s = s + c.h[j] * (d * d * d)
            out.append(s)
        return out

    def restoring_forces(
        self, t: Any, x: Sequence[Any], v: Sequence[Any], cos: Callable[[Any], Any] = np.cos
    ) -> list[Any]:
        """``R_i`` of MODEL.md: every force on block i except friction, moved left.

        Generic over the arithmetic of ``x``, ``v`` and ``t`` (see :meth:`link_forces`);
        the compiled law's ``restoring`` is the one the core uses (tested equal).
        """
        c = self.coefficients
        links = self.link_forces(x)
        nb = self.n_blocks
        out = []
        for i in range(nb):
            r = c.c[i] * v[i] + links[i]
            if i + 1 < nb:
                r = r - links[i + 1]
            if i == nb - 1 and c.F != 0.0:
                r = r - c.F * cos(c.w * t)
            out.append(r)
        return out

    def _split(self, y):
        y = np.asarray(y, dtype=float)
        return y, [y[2 * i] for i in range(self.n_blocks)], [y[2 * i + 1] for i in range(self.n_blocks)]

    def restoring_force(self, block: int, t, y):
        """``R_block`` (1-based block) at states ``y`` of shape ``(n,)`` or ``(n, k)``."""
        _, x, v = self._split(y)
        return self.restoring_forces(t, x, v)[block - 1]

    def restoring_rate(self, block: int, t, y, dydt):
        """``dR_block/dt`` along ``dydt``, including the explicit time dependence (the upper guard's rate)."""
        return self.guard_rate(Guard(self, block, "upper", -1), t, y, dydt)

    def belt_speed_restoring(self, t, x: Sequence[Any]) -> list[Any]:
        """The sliding-region functions: ``R_i`` with every ``v_i = v0``.

        Sliding region I is ``|R_1| <= fr_1``, region II ``|R_2| <= fr_2`` (it moves
        with ``t`` when forced), region III their overlap.
        """
        v = [self.v0 + 0.0 * np.asarray(xi, dtype=float) for xi in x]
        return self.restoring_forces(t, x, v)

    def in_sliding_region(self, block: int, t, x: Sequence[Any]):
        """Whether positions ``x`` lie in the sliding region of ``block`` (1-based)."""
        r = self.belt_speed_restoring(t, x)[block - 1]
        return np.abs(r) <= self.coefficients.fr[block - 1]

    # ------------------------------------------------------------------ closed-form data (exact)
    def linear_form(self, mode: Mode) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``(A, b0, bc, bs)`` with ``y' = A y + b0 + bc cos(w t) + bs sin(w t)``.

        Only for linear problems (every ``h = 0``), where each mode is affine.
        """
        if not self.is_linear:
            raise ValueError(f"{self.name}: linear_form needs h = 0 (the problem has cubic springs)")
        n = self.n_states
        a = self.jacobian(mode, 0.0, np.zeros(n))
        b0 = self.rhs(mode, 0.0, np.zeros(n))
        c = self.coefficients
        bc = np.zeros(n)
        bs = np.zeros(n)
        last = self.n_blocks - 1
        if c.F != 0.0 and mode[last] != STICK:
            # rhs(0, y=0) holds (F cos(0) - fs s) / m in the last velocity row; subtracting F / m
            # from it would round the friction term (fs = 0.81 came out as 0.8099999999999999), so
            # the constant is the friction term alone, as rhs forms it without the force.
            b0[2 * last + 1] = (-c.fs[last] * mode[last]) / c.m[last]
            bc[2 * last + 1] = c.F / c.m[last]
        return a, b0, bc, bs

    def guard_row(self, mode: Mode, kind: int, index: int) -> np.ndarray:
        """``q`` with guard ``(kind, index)`` ``= q . [y, 1, cos w t, sin w t]`` (linear problems).

        ``R_i = c_i v_i + k_i d_i - k_{i+1} d_{i+1} - F cos(w t) [last block]`` with ``d_1 = x_1`` and
        ``d_i = x_i - x_{i-1}`` (MODEL.md section 7), so its row is read off the coefficients.
        """
        n, nb = self.n_states, self.n_blocks
        c = self.coefficients
        q = np.zeros(n + 3)
        i = index
        if kind == spec.VELOCITY:
            q[2 * i + 1], q[n] = 1.0, -self.v0
            return q
        q[2 * i + 1] = c.c[i]
        q[2 * i] = c.k[i] + (c.k[i + 1] if i + 1 < nb else 0.0)
        if i > 0:
            q[2 * (i - 1)] = -c.k[i]
        if i + 1 < nb:
            q[2 * (i + 1)] = -c.k[i + 1]
        q[n] = -c.fr[i] if kind == spec.UPPER else c.fr[i]
        if i == nb - 1:
            q[n + 1] = -c.F
        return q

    # ------------------------------------------------------------------ energy
    def energy(self, y):
        """Mechanical energy: kinetic plus spring potential (vectorised)."""
        y, x, v = self._split(y)
        c = self.coefficients
        e = 0.0
        for i in range(self.n_blocks):
            e = e + 0.5 * c.m[i] * v[i] * v[i]
            d = x[i] - x[i - 1] if i > 0 else x[0]
            e = e + 0.5 * c.k[i] * d * d + 0.25 * c.h[i] * d * d * d * d
        return e

    def friction_forces(self, mode: Mode, t, y) -> list[Any]:
        """Friction force on each block: ``-s_i S_i(s_i (v_i - v0))`` in slip (``-fs_i s_i`` for Coulomb),
        ``R_i`` in stick."""
        y, x, v = self._split(y)
        r = self.restoring_forces(t, x, v)
        c, law = self.coefficients, self.law_spec
        out = []
        for i, p in enumerate(mode):
            if p == STICK:
                out.append(r[i])
            elif law.is_coulomb:
                out.append(-c.fs[i] * p + 0.0 * r[i])
            else:
                f = law.fields(c.fs)
                level = slip_level(
                    law.code, p * (v[i] - c.v0), c.fs[i], f["fk"][i], f["delta"][i], f["vs"][i], f["cv"][i], exp=np.exp
                )
                out.append(-level * p + 0.0 * r[i])
        return out

    def power(self, mode: Mode, t, y) -> dict[str, Any]:
        """Power of friction, damping and the external force; they sum to dE/dt."""
        y, x, v = self._split(y)
        c = self.coefficients
        f = self.friction_forces(mode, t, y)
        friction = sum(f[i] * v[i] for i in range(self.n_blocks))
        damping = -sum(c.c[i] * v[i] * v[i] for i in range(self.n_blocks))
        force = c.F * np.cos(c.w * np.asarray(t, dtype=float)) * v[-1]
        return {"friction": friction, "damping": damping, "force": force}
