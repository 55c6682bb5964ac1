"""The N-block friction chain of MODEL.md section 7: ``n`` blocks on one belt.

Block 1 is tied to the ground, block ``i`` to block ``i - 1``; the harmonic force
acts on the last block. Parameters are given uniformly by the names of the 2-DOF
problem without an index (``c kappa mu h rho r_f F Omega v0``; dimensional ``m c
k h fs fr F w v0``) and per block with the block's index appended (``c3``,
``kappa3``, ``mu3``, ``h3``, ``rho3``, ``rf3``; dimensional ``m3``, ``c3``, ``k3``,
``h3``, ``fs3``, ``fr3``); a per-block value overrides the uniform one. ``n`` is
the number of blocks (1 to :data:`MAX_BLOCKS`). With ``n = 2`` the problem is the
2-DOF oscillator, with ``n = 1`` the 1-DOF one, coefficient for coefficient.
"""

from __future__ import annotations

import math
import re
from typing import Any

from nsbench.errors import ConfigError
from nsbench.problems.friction_laws import check_against_blocks, split_law
from nsbench.problems.oscillator import FrictionOscillator, split_start
from nsbench.problems.parameters import (
    CASES,
    Bound,
    Coefficients,
    Scales,
    check_case,
    check_friction_order,
    check_values,
)

NAME = "chain"
MAX_BLOCKS = 64
DEFAULT_BLOCKS = 4

#: uniform dimensionless names (MODEL.md section 7) and the per-block stems
UNIFORM_DIMENSIONLESS = ("c", "kappa", "mu", "h", "rho", "r_f", "F", "Omega", "v0")
PER_BLOCK_DIMENSIONLESS = ("c", "kappa", "mu", "h", "rho", "rf")
UNIFORM_DIMENSIONAL = ("m", "c", "k", "h", "fs", "fr", "F", "w", "v0")
PER_BLOCK_DIMENSIONAL = ("m", "c", "k", "h", "fs", "fr")
#: block 1 sets the scales: these are 1 by definition in the dimensionless form
FIXED_BY_SCALES = ("kappa1", "mu1", "rho1")

# Table 3 of the paper for every block (MODEL.md sections 3 and 7)
TABLE3_DIMENSIONLESS = dict(
    c=0.05, kappa=1.0, mu=1.0, h=0.576, rho=1.0, r_f=5.0 / 6.0, F=5.0 / 12.0, Omega=1.0, v0=1.0 / 12.0
)
TABLE3_DIMENSIONAL = dict(m=1.0, c=0.05, k=1.0, h=0.1, fs=2.0, fr=2.4, F=1.0, w=1.0, v0=0.2)

#: allowed range of every stem: (lower, inclusive, meaning)
_STEM_BOUNDS = {
    "m": (0.0, False, "mass"),
    "k": (0.0, False, "stiffness"),
    "c": (0.0, True, "damping"),
    "h": (0.0, True, "cubic stiffness (hardening only)"),
    "fs": (0.0, True, "kinetic friction"),
    "fr": (0.0, False, "static friction"),
    "kappa": (0.0, False, "stiffness ratio"),
    "mu": (0.0, False, "mass ratio"),
    "rho": (0.0, False, "static friction ratio"),
    "rf": (0.0, True, "slip friction level"),
    "r_f": (0.0, True, "slip friction level r_f"),
    "F": (0.0, True, "harmonic force amplitude"),
    "w": (0.0, True, "forcing frequency"),
    "Omega": (0.0, True, "forcing frequency Omega"),
    "v0": (0.0, True, "belt speed"),
}
_PER_BLOCK = re.compile(r"^([a-z]+?)(\d+)$")
#: per-block stem -> the uniform name it overrides
_UNIFORM_OF = {"rf": "r_f"}


