"""``block-on-ground``: a 1-DOF Coulomb oscillator on fixed ground, unforced or under a harmonic force.

``m x'' + c x' + k x = f + F cos(w t)`` with ``|f| <= fr`` while stuck and
``f = -fs sign(x')`` while slipping, the friction family with a belt that does not
move (``v0 = 0``). The defaults are those of the Siconos ``FrictionOscillator``
example (INRIA): ``m = k = 1``, ``c = 0``, ``fs = fr = 1``, no force (``F = 0``),
from ``x(0) = 12``, ``x'(0) = 6``.

Undamped and unforced, each slip is half a period (``pi sqrt(m / k)``) of a harmonic
oscillation about ``-+ fs / k``, so the amplitude about the origin falls by ``2 fs
/ k`` at every velocity reversal; the block sticks at the first reversal where
``|k x| <= fr`` and never slips again. :func:`closed_form_events` gives every event
time, the rest time and the rest position. With ``F > fr`` the force breaks a stuck
block away again and the motion settles on a cycle of sticks and slips (Den Hartog's
forced Coulomb oscillator), the natural test of time-stepping on stick-slip cycles;
``exact`` solves it (the force is the one of the belt problems' forced cases, on the
block itself).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from nsbench.errors import ConfigError
from nsbench.problems.friction_laws import ALL_PARAMETERS, check_against_blocks, split_law
from nsbench.problems.oscillator import FrictionOscillator, split_start
from nsbench.problems.parameters import Bound, Coefficients, check_friction_order, check_values, scales_of

NAME = "block-on-ground"
DEFAULTS = {"m": 1.0, "c": 0.0, "k": 1.0, "fs": 1.0, "fr": 1.0, "F": 0.0, "w": 1.0}
START = {"x1_0": 12.0, "v1_0": 6.0}
BOUNDS = {
    "m": Bound(0.0, False, "mass m"),
    "c": Bound(0.0, True, "damping c"),
    "k": Bound(0.0, False, "stiffness k"),
    "fs": Bound(0.0, True, "kinetic friction fs"),
    "fr": Bound(0.0, False, "static friction fr"),
    "F": Bound(0.0, True, "harmonic force amplitude F"),
    "w": Bound(0.0, True, "forcing frequency w"),
}
#: Every name the problem takes, for the error message of an unknown one (the start and the law's
#: names are split off before the coefficients are checked).
ALLOWED = (*DEFAULTS, *START, *ALL_PARAMETERS)


def block_on_ground(case: int | str | None = None, dimensional: bool = True, **params: Any) -> FrictionOscillator:
    """Build the block on fixed ground (parameters ``m c k fs fr F w``, start ``x1_0``, ``v1_0``).

    The parameters are in the problem's own units (there are no cases and no
    dimensionless presets; ``dimensional`` is ignored). ``F`` and ``w`` are the
    amplitude and the angular frequency of the harmonic force ``F cos(w t)`` on the
    block (default ``F = 0``: unforced).
    ``law`` and its parameters set the friction law (:mod:`nsbench.problems.friction_laws`;
    default Coulomb, whose closed form :func:`closed_form_events` gives).

    Raises
    ------
    ConfigError
        A case, an unknown parameter, a non-finite or out-of-range value, ``fs > fr``.
    """
    if case not in (None, 1, "1"):
        raise ConfigError(f"{NAME}: unknown case {case!r}; the problem has no cases (give its parameters)")
    rest, law = split_law(NAME, params)
    rest, _, start = split_start(NAME, rest, 1)
    unknown = [key for key in rest if key not in DEFAULTS]
    if unknown:  # named here, not by check_values, so that the message lists the start and the law too
        raise ConfigError(f"{NAME}: unknown parameter {unknown[0]!r}; allowed: {', '.join(ALLOWED)}")
    v = {**DEFAULTS, **check_values(NAME, rest, tuple(DEFAULTS), BOUNDS)}
    check_friction_order(NAME, "fs", v["fs"], "fr", v["fr"])
    y0 = np.array([start.get("x1_0", START["x1_0"]), start.get("v1_0", START["v1_0"])])
    coeffs = Coefficients(
        m=(v["m"],), c=(v["c"],), k=(v["k"],), h=(0.0,), fs=(v["fs"],), fr=(v["fr"],), F=v["F"], w=v["w"], v0=0.0
    )
    check_against_blocks(NAME, law, coeffs.fs)
    return FrictionOscillator(
        coeffs,
        name=NAME,
        case=None,
        dimensional=True,
        params=dict(params),
        parameters={**v, **law.parameters(), "x1_0": float(y0[0]), "v1_0": float(y0[1])},
        scales=scales_of(v["m"], v["k"], v["fr"]),
        y0=y0,
        law=law,
    )


def closed_form_events(problem: FrictionOscillator) -> tuple[list[tuple[float, str]], float]:
    """``([(t, kind)], rest position)`` of the undamped block on ground, in closed form.

    Each slip of sign ``s`` is the oscillation ``x = x_c + A cos(omega t + phi)`` about
    ``x_c = -s fs / k`` with ``omega = sqrt(k / m)``; it ends when ``v = 0``, half a
    period after the previous reversal (the first after the start's own phase).
    """
    c = problem.coefficients
    if c.c[0] != 0.0 or c.v0 != 0.0 or c.F != 0.0 or not problem.law_spec.is_coulomb:
        raise ValueError("the closed form is for the undamped, unforced block on fixed ground with Coulomb friction")
    m, k, fs, fr = c.m[0], c.k[0], c.fs[0], c.fr[0]
    omega = math.sqrt(k / m)
    x, v = (float(a) for a in problem.initial_state())
    if v == 0.0:
        raise ValueError("the closed form starts from a moving block (v != 0)")
    s = 1.0 if v > 0.0 else -1.0
    center = -s * fs / k
    amp = math.hypot(x - center, v / omega)
    # phase: x - center = amp cos(theta), v = -amp omega sin(theta); the reversal at theta = 0 (mod pi)
    theta0 = math.atan2(-v / omega, x - center)
    t = (-theta0 if s > 0 else math.pi - theta0) / omega  # first time theta reaches 0 (v > 0) or pi (v < 0)
    events = []
    while True:
        x = center + s * amp  # the extreme reached, where v = 0
        if abs(k * x) <= fr:
            events.append((t, "stick"))
            return events, x
        events.append((t, "reverse"))
        s = -s
        center = -s * fs / k
        amp = abs(x - center)
        t += math.pi / omega
