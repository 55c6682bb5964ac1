"""Friction laws of a slipping block, by name: ``coulomb``, ``weakening``, ``stribeck`` (no numba here).

A slipping block of phase ``s = sign(v - v0)`` feels the friction force
``-s S(u)``, where ``u = s (v - v0) = |v - v0|`` is its slip speed and ``S`` the
law's slip level:

- ``coulomb``: ``S = fs`` (the default; the piecewise-linear problems of MODEL.md);
- ``weakening``: ``S = fs / (1 + delta u)`` (Leine, van Campen, de Kraker and van den Steen,
  Nonlinear Dynamics 16 (1998) 41-54, the belt oscillator's law), ``delta >= 0``;
- ``stribeck``: ``S = fk + (fs - fk) exp(-(u / vs)^2) + cv u``, ``0 <= fk <= fs``, ``vs > 0``,
  ``cv >= 0`` (a Stribeck curve with a Gaussian decay and an optional viscous term).

Every law starts from ``S(0) = fs``; the static limit ``fr`` is the same in every
law (a stuck block stays stuck while ``|R| <= fr``). The compiled form, which the
core, the numpy functions, SUNDIALS and scipy use, is
:func:`nsbench.problems.friction_law.slip_level`; :func:`slip_level` here is the
same formula in any arithmetic (heyoka's expressions), tested equal to it.
Parameters are in the problem's units: for the dimensionless presets ``fk`` is in
units of the static limit ``fr_1`` (like ``r_f``), ``vs`` in the velocity scale
``fr_1 / sqrt(m1 k1)``, ``delta`` in its inverse and ``cv`` in ``sqrt(m1 k1)``
(like the damping ``c``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Callable, Mapping, Sequence

from nsbench.errors import ConfigError
from nsbench.problems.friction_spec import COULOMB, LAW_NAMES, STRIBECK, WEAKENING

#: The law parameters each law takes (the problems' ``law`` parameter picks the law).
LAW_PARAMETERS = {"coulomb": (), "weakening": ("delta",), "stribeck": ("fk", "vs", "cv")}
ALL_PARAMETERS = ("law", "delta", "fk", "vs", "cv")
#: Defaults of the optional ones (``delta``, ``fk`` and ``vs`` must be given with their law).
OPTIONAL = {"cv": 0.0}


@dataclass(frozen=True)
class FrictionLaw:
    """A friction law and its parameters (the same for every block).

    Attributes
    ----------
    name
        ``'coulomb'``, ``'weakening'`` or ``'stribeck'``.
    delta, fk, vs, cv
        The law's parameters (unused ones hold neutral values: ``delta = 0``,
        ``fk = None`` meaning ``fs``, ``vs = 1``, ``cv = 0``).
    """

    name: str = "coulomb"
    delta: float = 0.0
    fk: float | None = None
    vs: float = 1.0
    cv: float = 0.0

    @property
    def code(self) -> int:
        return LAW_NAMES.index(self.name)

    @property
    def is_coulomb(self) -> bool:
        return self.name == "coulomb"

    def parameters(self) -> dict[str, Any]:
        """The law and its own parameters by name (empty for Coulomb, which the problems leave implicit)."""
        if self.is_coulomb:
            return {}
        return {"law": self.name, **{k: getattr(self, k) for k in LAW_PARAMETERS[self.name]}}

    def fields(self, fs: Sequence[float]) -> dict[str, tuple[float, ...]]:
        """The per-block slots of the parameter vector (``fk`` defaults to each block's ``fs``)."""
        n = len(fs)
        fk = tuple(fs) if self.fk is None else (self.fk,) * n
        return {"fk": fk, "delta": (self.delta,) * n, "vs": (self.vs,) * n, "cv": (self.cv,) * n}

    def describe(self) -> str:
        if self.is_coulomb:
            return "coulomb"
        return f"{self.name} ({', '.join(f'{k} = {v:g}' for k, v in self.parameters().items() if k != 'law')})"


COULOMB_LAW = FrictionLaw()


def slip_level(
    code: int, u: Any, fs: Any, fk: Any, delta: Any, vs: Any, cv: Any, exp: Callable[[Any], Any] = math.exp
) -> Any:
    """``S(u)`` of the law ``code`` in any arithmetic (floats, numpy, heyoka expressions)."""
    if code == COULOMB:
        return fs
    if code == WEAKENING:
        return fs / (1.0 + delta * u)
    if code == STRIBECK:
        q = u / vs
        return fk + (fs - fk) * exp(-(q * q)) + cv * u
    raise ValueError(f"unknown friction law code {code!r}")


def _number(problem: str, name: str, raw: Any) -> float:
    if isinstance(raw, bool):
        raise ConfigError(f"{problem}: parameter {name} = {raw!r} must be a real number")
    try:
        value = float(raw)
    except (TypeError, ValueError):
        raise ConfigError(f"{problem}: parameter {name} = {raw!r} is not a number") from None
    if not math.isfinite(value):
        raise ConfigError(f"{problem}: parameter {name} = {value} is not allowed: it must be a finite real number")
    return value


def split_law(problem: str, params: Mapping[str, Any]) -> tuple[dict[str, Any], FrictionLaw]:
    """``(the other parameters, the friction law)`` from a problem's parameters.

    Refuses an unknown law, a law parameter given with a law that does not take
    it, a missing required one, and values out of range (``delta >= 0``,
    ``fk >= 0``, ``vs > 0``, ``cv >= 0``; NaN and infinities everywhere). ``fk <= fs``
    is checked by :func:`check_against_blocks` once the blocks' ``fs`` are known.
    """
    rest = {k: v for k, v in params.items() if k not in ALL_PARAMETERS}
    raw_name = params.get("law", "coulomb")
    name = raw_name.strip().lower() if isinstance(raw_name, str) else raw_name
    if name not in LAW_NAMES:
        raise ConfigError(
            f"{problem}: parameter law = {raw_name!r} is not a friction law; allowed: {', '.join(LAW_NAMES)}"
        )
    takes = LAW_PARAMETERS[name]
    given = {k: params[k] for k in ALL_PARAMETERS[1:] if k in params}
    for key in given:
        if key not in takes:
            users = [law for law, names in LAW_PARAMETERS.items() if key in names]
            raise ConfigError(
                f"{problem}: parameter {key} belongs to law={users[0]}, not law={name} "
                f"(law={name} takes {', '.join(takes) or 'no parameters'})"
            )
    missing = [k for k in takes if k not in given and k not in OPTIONAL]
    if missing:
        raise ConfigError(f"{problem}: law={name} needs the parameter(s) {', '.join(missing)}")
    values = {k: _number(problem, k, v) for k, v in given.items()}
    bounds = {
        "delta": (0.0, True, "the weakening rate delta"),
        "fk": (0.0, True, "the high-speed level fk"),
        "vs": (0.0, False, "the Stribeck speed vs"),
        "cv": (0.0, True, "the viscous coefficient cv"),
    }
    for key, value in values.items():
        lower, inclusive, meaning = bounds[key]
        if value < lower or (value == lower and not inclusive):
            op = ">=" if inclusive else ">"
            raise ConfigError(
                f"{problem}: parameter {key} = {value:g} is out of range: {meaning} must be {op} {lower:g}"
            )
    if name == "coulomb":
        return rest, COULOMB_LAW
    if name == "weakening":
        return rest, FrictionLaw(name, delta=values["delta"])
    return rest, FrictionLaw(name, fk=values["fk"], vs=values["vs"], cv=values.get("cv", OPTIONAL["cv"]))


def check_against_blocks(problem: str, law: FrictionLaw, fs: Sequence[float], fs_name: str = "fs") -> None:
    """The Stribeck level at high speed may not exceed any block's slip level at rest (``fk <= fs``)."""
    if law.fk is None:
        return
    for i, level in enumerate(fs):
        if law.fk > level:
            which = fs_name if len(fs) == 1 else f"{fs_name} of block {i + 1}"
            raise ConfigError(
                f"{problem}: parameter fk = {law.fk:g} is out of range: the high-speed level fk "
                f"must be <= the slip level at rest {which} = {level:g}"
            )
