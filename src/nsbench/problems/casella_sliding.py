"""``casella-sliding``: Casella's two-state sliding-mode test, with its exact Filippov solution.

``x' = a1 if x > y else a2``, ``y' = b1 if y > x else b2``: with Casella's values
``a1 = -2, a2 = 2, b1 = -3, b2 = 1.5`` both sides drive ``s = x - y`` towards zero
(``s' = a1 - b2 = -3.5`` where ``x > y``, ``s' = a2 - b1 = 5`` where ``x < y``), so
a trajectory reaches ``x = y`` and stays on it. A tool that only switches
between the two branches chatters there; Filippov's solution slides with the
convex combination of the two fields that keeps ``s' = 0``, weight ``lambda = 10/17``
on the side ``x > y``, i.e. ``x' = y' = -6/17``. From Casella's start
``(1.5, 1)``: the surface is reached at ``t = 1/7`` in ``x = y = 17/14``, and at
``t = 1`` the state is ``x = y = 31/34`` (:func:`closed_form`).

The model (F. Casella, OpenModelica issue 12190, 2024, ``TestChattering.Test1``)::

    Real x(start = 1.5, fixed = true);  Real y(start = 1, fixed = true);
    der(x) = if x > y then -2 else 2;   der(y) = if y > x then -3 else 1.5;

Piecewise constant with a linear guard: ``exact`` solves it.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from nsbench.errors import ConfigError
from nsbench.problems import casella_sliding_spec as spec
from nsbench.problems.base import Guard, HybridProblem, Mode, NamedModes, Traits
from nsbench.problems.parameters import Bound, check_values

NAME = "casella-sliding"
_ANY = -math.inf
#: Casella's values and start (OpenModelica issue 12190, ``TestChattering.Test1``; StopTime 1).
DEFAULTS = {"a1": -2.0, "a2": 2.0, "b1": -3.0, "b2": 1.5, "x0": 1.5, "y0": 1.0}
#: The span of Casella's experiment annotation.
CASELLA_T_END = 1.0
BOUNDS = {name: Bound(_ANY, False, f"{'rate' if name[0] in 'ab' else 'start'} {name}") for name in DEFAULTS}


def filippov_weight(a1: float, a2: float, b1: float, b2: float) -> float:
    """``lambda``, the weight of the side ``x > y`` in Filippov's field on ``x = y`` (``s' = 0`` there)."""
    above, below = a1 - b2, a2 - b1
    return below / (below - above)


class CasellaSliding(NamedModes, HybridProblem):
    """Casella's two-state sliding test (see the module docstring)."""

    mode_names = spec.MODE_NAMES
    family = "relay"
    traits = Traits(sliding=True)
    problem_class = "sliding"
    law_module = "nsbench.problems.casella_sliding_law"
    guard_kinds = spec.GUARD_KINDS
    event_kinds = spec.EVENT_KINDS
    mode_columns = ("side",)

    def __init__(self, params: dict[str, Any], parameters: dict[str, float]) -> None:
        self._given(NAME, params, parameters, state_names=("x", "y"), position_rates={})
        self.a1, self.a2, self.b1, self.b2 = (parameters[k] for k in ("a1", "a2", "b1", "b2"))
        self.weight = filippov_weight(self.a1, self.a2, self.b1, self.b2)
        self.packed = spec.LAYOUT.pack(
            {"a1": self.a1, "a2": self.a2, "b1": self.b1, "b2": self.b2, "weight": self.weight}
        )

    def initial_state(self) -> np.ndarray:
        return np.array([self.parameters["x0"], self.parameters["y0"]])

    def guard_name(self, guard: Guard) -> str:
        return guard.kind

    @property
    def max_guards(self) -> int:
        return 1

    def field(self, mode: Mode) -> np.ndarray:
        """The constant field of ``mode``: ``(a1, b2)`` where ``x > y``, ``(a2, b1)`` where ``x < y``, Filippov's on it."""
        above, below = np.array([self.a1, self.b2]), np.array([self.a2, self.b1])
        m = int(mode[0])
        if m == spec.ABOVE:
            return above
        if m == spec.BELOW:
            return below
        return self.weight * above + (1.0 - self.weight) * below

    # ------------------------------------------------------------------ piecewise linear: exact's data
    @property
    def is_linear(self) -> bool:
        return True

    def linear_form(self, mode: Mode):
        return np.zeros((2, 2)), self.field(mode), np.zeros(2), np.zeros(2)

    def guard_row(self, mode: Mode, kind: int, index: int) -> np.ndarray:
        return np.array([1.0, -1.0, 0.0, 0.0, 0.0])  # x - y

    def event_linearisation(self, kind: str, t: float, y_after) -> tuple[np.ndarray, np.ndarray]:
        """``(y_before, R_y)`` of an event: a crossing or a sliding entry changes the mode, never the state."""
        return np.array(y_after, dtype=float), np.eye(2)

    # ------------------------------------------------------------------ a form for symbolic integrators
    #: The modes a symbolic integrator prepares at set-up.
    symbolic_modes = ((spec.ABOVE,), (spec.BELOW,), (spec.SLIDE,))

    def symbolic_field(self, mode: Mode, t, y) -> list:
        """The constant field written so that ``y`` may hold heyoka's variables (``0 * y`` keeps it an expression)."""
        f = self.field(mode)
        return [float(f[0]) + 0.0 * y[0], float(f[1]) + 0.0 * y[1]]

    def symbolic_guard(self, mode: Mode, kind: int, index: int, t, y):
        return y[0] - y[1]


