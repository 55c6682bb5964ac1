"""``henon-heiles``: the smooth Henon-Heiles system, its Poincare section ``x = 0, px > 0`` as events.

``H = (px^2 + py^2) / 2 + (x^2 + y^2) / 2 + a (x^2 y - y^3 / 3)`` with ``a = 1``
(Henon and Heiles, 1964). Nothing is switched: every crossing of the plane
``x = 0`` is an event that changes no state (``section`` where ``px > 0``,
``return`` where ``px < 0``), so the bench measures what each integrator pays to
locate the points of the Poincare section, against a reference in quad
precision. The default start and span are heyoka's Henon-Heiles event-detection
benchmark (``benchmark/hh_event.cpp`` of github.com/bluescarni/heyoka): ``x = 0,
y = 0.2587703282931232, px = -0.2525875586263492, py = -0.2178423952983717``,
propagated to ``t = 2000`` with an event on ``x`` increasing through 0, at
tolerance 1e-15.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from nsbench.errors import ConfigError
from nsbench.problems import henon_heiles_spec as spec
from nsbench.problems.base import Guard, HybridProblem, Mode, NamedModes
from nsbench.problems.parameters import Bound, check_values

NAME = "henon-heiles"
_ANY = -np.inf
#: heyoka's benchmark start (benchmark/hh_event.cpp: state order vx, vy, x, y there).
HEYOKA_START = {"x0": 0.0, "y0": 0.2587703282931232, "px0": -0.2525875586263492, "py0": -0.2178423952983717}
#: heyoka's benchmark span and tolerance.
HEYOKA_T_END = 2000.0
HEYOKA_TOL = 1e-15
DEFAULTS = {"coupling": 1.0, **HEYOKA_START}
BOUNDS = {"coupling": Bound(_ANY, False, "coupling"), **{k: Bound(_ANY, False, f"start {k}") for k in HEYOKA_START}}


class HenonHeiles(NamedModes, HybridProblem):
    """The Henon-Heiles system with its Poincare section as events (see the module docstring)."""

    mode_names = spec.MODE_NAMES
    family = "smooth"
    problem_class = "smooth"
    law_module = "nsbench.problems.henon_heiles_law"
    guard_kinds = spec.GUARD_KINDS
    event_kinds = spec.EVENT_KINDS
    mode_columns = ("side",)

    def __init__(self, params: dict[str, Any], parameters: dict[str, float]) -> None:
        self._given(NAME, params, parameters, state_names=("x", "y", "px", "py"), position_rates={"x": "px", "y": "py"})
        self.coupling = parameters["coupling"]
        self.packed = spec.LAYOUT.pack({"coupling": self.coupling})

    def initial_state(self) -> np.ndarray:
        return np.array([self.parameters[k] for k in ("x0", "y0", "px0", "py0")])

    def guard_name(self, guard: Guard) -> str:
        return "x"

    @property
    def max_guards(self) -> int:
        return 1

    # ------------------------------------------------------------------ a form for symbolic integrators
    #: The modes a symbolic integrator prepares at set-up (both sides of the plane).
    symbolic_modes = ((spec.LEFT,), (spec.RIGHT,))

    def symbolic_field(self, mode: Mode, t, y) -> list:
        """The field written with ``+ - *`` only, so that ``y`` may hold symbolic variables (heyoka's)."""
        x, yy, px, py = y
        a = self.coupling
        return [px, py, -x - 2.0 * a * x * yy, -yy - a * (x * x - yy * yy)]

    def symbolic_guard(self, mode: Mode, kind: int, index: int, t, y):
        """The guard (the plane ``x = 0``), for symbolic integrators."""
        return y[0]

    # ------------------------------------------------------------------ what is known exactly
    def energy(self, y):
        """The Hamiltonian, conserved along every orbit."""
        x, yy, px, py = (np.asarray(v, dtype=float) for v in np.asarray(y, dtype=float))
        return 0.5 * (px * px + py * py) + 0.5 * (x * x + yy * yy) + self.coupling * (x * x * yy - yy**3 / 3.0)


def henon_heiles(case: int | str | None = None, dimensional: bool = False, **params: Any) -> HenonHeiles:
    """Build the Henon-Heiles problem (parameters ``coupling``, start ``x0 y0 px0 py0``; defaults: heyoka's
    benchmark start).

    Raises
    ------
    ConfigError
        A case (the problem has one form), an unknown parameter or a non-finite value.
    """
    if case not in (None, 1, "1"):
        raise ConfigError(f"{NAME}: unknown case {case!r}; the problem has no cases (give its parameters)")
    given = check_values(NAME, params, tuple(DEFAULTS), BOUNDS)
    return HenonHeiles(params, {**DEFAULTS, **given})
