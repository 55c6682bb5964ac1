"""``bouncing-ball``: a ball dropped on the ground, impacts with restitution, Zeno accumulation, rest.

Height ``x``, velocity ``v``: ``x'' = -g`` in flight; at ``x = 0`` with ``v < 0``
Newton's impact law ``v -> -e v``. The impacts accumulate at a finite time (Zeno):
from a release at rest from ``x0`` the first impact is at ``t1 = sqrt(2 x0 / g)``
with speed ``v1 = sqrt(2 g x0)``, the flights after it last ``2 e^k v1 / g``, and
they sum to the accumulation time ``t_Z = t1 + 2 e v1 / (g (1 - e))``, after which
the ball lies on the ground. The core extrapolates ``t_Z`` from the geometric
intervals and applies that rest as an event of its own (``rest``).

Parameters (SI units; there is no dimensionless form): ``g`` (default 9.81),
``e`` (0 <= e < 1, default 0.8), the start height ``x0`` (>= 0, default 1) and
velocity ``v0`` (default 0). Piecewise linear: ``exact`` solves it.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from nsbench.errors import ConfigError
from nsbench.problems import bouncing_ball_spec as spec
from nsbench.problems.base import Guard, HybridProblem, Mode, NamedModes, Traits
from nsbench.problems.parameters import Bound, check_values

NAME = "bouncing-ball"
DEFAULTS = {"g": 9.81, "e": 0.8, "x0": 1.0, "v0": 0.0}
BOUNDS = {
    "g": Bound(0.0, False, "gravity g"),
    "e": Bound(0.0, True, "restitution e"),
    "x0": Bound(0.0, True, "start height x0"),
    "v0": Bound(-math.inf, False, "start velocity v0"),
}


class BouncingBall(NamedModes, HybridProblem):
    """A ball bouncing on the ground (see the module docstring)."""

    mode_names = spec.MODE_NAMES
    family = "impact"
    traits = Traits(impacts=True, falling_mass=True)
    law_module = "nsbench.problems.bouncing_ball_law"
    guard_kinds = spec.GUARD_KINDS
    event_kinds = spec.EVENT_KINDS
    mode_columns = ("contact",)
    #: Its law runs on mpmath numbers (arithmetic; ``math`` only in sign tests): the reference is certified by
    #: a whole hybrid run in mp (:mod:`nsbench.integrators.mp_hybrid`), resets and accumulations included.
    mp_law = True

    def __init__(self, params: dict[str, Any], parameters: dict[str, float]) -> None:
        self._given(NAME, params, parameters, state_names=("x", "v"), position_rates={"x": "v"})
        self.g, self.e = parameters["g"], parameters["e"]
        self.packed = spec.LAYOUT.pack({"g": self.g, "e": self.e})

    def initial_state(self) -> np.ndarray:
        return np.array([self.parameters["x0"], self.parameters["v0"]])

    def guard_name(self, guard: Guard) -> str:
        return "x"

    @property
    def max_guards(self) -> int:
        return 1

    # ------------------------------------------------------------------ piecewise linear: exact's data
    @property
    def is_linear(self) -> bool:
        return True

    def linear_form(self, mode: Mode):
        a, b0 = np.zeros((2, 2)), np.zeros(2)
        if int(mode[0]) == spec.FLIGHT:
            a[0, 1], b0[1] = 1.0, -self.g
        return a, b0, np.zeros(2), np.zeros(2)

    def guard_row(self, mode: Mode, kind: int, index: int) -> np.ndarray:
        q = np.zeros(5)
        q[0] = 1.0  # x
        return q

    # ------------------------------------------------------------------ a form for symbolic integrators
    #: The modes a symbolic integrator prepares at set-up.
    symbolic_modes = ((spec.FLIGHT,), (spec.REST,))

    def symbolic_field(self, mode: Mode, t, y) -> list:
        """The field written with ``+ - *`` only, so that ``y`` may hold heyoka's variables (the constants
        times a state keep every entry an expression of the state)."""
        x, v = y
        if int(mode[0]) == spec.FLIGHT:
            return [v, -self.g + 0.0 * v]
        return [0.0 * x, 0.0 * v]

    def symbolic_guard(self, mode: Mode, kind: int, index: int, t, y):
        """The contact guard, the height ``x``, for symbolic integrators."""
        return y[0]

    # ------------------------------------------------------------------ what is known exactly
    def impact_times(self, count: int) -> np.ndarray:
        """The first ``count`` impact times, in closed form (from the start state)."""
        x0, v0, g, e = self.parameters["x0"], self.parameters["v0"], self.g, self.e
        v1 = math.sqrt(v0 * v0 + 2.0 * g * x0)  # the speed at the first impact
        t1 = (v0 + v1) / g
        flights = 2.0 * v1 / g * e ** np.arange(1, count)
        return t1 + np.concatenate([[0.0], np.cumsum(flights)])

    def accumulation_time(self) -> float:
        """``t_Z``: where the impacts accumulate and the ball comes to rest."""
        x0, v0, g, e = self.parameters["x0"], self.parameters["v0"], self.g, self.e
        v1 = math.sqrt(v0 * v0 + 2.0 * g * x0)
        return (v0 + v1) / g + 2.0 * e * v1 / (g * (1.0 - e))

    def energy(self, y):
        """Kinetic plus potential energy per unit mass."""
        y = np.asarray(y, dtype=float)
        return 0.5 * y[1] * y[1] + self.g * y[0]


def bouncing_ball(case: int | str | None = None, dimensional: bool = False, **params: Any) -> BouncingBall:
    """Build the bouncing ball (parameters ``g``, ``e``, ``x0``, ``v0``; see the module docstring).

    Raises
    ------
    ConfigError
        A case (the problem has one form), an unknown parameter, a non-finite or
        out-of-range value (``g <= 0``, ``e`` outside ``[0, 1)``, ``x0 < 0``), or a
        start below the ground.
    """
    if case not in (None, 1, "1"):
        raise ConfigError(f"{NAME}: unknown case {case!r}; the problem has no cases (give its parameters)")
    given = check_values(NAME, params, tuple(DEFAULTS), BOUNDS)
    values = {**DEFAULTS, **given}
    if values["e"] >= 1.0:
        raise ConfigError(
            f"{NAME}: parameter e = {values['e']:g} is out of range: restitution e must be < 1 "
            "(e = 1 never comes to rest)"
        )
    return BouncingBall(params, values)
