"""The 1-DOF dry-friction oscillator of MODEL.md section 4.

Case presets mirror the 2-DOF ones: 1 is the standard scenario (linear, unforced,
``c = 0.05, r_f = 5/6, v0 = 1/12``), 2 adds the force ``F = 5/12, Omega = 1``, 3 the
cubic spring ``h = 0.576``, 4 both.
"""

from __future__ import annotations

from nsbench.errors import ConfigError
from nsbench.problems.oscillator import FrictionOscillator, split_start
from nsbench.problems.parameters import (
    ONE_DOF_DIMENSIONAL,
    ONE_DOF_DIMENSIONLESS,
    TABLE3_DIMENSIONAL_ONE_DOF,
    TABLE3_DIMENSIONLESS_ONE_DOF,
    Coefficients,
    Scales,
    apply_case,
    check_case,
    check_friction_order,
    check_values,
    scales_of,
)

NAME = "one-dof"


def one_dof(case: int | str | None = None, dimensional: bool = False, **params: float) -> FrictionOscillator:
    """Build the 1-DOF oscillator ``m x'' + c x' + k x + h x^3 = f + F cos(w t)``.

    Parameters
    ----------
    case
        1..4 as for ``two-dof`` (default 1, the standard scenario).
    dimensional
        If true, ``params`` are ``m c k h fs fr F w v0``; otherwise the
        dimensionless ``c h r_f F Omega v0``.
    **params
        Parameter overrides on top of the case preset.

    Raises
    ------
    ConfigError
        Unknown case or parameter name, non-finite or out-of-range value,
        kinetic friction above the static limit.
    """
    case_n = check_case(NAME, 1 if case is None else case)
    user = dict(params)
    params, y0, start = split_start(NAME, params, 1)
    if dimensional:
        given = check_values(NAME, params, ONE_DOF_DIMENSIONAL)
        v = apply_case(TABLE3_DIMENSIONAL_ONE_DOF, case_n, ("h",))
        v.update(given)
        check_friction_order(NAME, "fs", v["fs"], "fr", v["fr"])
        coeffs = Coefficients(
            m=(v["m"],), c=(v["c"],), k=(v["k"],), h=(v["h"],), fs=(v["fs"],), fr=(v["fr"],),
            F=v["F"], w=v["w"], v0=v["v0"],
        )
        scales = scales_of(v["m"], v["k"], v["fr"])
    else:
        given = check_values(NAME, params, ONE_DOF_DIMENSIONLESS)
        v = apply_case(TABLE3_DIMENSIONLESS_ONE_DOF, case_n, ("h",))
        v.update(given)
        if v["r_f"] > 1.0:
            raise ConfigError(
                f"{NAME}: parameter r_f = {v['r_f']:g} is out of range: the slip friction level "
                "r_f = fs/fr must be <= 1 (kinetic friction cannot exceed static)"
            )
        coeffs = Coefficients(
            m=(1.0,), c=(v["c"],), k=(1.0,), h=(v["h"],), fs=(v["r_f"],), fr=(1.0,),
            F=v["F"], w=v["Omega"], v0=v["v0"],
        )
        scales = Scales()
    return FrictionOscillator(
        coeffs, name=NAME, case=case_n, dimensional=dimensional,
        params=user, parameters={**dict(v), **start}, scales=scales, y0=y0,
    )
