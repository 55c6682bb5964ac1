"""The 1-DOF dry-friction oscillator of MODEL.md section 4.

Case presets mirror the 2-DOF ones: 1 is the standard scenario (linear, unforced,
``c = 0.05, r_f = 5/6, v0 = 1/12``), 2 adds the force ``F = 5/12, Omega = 1``, 3 the
cubic spring ``h = 0.576``, 4 both. The preset ``leine`` is Leine's belt
oscillator (Leine, van Campen, de Kraker and van den Steen, Nonlinear Dynamics 16
(1998) 41-54): ``m = k = fs = fr = 1``, no damping, belt speed 0.2 and the
weakening law ``fs / (1 + delta |v_rel|)`` with ``delta = 3``. With ``m = k = fr =
1`` the scales of MODEL.md are all 1, so the dimensionless and the dimensional
forms have the same numbers (``r_f = 1``, ``v0 = 0.2``, ``delta = 3``).
"""

from __future__ import annotations

from typing import Any

from nsbench.errors import ConfigError
from nsbench.problems.friction_laws import check_against_blocks, split_law
from nsbench.problems.oscillator import FrictionOscillator, split_start
from nsbench.problems.parameters import (
    CASES,
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
LEINE = "leine"
#: Leine's belt oscillator, dimensionless (every scale is 1 here) and dimensional.
LEINE_DIMENSIONLESS = dict(c=0.0, h=0.0, r_f=1.0, F=0.0, Omega=1.0, v0=0.2)
LEINE_DIMENSIONAL = dict(m=1.0, c=0.0, k=1.0, h=0.0, fs=1.0, fr=1.0, F=0.0, w=1.0, v0=0.2)
LEINE_LAW = {"law": "weakening", "delta": 3.0}


def _preset(case, dimensional: bool) -> tuple[int | str, dict[str, float], dict[str, object]]:
    """``(case, base values, law parameters)`` of a case 1..4 or ``'leine'``."""
    if isinstance(case, str) and case.strip().lower() == LEINE:
        return LEINE, dict(LEINE_DIMENSIONAL if dimensional else LEINE_DIMENSIONLESS), dict(LEINE_LAW)
    try:
        case_n = check_case(NAME, 1 if case is None else case)
    except ConfigError as exc:
        raise ConfigError(f"{exc}, or {LEINE!r} (Leine's belt oscillator)") from None
    table = TABLE3_DIMENSIONAL_ONE_DOF if dimensional else TABLE3_DIMENSIONLESS_ONE_DOF
    return case_n, apply_case(table, case_n, ("h",)), {}


def one_dof(case: int | str | None = None, dimensional: bool = False, **params: Any) -> FrictionOscillator:
    """Build the 1-DOF oscillator ``m x'' + c x' + k x + h x^3 = f + F cos(w t)``.

    Parameters
    ----------
    case
        1..4 as for ``two-dof`` (default 1, the standard scenario), or ``'leine'``
        (Leine's belt oscillator: the weakening law, see the module docstring).
    dimensional
        If true, ``params`` are ``m c k h fs fr F w v0``; otherwise the
        dimensionless ``c h r_f F Omega v0``.
    **params
        Parameter overrides on top of the case preset; ``law`` (``coulomb``,
        ``weakening``, ``stribeck``) and its parameters pick the friction law
        (:mod:`nsbench.problems.friction_laws`).

    Raises
    ------
    ConfigError
        Unknown case or parameter name, non-finite or out-of-range value,
        kinetic friction above the static limit.
    """
    case_n, v, law_preset = _preset(case, dimensional)
    user = dict(params)
    if law_preset and "law" not in params:
        params = {**law_preset, **params}
    params, law = split_law(NAME, params)
    params, y0, start = split_start(NAME, params, 1)
    if dimensional:
        given = check_values(NAME, params, ONE_DOF_DIMENSIONAL)
        v.update(given)
        check_friction_order(NAME, "fs", v["fs"], "fr", v["fr"])
        coeffs = Coefficients(
            m=(v["m"],),
            c=(v["c"],),
            k=(v["k"],),
            h=(v["h"],),
            fs=(v["fs"],),
            fr=(v["fr"],),
            F=v["F"],
            w=v["w"],
            v0=v["v0"],
        )
        scales = scales_of(v["m"], v["k"], v["fr"])
    else:
        given = check_values(NAME, params, ONE_DOF_DIMENSIONLESS)
        v.update(given)
        if v["r_f"] > 1.0:
            raise ConfigError(
                f"{NAME}: parameter r_f = {v['r_f']:g} is out of range: the slip friction level "
                "r_f = fs/fr must be <= 1 (kinetic friction cannot exceed static)"
            )
        coeffs = Coefficients(
            m=(1.0,),
            c=(v["c"],),
            k=(1.0,),
            h=(v["h"],),
            fs=(v["r_f"],),
            fr=(1.0,),
            F=v["F"],
            w=v["Omega"],
            v0=v["v0"],
        )
        scales = Scales()
    check_against_blocks(NAME, law, coeffs.fs, "fs" if dimensional else "r_f")
    return FrictionOscillator(
        coeffs,
        name=NAME,
        case=case_n,
        dimensional=dimensional,
        params=user,
        parameters={**dict(v), **law.parameters(), **start},
        scales=scales,
        y0=y0,
        law=law,
        cases=(*CASES, LEINE),
    )
