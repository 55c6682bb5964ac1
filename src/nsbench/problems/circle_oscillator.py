"""``circle-oscillator``: nosnoc's oscillator with a circular switching surface (FESD's order study).

``x' = A_in x`` inside the circle ``|x| < R`` and ``x' = A_out x`` outside, with

    A_in = [[1, -omega], [omega, 1]],    A_out = [[1, omega], [-omega, 1]],

``omega = 2 pi``, ``R = 1``, from ``x(0) = (exp(-1), 0)``, over ``[0, pi / 2]``: the
benchmark of the integration-order study of Nurkanovic, Sperl, Albrecht and Diehl's
finite elements with switch detection (FESD), as nosnoc ships it
(``examples/oscillator/oscillator_example.py`` of nosnoc_py; ``examples/matlab/
oscilator_integrator_order`` of nosnoc). Both fields are ``e^t`` times a rotation
(``exp(A_in t) = e^t Rot(omega t)``, ``exp(A_out t) = e^t Rot(-omega t)``), so the
radius grows as ``e^t`` on both sides and the trajectory crosses the circle once,
transversally, at ``t1 = ln(R / |x0|)`` (1 from nosnoc's start, where it has turned
once: ``x(1) = (1, 0)``), and ``x(t) = e^(t - t1) Rot(-omega (t - t1)) x(t1)`` after
(:func:`closed_form`). The field is discontinuous across the circle; its
derivative jumps, so a method without switch detection drops to first order.

The guard ``x1^2 + x2^2 - R^2`` is quadratic: the problem is not piecewise linear
in nsbench's sense (``exact`` and ``exact-mp`` refuse it); ``reference`` runs it in
quad precision through its symbolic form (heyoka).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from nsbench.errors import ConfigError
from nsbench.problems import circle_oscillator_spec as spec
from nsbench.problems.base import Guard, HybridProblem, Mode, NamedModes, Traits
from nsbench.problems.parameters import Bound, check_values

NAME = "circle-oscillator"
_ANY = -math.inf
#: nosnoc's values: OMEGA = 2 pi, R_OSC = 1, x0 = (exp(-1), 0).
DEFAULTS = {"omega": 2.0 * math.pi, "radius": 1.0, "x1_0": math.exp(-1.0), "x2_0": 0.0}
#: nosnoc's span (TSIM of its order study).
NOSNOC_T_END = math.pi / 2.0
BOUNDS = {
    "omega": Bound(_ANY, False, "rotation rate omega"),
    "radius": Bound(0.0, False, "radius of the switching circle"),
    "x1_0": Bound(_ANY, False, "start x1_0"),
    "x2_0": Bound(_ANY, False, "start x2_0"),
}


def rotation(angle: float) -> np.ndarray:
    """``Rot(angle)``, counter-clockwise."""
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s], [s, c]])


class CircleOscillator(NamedModes, HybridProblem):
    """The oscillator with a circular switching surface (see the module docstring)."""

    mode_names = spec.MODE_NAMES
    family = "relay"
    traits = Traits(sliding=True)
    problem_class = "sliding"
    law_module = "nsbench.problems.circle_oscillator_law"
    guard_kinds = spec.GUARD_KINDS
    event_kinds = spec.EVENT_KINDS
    mode_columns = ("side",)
    #: Why ``exact`` and ``exact-mp`` refuse it (``Integrator.setup`` names it).
    nonlinear_reason = "a circular switching surface (the guard x1^2 + x2^2 - R^2 is quadratic)"

    def __init__(self, params: dict[str, Any], parameters: dict[str, float]) -> None:
        self._given(NAME, params, parameters, state_names=("x1", "x2"), position_rates={})
        self.omega, self.radius = parameters["omega"], parameters["radius"]
        self.packed = spec.LAYOUT.pack({"omega": self.omega, "radius": self.radius})

    def initial_state(self) -> np.ndarray:
        return np.array([self.parameters["x1_0"], self.parameters["x2_0"]])

    def guard_name(self, guard: Guard) -> str:
        return guard.kind

    #: Time the conformance kit integrates past the crossing: the radius grows to e^3 (20 times R).
    CHECK_GROWTH = 3.0

    @property
    def check_span(self) -> float:
        """The crossing time plus :attr:`CHECK_GROWTH` (4 from nosnoc's start: four turns, one crossing).

        The radius grows as ``e^t`` on both sides, so the kit's default of 60 time units would end at
        ``|x| = e^59`` (about 4e25): a test of the range of a double, where an absolute tolerance
        (IPOPT's in ``fesd``) leaves a method nothing to meet.
        """
        t1 = crossing_time(self)
        return (0.0 if math.isnan(t1) else t1) + self.CHECK_GROWTH

    @property
    def max_guards(self) -> int:
        return 1

    def matrix(self, mode: Mode) -> np.ndarray:
        """``A_in`` or ``A_out``."""
        w = self.omega if int(mode[0]) == spec.INSIDE else -self.omega
        return np.array([[1.0, -w], [w, 1.0]])

    # ------------------------------------------------------------------ a form for symbolic integrators
    #: The modes a symbolic integrator prepares at set-up.
    symbolic_modes = ((spec.INSIDE,), (spec.OUTSIDE,))

    def symbolic_field(self, mode: Mode, t, y) -> list:
        """The field written with ``+ - *`` only, so that ``y`` may hold heyoka's variables."""
        a = self.matrix(mode)
        return [y[0] + float(a[0, 1]) * y[1], float(a[1, 0]) * y[0] + y[1]]

    def symbolic_guard(self, mode: Mode, kind: int, index: int, t, y):
        """The circle ``x1^2 + x2^2 - R^2``, for symbolic integrators."""
        return y[0] * y[0] + y[1] * y[1] - self.radius * self.radius

    def event_linearisation(self, kind: str, t: float, y_after) -> tuple[np.ndarray, np.ndarray]:
        """``(y_before, R_y)`` of an event: a crossing changes the mode, never the state."""
        return np.array(y_after, dtype=float), np.eye(2)


def circle_oscillator(case: int | str | None = None, dimensional: bool = False, **params: Any) -> CircleOscillator:
    """Build the oscillator with a circular switching surface (``omega radius``, start ``x1_0 x2_0``; defaults:
    nosnoc's order study).

    Raises
    ------
    ConfigError
        A case (the problem has one form), an unknown parameter, a non-finite value, ``radius <= 0``,
        or a start at the origin (an equilibrium of both fields: nothing moves).
    """
    if case not in (None, 1, "1"):
        raise ConfigError(f"{NAME}: unknown case {case!r}; the problem has no cases (give its parameters)")
    given = check_values(NAME, params, tuple(DEFAULTS), BOUNDS)
    v = {**DEFAULTS, **given}
    if v["x1_0"] == 0.0 and v["x2_0"] == 0.0:
        raise ConfigError(
            f"{NAME}: start x1_0 = x2_0 = 0 is the equilibrium of both fields (nothing moves); start off the origin"
        )
    return CircleOscillator(params, v)


# ---------------------------------------------------------------------- what is computed exactly
def crossing_time(problem: CircleOscillator) -> float:
    """``t1 = ln(R / |x0|)``: when the radius ``|x0| e^t`` reaches the circle (NaN if the start is outside it)."""
    r0 = math.hypot(*problem.initial_state())
    return math.log(problem.radius / r0) if r0 < problem.radius else math.nan


def closed_form(problem: CircleOscillator, t: float) -> np.ndarray:
    """The state at ``t`` from the problem's start: ``e^t Rot(+-omega t) x0`` on each side of the crossing."""
    x0 = problem.initial_state()
    t1 = crossing_time(problem)
    if math.isnan(t1):  # outside from the start: the clockwise spiral for ever
        return math.exp(t) * rotation(-problem.omega * t) @ x0
    if t <= t1:
        return math.exp(t) * rotation(problem.omega * t) @ x0
    x1 = math.exp(t1) * rotation(problem.omega * t1) @ x0
    return math.exp(t - t1) * rotation(-problem.omega * (t - t1)) @ x1
