"""``impact-oscillator``: a forced, damped oscillator hitting a rigid stop with Newton restitution.

``x'' + 2 zeta x' + x = F cos(w t)`` while ``x < sigma``; at ``x = sigma`` the
velocity is reset, ``v -> -r v``. A sequence of impacts can accumulate at a
finite time (chattering); the core's Zeno rule extrapolates it, and from then on
the mass is stuck on the stop while the force presses it there
(``F cos(w t) > sigma``), released when the force turns. Piecewise linear and
harmonically forced: ``exact`` solves it, grazing impacts (at zero speed)
included.

What is known exactly: with ``zeta > 0`` the motion that never touches the stop
settles on ``x_p(t) = A cos(w t - phi)`` with ``A = F / sqrt((1 - w^2)^2 + (2
zeta w)^2)``; that orbit grazes the stop when ``sigma = A``
(:meth:`ImpactOscillator.grazing_stop`), the grazing bifurcation of Nordmark
(1991) and of di Bernardo et al. (2008), chapter 6.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from nsbench.errors import ConfigError
from nsbench.problems import impact_oscillator_spec as spec
from nsbench.problems.base import Guard, HybridProblem, Mode, NamedModes, Traits
from nsbench.problems.parameters import Bound, check_values

NAME = "impact-oscillator"
DEFAULTS = {"zeta": 0.1, "F": 1.0, "w": 0.4, "sigma": 0.2, "r": 0.6, "x0": 0.0, "v0": 0.0}
_ANY = -math.inf
BOUNDS = {
    "zeta": Bound(0.0, True, "damping ratio zeta"),
    "F": Bound(_ANY, False, "forcing amplitude F"),
    "w": Bound(0.0, False, "forcing frequency w"),
    "sigma": Bound(_ANY, False, "stop position sigma"),
    "r": Bound(0.0, True, "restitution r"),
    "x0": Bound(_ANY, False, "start position x0"),
    "v0": Bound(_ANY, False, "start velocity v0"),
}


class ImpactOscillator(NamedModes, HybridProblem):
    """The harmonically forced impact oscillator (see the module docstring)."""

    mode_names = spec.MODE_NAMES
    family = "impact"
    traits = Traits(impacts=True)
    problem_class = "impact"
    law_module = "nsbench.problems.impact_oscillator_law"
    guard_kinds = spec.GUARD_KINDS
    event_kinds = spec.EVENT_KINDS
    mode_columns = ("contact",)
    #: Its law runs on mpmath numbers (arithmetic; ``math`` only in sign tests): the reference is certified by
    #: a whole hybrid run in mp (:mod:`nsbench.integrators.mp_hybrid`), resets and accumulations included.
    mp_law = True

    def __init__(self, params: dict[str, Any], parameters: dict[str, float]) -> None:
        self._given(NAME, params, parameters, state_names=("x", "v"), position_rates={"x": "v"})
        self.zeta, self.F, self.w = parameters["zeta"], parameters["F"], parameters["w"]
        self.sigma, self.r = parameters["sigma"], parameters["r"]
        self.packed = spec.LAYOUT.pack({k: parameters[k] for k in ("zeta", "F", "w", "sigma", "r")})

    def initial_state(self) -> np.ndarray:
        return np.array([self.parameters["x0"], self.parameters["v0"]])

    def guard_name(self, guard: Guard) -> str:
        return guard.kind

    @property
    def max_guards(self) -> int:
        return 1

    # ------------------------------------------------------------------ piecewise linear: exact's data
    @property
    def is_linear(self) -> bool:
        return True

    @property
    def forcing_frequency(self) -> float:
        return self.w if self.F != 0.0 else 0.0

    def linear_form(self, mode: Mode):
        a, b0, bc = np.zeros((2, 2)), np.zeros(2), np.zeros(2)
        if int(mode[0]) == spec.FREE:
            a[0, 1], a[1, 0], a[1, 1] = 1.0, -1.0, -2.0 * self.zeta
            bc[1] = self.F
        return a, b0, bc, np.zeros(2)

    def guard_row(self, mode: Mode, kind: int, index: int) -> np.ndarray:
        if kind == spec.GAP:
            return np.array([-1.0, 0.0, self.sigma, 0.0, 0.0])  # sigma - x
        return np.array([-1.0, -2.0 * self.zeta, 0.0, self.F, 0.0])  # the free acceleration

    # ------------------------------------------------------------------ linearisation of the events
    def event_linearisation(self, kind: str, t: float, y_after) -> tuple[np.ndarray, np.ndarray] | None:
        """``(y_before, R_y)`` of an event (for saltation matrices, :mod:`nsbench.periodic.flow`).

        ``impact``: the state before is ``(sigma, -v+ / r)`` and the reset's Jacobian
        ``diag(1, -r)``; ``release``: nothing is reset. ``stick``: ``None`` (the mass rests
        at ``(sigma, 0)`` and leaves at a time fixed by the force, whatever came before).

        Raises
        ------
        ArithmeticError
            An impact with ``r = 0``: the speed before it cannot be recovered.
        """
        y = np.asarray(y_after, dtype=float)
        if kind == "stick":
            return None
        if kind == "release":
            return y.copy(), np.eye(2)
        if self.r == 0.0:
            raise ArithmeticError("an impact with r = 0 forgets its speed: no saltation matrix from the state after it")
        return np.array([self.sigma, -y[1] / self.r]), np.diag([1.0, -self.r])

    # ------------------------------------------------------------------ what is known exactly
    def free_amplitude(self) -> float:
        """``A``: the amplitude of the periodic motion that never reaches the stop (``zeta > 0`` or ``w != 1``)."""
        return abs(self.F) / math.hypot(1.0 - self.w**2, 2.0 * self.zeta * self.w)

    def grazing_stop(self) -> float:
        """The stop position ``sigma`` at which the non-impacting periodic orbit grazes the stop (``= A``)."""
        return self.free_amplitude()

    def free_orbit(self, t) -> tuple[np.ndarray, np.ndarray]:
        """``(x, v)`` of the non-impacting periodic orbit at times ``t`` (closed form)."""
        t = np.asarray(t, dtype=float)
        z = self.F / complex(1.0 - self.w**2, 2.0 * self.zeta * self.w)  # x_p = Re(z e^{i w t})
        e = np.exp(1j * self.w * t)
        return (z * e).real, (1j * self.w * z * e).real

    def energy(self, y):
        """Kinetic plus potential energy of the oscillator (unforced part)."""
        y = np.asarray(y, dtype=float)
        return 0.5 * (y[1] * y[1] + y[0] * y[0])


def impact_oscillator(case: int | str | None = None, dimensional: bool = False, **params: Any) -> ImpactOscillator:
    """Build the impact oscillator (parameters ``zeta F w sigma r x0 v0``; see the module docstring).

    Raises
    ------
    ConfigError
        A case (the problem has one form), an unknown parameter, a non-finite or
        out-of-range value (``zeta < 0``, ``w <= 0``, ``r`` outside ``[0, 1]``), or a
        start beyond the stop (``x0 > sigma``, or on it moving into it).

    Without ``x0`` the mass starts at the origin, or on the stop if the stop is below it (``sigma < 0``).
    """
    if case not in (None, 1, "1"):
        raise ConfigError(f"{NAME}: unknown case {case!r}; the problem has no cases (give its parameters)")
    given = check_values(NAME, params, tuple(DEFAULTS), BOUNDS)
    v = {**DEFAULTS, **given}
    if "x0" not in given and v["sigma"] < v["x0"]:
        v["x0"] = v["sigma"]  # a stop below the origin: the default start is on the stop, at rest
    if v["r"] > 1.0:
        raise ConfigError(
            f"{NAME}: parameter r = {v['r']:g} is out of range: restitution r must be <= 1 "
            "(an impact cannot add energy)"
        )
    if v["x0"] > v["sigma"] or (v["x0"] == v["sigma"] and v["v0"] > 0.0):
        raise ConfigError(
            f"{NAME}: start x0 = {v['x0']:g}, v0 = {v['v0']:g} is beyond the stop sigma = "
            f"{v['sigma']:g}: the mass must start at x0 < sigma, or on the stop with v0 <= 0"
        )
    return ImpactOscillator(params, v)
