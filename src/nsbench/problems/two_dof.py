"""The 2-DOF dry-friction oscillator of MODEL.md section 1, with the presets of cases 1-4."""

from __future__ import annotations

import math

from nsbench.errors import ConfigError
from nsbench.problems.friction_laws import check_against_blocks, split_law
from nsbench.problems.oscillator import FrictionOscillator, split_start
from nsbench.problems.parameters import (
    CASES,
    TABLE3_DIMENSIONAL_TWO_DOF,
    TABLE3_DIMENSIONLESS_TWO_DOF,
    TWO_DOF_DIMENSIONAL,
    TWO_DOF_DIMENSIONLESS,
    TWO_DOF_SHORTHANDS,
    Coefficients,
    Scales,
    apply_case,
    check_case,
    check_friction_order,
    check_values,
    scales_of,
)

NAME = "two-dof"


def _resolve_shorthands(given: dict[str, float]) -> dict[str, float]:
    """Expand ``r_f``, ``omega_r`` and ``inv_omega_r`` (MODEL.md conventions)."""
    out = dict(given)
    if "r_f" in out:
        clash = [n for n in ("rf1", "rf2") if n in out]
        if clash:
            raise ConfigError(f"{NAME}: parameter r_f sets rf1 and rf2 together; do not also give {', '.join(clash)}")
        out["rf1"] = out["rf2"] = out.pop("r_f")
    ratio_names = [n for n in ("omega_r", "inv_omega_r", "kappa") if n in out]
    if len(ratio_names) > 1:
        raise ConfigError(f"{NAME}: parameters {' and '.join(ratio_names)} all set the stiffness ratio; give only one")
    if "inv_omega_r" in out:
        out["omega_r"] = 1.0 / out.pop("inv_omega_r")
    if "omega_r" in out:
        # omega_r = sqrt(kappa / mu); the paper varies it through kappa with mu fixed.
        out["kappa"] = out.get("mu", 1.0) * out.pop("omega_r") ** 2
    return out


def two_dof(case: int | str | None = None, dimensional: bool = False, **params: float) -> FrictionOscillator:
    """Build the 2-DOF oscillator from a case preset and parameter overrides.

    Parameters
    ----------
    case
        1..4 (MODEL.md section 3): 1 linear unforced, 2 linear forced, 3 cubic
        unforced, 4 cubic forced. Default 1. Overrides apply on top of it.
    dimensional
        If true, ``params`` are dimensional (``m1 m2 c1 c2 k1 k2 h1 h2 fs1 fs2
        fr1 fr2 F w v0``) and the problem is integrated in those units;
        otherwise they are the dimensionless groups ``c1 c2 kappa mu h1 h2 rho2
        rf1 rf2 F Omega v0`` with shorthands ``r_f``, ``omega_r``, ``inv_omega_r``.
    **params
        Parameter overrides.
        ``law`` (``coulomb``, ``weakening``, ``stribeck``) and its parameters
        (``delta``; ``fk``, ``vs``, ``cv``) set the friction law of every block
        (:mod:`nsbench.problems.friction_laws`).

    Raises
    ------
    ConfigError
        Unknown case or parameter name, non-finite or out-of-range value,
        kinetic friction above the static limit, clashing shorthands.
    """
    case_n = check_case(NAME, 1 if case is None else case)
    user = dict(params)
    params, law = split_law(NAME, params)
    params, y0, start = split_start(NAME, params, 2)
    if dimensional:
        given = check_values(NAME, params, TWO_DOF_DIMENSIONAL)
        v = apply_case(TABLE3_DIMENSIONAL_TWO_DOF, case_n, ("h1", "h2"))
        v.update(given)
        check_friction_order(NAME, "fs1", v["fs1"], "fr1", v["fr1"])
        check_friction_order(NAME, "fs2", v["fs2"], "fr2", v["fr2"])
        coeffs = Coefficients(
            m=(v["m1"], v["m2"]),
            c=(v["c1"], v["c2"]),
            k=(v["k1"], v["k2"]),
            h=(v["h1"], v["h2"]),
            fs=(v["fs1"], v["fs2"]),
            fr=(v["fr1"], v["fr2"]),
            F=v["F"],
            w=v["w"],
            v0=v["v0"],
        )
        scales = scales_of(v["m1"], v["k1"], v["fr1"])
        parameters = v
    else:
        given = check_values(NAME, params, TWO_DOF_DIMENSIONLESS + TWO_DOF_SHORTHANDS)
        v = apply_case(TABLE3_DIMENSIONLESS_TWO_DOF, case_n, ("h1", "h2"))
        v.update(_resolve_shorthands(given))
        rf_name = "r_f" if "r_f" in given else "rf1"
        if v["rf1"] > 1.0:
            raise ConfigError(
                f"{NAME}: parameter {rf_name} = {v['rf1']:g} is out of range: the slip friction "
                "level rf1 = fs1/fr1 must be <= 1 (kinetic friction cannot exceed static)"
            )
        if v["rf2"] > v["rho2"]:
            rf_name = "r_f" if "r_f" in given else "rf2"
            raise ConfigError(
                f"{NAME}: parameter {rf_name} = {v['rf2']:g} is out of range: the slip friction "
                f"level rf2 = fs2/fr1 must be <= rho2 = {v['rho2']:g} (kinetic friction cannot exceed static)"
            )
        coeffs = Coefficients(
            m=(1.0, v["mu"]),
            c=(v["c1"], v["c2"]),
            k=(1.0, v["kappa"]),
            h=(v["h1"], v["h2"]),
            fs=(v["rf1"], v["rf2"]),
            fr=(1.0, v["rho2"]),
            F=v["F"],
            w=v["Omega"],
            v0=v["v0"],
        )
        scales = Scales()
        parameters = dict(v)
        parameters["omega_r"] = math.sqrt(v["kappa"] / v["mu"])
        parameters["inv_omega_r"] = 1.0 / parameters["omega_r"]
        if v["rf1"] == v["rf2"]:
            parameters["r_f"] = v["rf1"]
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