def check_n(n: Any) -> int:
    """The number of blocks as an int in 1..:data:`MAX_BLOCKS`, or a ``ConfigError`` naming it."""
    value = None
    if isinstance(n, bool):
        value = None
    elif isinstance(n, int):
        value = n
    elif isinstance(n, float) and math.isfinite(n) and n == int(n):
        value = int(n)
    elif isinstance(n, str) and n.strip().isdigit():
        value = int(n)
    if value is None or not 1 <= value <= MAX_BLOCKS:
        raise ConfigError(
            f"{NAME}: parameter n = {n!r} is not allowed: the number of blocks must be "
            f"an integer from 1 to {MAX_BLOCKS}"
        )
    return value


def _split_names(
    params: dict[str, Any], n: int, uniform: tuple[str, ...], stems: tuple[str, ...], dimensional: bool
) -> tuple[dict[str, Any], dict[int, dict[str, Any]]]:
    """Uniform values and per-block overrides (block index from 1), with clear errors for bad names."""
    uniform_values: dict[str, Any] = {}
    per_block: dict[int, dict[str, Any]] = {}
    allowed = f"{', '.join(uniform)}; per block {', '.join(s + 'I' for s in stems)} with I = 1..{n}"
    for name, value in params.items():
        if name in uniform:
            uniform_values[name] = value
            continue
        match = _PER_BLOCK.match(name)
        if match and match.group(1) in stems:
            block = int(match.group(2))
            if not 1 <= block <= n:
                raise ConfigError(
                    f"{NAME}: parameter {name!r} names block {block}, but the chain has n = {n} blocks (1..{n})"
                )
            if not dimensional and name in FIXED_BY_SCALES:
                raise ConfigError(
                    f"{NAME}: parameter {name!r} is 1 by definition (block 1 sets the "
                    "scales of the dimensionless form); change the other blocks instead"
                )
            per_block.setdefault(block, {})[match.group(1)] = value
            continue
        raise ConfigError(f"{NAME}: unknown parameter {name!r}; allowed: {allowed}")
    return uniform_values, per_block


def _bounds(names: list[str]) -> dict[str, Bound]:
    """The allowed range of each given name, from the range of its stem."""
    out = {}
    for name in names:
        match = None if name in _STEM_BOUNDS else _PER_BLOCK.match(name)
        stem, block = (match.group(1), match.group(2)) if match else (name, "")
        lower, inclusive, meaning = _STEM_BOUNDS[stem]
        out[name] = Bound(lower, inclusive, f"{meaning} {name}".strip() if block else meaning)
    return out


