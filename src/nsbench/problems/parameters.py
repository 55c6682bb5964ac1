"""Parameters of the friction oscillators: names, Table 3 presets, validation, pi groups.

Everything here follows ``MODEL.md``: dimensionless parameters use the names
``c1 c2 kappa mu h1 h2 rho2 rf1 rf2 F Omega v0`` (2-DOF) and ``c h r_f F Omega v0``
(1-DOF), dimensional ones ``m1 m2 c1 c2 k1 k2 h1 h2 fs1 fs2 fr1 fr2 F w v0`` and
``m c k h fs fr F w v0``. Presets are the exact conversions of Table 3
(``r_f = 5/6``, ``v0 = 1/12``, ``F = 5/12``, ``h = 0.576``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Mapping

from nsbench.errors import ConfigError

CASES = (1, 2, 3, 4)
CASE_DESCRIPTIONS = {
    1: "linear springs, no harmonic force",
    2: "linear springs, harmonic force",
    3: "cubic springs, no harmonic force",
    4: "cubic springs, harmonic force",
}


@dataclass(frozen=True)
class Coefficients:
    """Coefficients of a chain of blocks on a belt, in the problem's own units.

    Block 1 is tied to the ground by ``k[0], h[0]``; block ``i`` (0-based) is tied
    to block ``i - 1`` by ``k[i], h[i]``. The harmonic force ``F cos(w t)`` acts on
    the last block. ``fs`` are the kinetic (slip) friction levels, ``fr`` the static
    limits.
    """

    m: tuple[float, ...]
    c: tuple[float, ...]
    k: tuple[float, ...]
    h: tuple[float, ...]
    fs: tuple[float, ...]
    fr: tuple[float, ...]
    F: float
    w: float
    v0: float

    @property
    def n_blocks(self) -> int:
        return len(self.m)

    @property
    def is_linear(self) -> bool:
        return all(hi == 0.0 for hi in self.h)

    @property
    def is_forced(self) -> bool:
        return self.F != 0.0


@dataclass(frozen=True)
class Scales:
    """Units of a problem relative to the dimensionless form of ``MODEL.md``.

    A quantity in problem units divided by its scale is dimensionless:
    ``tau = t / time``, ``x_bar = x / length``, ``v_bar = v / velocity``.
    """

    length: float = 1.0
    time: float = 1.0
    force: float = 1.0

    @property
    def velocity(self) -> float:
        return self.length / self.time

    @property
    def is_identity(self) -> bool:
        return self.length == 1.0 and self.time == 1.0 and self.force == 1.0


@dataclass(frozen=True)
class Bound:
    """Allowed range of one parameter: ``value > lower`` (or ``>=`` if inclusive)."""

    lower: float
    inclusive: bool
    meaning: str

    def describe(self) -> str:
        op = ">=" if self.inclusive else ">"
        return f"{self.meaning} must be {op} {self.lower:g}"

    def admits(self, value: float) -> bool:
        return value >= self.lower if self.inclusive else value > self.lower


_POS = lambda meaning: Bound(0.0, False, meaning)  # noqa: E731
_NONNEG = lambda meaning: Bound(0.0, True, meaning)  # noqa: E731

# Allowed ranges, by parameter name (shared between problems where names coincide).
BOUNDS: dict[str, Bound] = {
    # dimensional
    "m": _POS("mass"),
    "m1": _POS("mass m1"),
    "m2": _POS("mass m2"),
    "k": _POS("stiffness"),
    "k1": _POS("stiffness k1"),
    "k2": _POS("stiffness k2"),
    "c": _NONNEG("damping"),
    "c1": _NONNEG("damping c1"),
    "c2": _NONNEG("damping c2"),
    "h": _NONNEG("cubic stiffness (hardening only)"),
    "h1": _NONNEG("cubic stiffness h1 (hardening only)"),
    "h2": _NONNEG("cubic stiffness h2 (hardening only)"),
    "fs": _NONNEG("kinetic friction"),
    "fs1": _NONNEG("kinetic friction fs1"),
    "fs2": _NONNEG("kinetic friction fs2"),
    "fr": _POS("static friction"),
    "fr1": _POS("static friction fr1"),
    "fr2": _POS("static friction fr2"),
    "F": _NONNEG("harmonic force amplitude"),
    "w": _NONNEG("forcing frequency"),
    "v0": _NONNEG("belt speed"),
    # dimensionless
    "kappa": _POS("stiffness ratio kappa"),
    "mu": _POS("mass ratio mu"),
    "rho2": _POS("static friction ratio rho2"),
    "rf1": _NONNEG("slip friction level rf1"),
    "rf2": _NONNEG("slip friction level rf2"),
    "r_f": _NONNEG("slip friction level r_f"),
    "Omega": _NONNEG("forcing frequency Omega"),
    "omega_r": _POS("frequency ratio omega_r"),
    "inv_omega_r": _POS("inverse frequency ratio inv_omega_r"),
}

# Names accepted by each (problem, units) pair, in display order.
TWO_DOF_DIMENSIONLESS = ("c1", "c2", "kappa", "mu", "h1", "h2", "rho2", "rf1", "rf2", "F", "Omega", "v0")
TWO_DOF_SHORTHANDS = ("r_f", "omega_r", "inv_omega_r")
TWO_DOF_DIMENSIONAL = ("m1", "m2", "c1", "c2", "k1", "k2", "h1", "h2", "fs1", "fs2", "fr1", "fr2", "F", "w", "v0")
ONE_DOF_DIMENSIONLESS = ("c", "h", "r_f", "F", "Omega", "v0")
ONE_DOF_DIMENSIONAL = ("m", "c", "k", "h", "fs", "fr", "F", "w", "v0")

# Table 3 of the paper, exact conversion (MODEL.md section 2).
TABLE3_DIMENSIONAL_TWO_DOF = dict(
    m1=1.0,
    m2=1.0,
    c1=0.05,
    c2=0.05,
    k1=1.0,
    k2=1.0,
    h1=0.1,
    h2=0.1,
    fs1=2.0,
    fs2=2.0,
    fr1=2.4,
    fr2=2.4,
    F=1.0,
    w=1.0,
    v0=0.2,
)
TABLE3_DIMENSIONLESS_TWO_DOF = dict(
    c1=0.05,
    c2=0.05,
    kappa=1.0,
    mu=1.0,
    h1=0.576,
    h2=0.576,
    rho2=1.0,
    rf1=5.0 / 6.0,
    rf2=5.0 / 6.0,
    F=5.0 / 12.0,
    Omega=1.0,
    v0=1.0 / 12.0,
)
TABLE3_DIMENSIONAL_ONE_DOF = dict(m=1.0, c=0.05, k=1.0, h=0.1, fs=2.0, fr=2.4, F=1.0, w=1.0, v0=0.2)
TABLE3_DIMENSIONLESS_ONE_DOF = dict(c=0.05, h=0.576, r_f=5.0 / 6.0, F=5.0 / 12.0, Omega=1.0, v0=1.0 / 12.0)


def check_case(problem: str, case: object) -> int:
    """Return ``case`` as an int in 1..4, or raise a ``ConfigError`` naming it."""
    value = None
    if isinstance(case, int) and not isinstance(case, bool):
        value = case
    elif isinstance(case, str) and case.strip().isdigit():
        value = int(case)
    if value not in CASES:
        raise ConfigError(
            f"{problem}: unknown case {case!r}; allowed: " + ", ".join(f"{c} ({CASE_DESCRIPTIONS[c]})" for c in CASES)
        )
    return value


def apply_case(defaults: Mapping[str, float], case: int, cubic: tuple[str, ...]) -> dict[str, float]:
    """Table 3 values with the case's switches: no cubic term (1, 2), no force (1, 3)."""
    values = dict(defaults)
    if case in (1, 2):
        for name in cubic:
            values[name] = 0.0
    if case in (1, 3):
        values["F"] = 0.0
    return values