def casella_sliding(case: int | str | None = None, dimensional: bool = False, **params: Any) -> CasellaSliding:
    """Build Casella's sliding test (rates ``a1 a2 b1 b2``, start ``x0 y0``; defaults: Casella's model).

    Raises
    ------
    ConfigError
        A case (the problem has one form), an unknown parameter, a non-finite value, rates that make a
        side's field tangent to ``x = y`` (``a1 = b2`` or ``a2 = b1``: Filippov's weight is undefined),
        or a start on a repelling surface (both fields point away from ``x = y``: no unique solution).
    """
    if case not in (None, 1, "1"):
        raise ConfigError(f"{NAME}: unknown case {case!r}; the problem has no cases (give its parameters)")
    given = check_values(NAME, params, tuple(DEFAULTS), BOUNDS)
    v = {**DEFAULTS, **given}
    above, below = v["a1"] - v["b2"], v["a2"] - v["b1"]
    if above == 0.0 or below == 0.0:
        side, rate = ("x > y", "a1 - b2") if above == 0.0 else ("x < y", "a2 - b1")
        raise ConfigError(
            f"{NAME}: rates a1 = {v['a1']:g}, a2 = {v['a2']:g}, b1 = {v['b1']:g}, b2 = {v['b2']:g} make the field "
            f"on the side {side} tangent to x = y ({rate} = 0); allowed: a1 != b2 and a2 != b1"
        )
    if v["x0"] == v["y0"] and above > 0.0 and below < 0.0:
        raise ConfigError(
            f"{NAME}: start x0 = y0 = {v['x0']:g} lies on a repelling surface (both fields point away from x = y): "
            "the solution is not unique; start off the surface"
        )
    return CasellaSliding(params, v)


# ---------------------------------------------------------------------- what is computed exactly
def closed_form(problem: CasellaSliding, t: float) -> tuple[list[tuple[float, str]], np.ndarray]:
    """``([(t_event, kind)], (x, y) at t)``: the exact Filippov solution from the problem's start.

    Off the surface the motion is a straight line at the side's constant field; the surface is
    reached (if at all) at ``t1 = -s0 / s'`` of the start side; from there the trajectory crosses
    into the other side (whose field carries on) or slides with Filippov's field for ever.
    """
    y0 = problem.initial_state()
    s0 = float(y0[0] - y0[1])
    mode = problem.initial_mode(0.0, y0)
    f = problem.field(mode)
    rate = float(f[0] - f[1])
    events: list[tuple[float, str]] = []
    if int(mode[0]) == spec.SLIDE or s0 * rate >= 0.0:  # on the surface already, or moving away from it
        return events, y0 + f * t
    t1 = -s0 / rate
    if t < t1:
        return events, y0 + f * t
    y1 = y0 + f * t1
    above, below = problem.a1 - problem.b2, problem.a2 - problem.b1
    if above < 0.0 < below:  # both fields point at the surface: Filippov sliding
        events.append((t1, "slide"))
        return events, y1 + problem.field((spec.SLIDE,)) * (t - t1)
    events.append((t1, "cross"))
    side = (spec.BELOW,) if s0 > 0.0 else (spec.ABOVE,)
    return events, y1 + problem.field(side) * (t - t1)