def chain(
    case: int | str | None = None, dimensional: bool = False, n: Any = DEFAULT_BLOCKS, **params: float
) -> FrictionOscillator:
    """Build the N-block friction chain from a case preset and parameter overrides.

    Parameters
    ----------
    case
        1..4 (MODEL.md section 3) for every block: 1 linear unforced, 2 linear
        forced, 3 cubic unforced (every ``h_i = 0.576``), 4 cubic forced. Default 1.
    dimensional
        If true, ``params`` are dimensional (``m c k h fs fr F w v0`` for every
        block, ``m3 c3 k3 h3 fs3 fr3`` for one); otherwise the dimensionless
        groups (``c kappa mu h rho r_f F Omega v0`` for every block, ``c3 kappa3
        mu3 h3 rho3 rf3`` for one; ``kappa1 = mu1 = rho1 = 1``).
    n
        Number of blocks, 1 to 64 (default 4).
    **params
        Parameter overrides; a per-block value wins over the uniform one.
        ``law`` (``coulomb``, ``weakening``, ``stribeck``) and its parameters
        (``delta``; ``fk``, ``vs``, ``cv``) set the friction law of every block
        (:mod:`nsbench.problems.friction_laws`).

    Raises
    ------
    ConfigError
        Bad ``n``, unknown case or parameter name, a block index outside
        ``1..n``, non-finite or out-of-range value, kinetic friction above the
        static limit of its block.
    """
    nb = check_n(n)
    case_n = check_case(NAME, 1 if case is None else case)
    user = {"n": nb, **params}
    params, law = split_law(NAME, params)
    params, y0, start = split_start(NAME, params, nb)
    uniform_names = UNIFORM_DIMENSIONAL if dimensional else UNIFORM_DIMENSIONLESS
    stems = PER_BLOCK_DIMENSIONAL if dimensional else PER_BLOCK_DIMENSIONLESS
    given_u, given_b = _split_names(dict(params), nb, uniform_names, stems, dimensional)
    given_u = check_values(NAME, given_u, tuple(given_u), _bounds(list(given_u)))
    flat = {f"{stem}{i}": v for i, values in given_b.items() for stem, v in values.items()}
    checked = check_values(NAME, flat, tuple(flat), _bounds(list(flat)))
    given_b = {i: {stem: checked[f"{stem}{i}"] for stem in values} for i, values in given_b.items()}
    base = dict(TABLE3_DIMENSIONAL if dimensional else TABLE3_DIMENSIONLESS)
    if case_n in (1, 2):
        base["h"] = 0.0
    if case_n in (1, 3):
        base["F"] = 0.0
    base.update(given_u)

    def per_block(stem: str, block: int) -> float:
        return given_b.get(block, {}).get(stem, base[_UNIFORM_OF.get(stem, stem)])

    blocks = range(1, nb + 1)
    if dimensional:
        m = tuple(per_block("m", i) for i in blocks)
        c = tuple(per_block("c", i) for i in blocks)
        k = tuple(per_block("k", i) for i in blocks)
        h = tuple(per_block("h", i) for i in blocks)
        fs = tuple(per_block("fs", i) for i in blocks)
        fr = tuple(per_block("fr", i) for i in blocks)
        for i in blocks:
            check_friction_order(NAME, f"fs{i}", fs[i - 1], f"fr{i}", fr[i - 1])
        coeffs = Coefficients(m=m, c=c, k=k, h=h, fs=fs, fr=fr, F=base["F"], w=base["w"], v0=base["v0"])
        scales = Scales(length=fr[0] / k[0], time=math.sqrt(m[0] / k[0]), force=fr[0])
    else:
        c = tuple(per_block("c", i) for i in blocks)
        k = (1.0,) + tuple(per_block("kappa", i) for i in blocks[1:])
        m = (1.0,) + tuple(per_block("mu", i) for i in blocks[1:])
        h = tuple(per_block("h", i) for i in blocks)
        rho = (1.0,) + tuple(per_block("rho", i) for i in blocks[1:])
        rf = tuple(per_block("rf", i) for i in blocks)
        for i in blocks:
            if rf[i - 1] > rho[i - 1]:
                name = f"rf{i}" if "rf" in given_b.get(i, {}) else "r_f"
                raise ConfigError(
                    f"{NAME}: parameter {name} = {rf[i - 1]:g} is out of range: the slip friction level "
                    f"rf{i} = fs{i}/fr1 must be <= rho{i} = {rho[i - 1]:g} (kinetic friction cannot "
                    "exceed static)"
                )
        coeffs = Coefficients(m=m, c=c, k=k, h=h, fs=rf, fr=rho, F=base["F"], w=base["Omega"], v0=base["v0"])
        scales = Scales()
    parameters: dict[str, float] = {"n": nb, **base}
    for i in blocks:
        stems_i = stems if dimensional else PER_BLOCK_DIMENSIONLESS
        for stem in stems_i:
            if not dimensional and f"{stem}{i}" in FIXED_BY_SCALES:
                parameters[f"{stem}{i}"] = 1.0
            else:
                parameters[f"{stem}{i}"] = per_block(stem, i)
    check_against_blocks(NAME, law, coeffs.fs, "fs" if dimensional else "rf")
    return FrictionOscillator(
        coeffs,
        name=NAME,
        case=case_n,
        dimensional=dimensional,
        params=user,
        parameters={**parameters, **law.parameters(), **start},
        scales=scales,
        y0=y0,
        law=law,
        cases=CASES,
    )