def check_values(
    problem: str, params: Mapping[str, object], allowed: tuple[str, ...], bounds: Mapping[str, Bound] | None = None
) -> dict[str, float]:
    """Reject unknown names and non-finite or out-of-range values; return floats.

    ``bounds`` gives the allowed range of each name (default :data:`BOUNDS`).

    Raises
    ------
    ConfigError
        Naming the first bad parameter and its allowed range.
    """
    out: dict[str, float] = {}
    for name, raw in params.items():
        if name not in allowed:
            raise ConfigError(f"{problem}: unknown parameter {name!r}; allowed: {', '.join(allowed)}")
        if isinstance(raw, bool):
            raise ConfigError(f"{problem}: parameter {name} = {raw!r} must be a real number")
        try:
            value = float(raw)  # type: ignore[arg-type]
        except (TypeError, ValueError):
            raise ConfigError(f"{problem}: parameter {name} = {raw!r} is not a number") from None
        if not math.isfinite(value):
            raise ConfigError(f"{problem}: parameter {name} = {value} is not allowed: it must be a finite real number")
        bound = (BOUNDS if bounds is None else bounds)[name]
        if not bound.admits(value):
            raise ConfigError(f"{problem}: parameter {name} = {value:g} is out of range: {bound.describe()}")
        out[name] = value
    return out


def check_friction_order(problem: str, kinetic: str, fs: float, static: str, fr: float) -> None:
    """Kinetic friction may not exceed the static limit (``fs <= fr``)."""
    if fs > fr:
        raise ConfigError(
            f"{problem}: parameter {kinetic} = {fs:g} is out of range: kinetic friction "
            f"{kinetic} must be <= static friction {static} = {fr:g}"
        )


def pi_groups_two_dof(
    m1: float,
    m2: float,
    c1: float,
    c2: float,
    k1: float,
    k2: float,
    h1: float,
    h2: float,
    fs1: float,
    fs2: float,
    fr1: float,
    fr2: float,
    F: float,
    w: float,
    v0: float,
) -> dict[str, float]:
    """Buckingham-pi groups of the 2-DOF oscillator (MODEL.md section 2).

    Scales: force ``fr1``, length ``fr1 / k1``, time ``sqrt(m1 / k1)``.
    """
    root = math.sqrt(k1 * m1)
    return dict(
        c1=c1 / root,
        c2=c2 / root,
        kappa=k2 / k1,
        mu=m2 / m1,
        h1=h1 * fr1**2 / k1**3,
        h2=h2 * fr1**2 / k1**3,
        rho2=fr2 / fr1,
        rf1=fs1 / fr1,
        rf2=fs2 / fr1,
        F=F / fr1,
        Omega=w * math.sqrt(m1 / k1),
        v0=v0 * root / fr1,
    )


def pi_groups_one_dof(
    m: float, c: float, k: float, h: float, fs: float, fr: float, F: float, w: float, v0: float
) -> dict[str, float]:
    """Buckingham-pi groups of the 1-DOF oscillator (MODEL.md section 4)."""
    root = math.sqrt(k * m)
    return dict(c=c / root, h=h * fr**2 / k**3, r_f=fs / fr, F=F / fr, Omega=w * math.sqrt(m / k), v0=v0 * root / fr)


def scales_of(m1: float, k1: float, fr1: float) -> Scales:
    """Scales that make a dimensional problem dimensionless (block 1 sets them)."""
    return Scales(length=fr1 / k1, time=math.sqrt(m1 / k1), force=fr1)
