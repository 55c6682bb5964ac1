"""``relay-feedback``: a third-order linear plant under relay feedback, with Filippov sliding.

``x' = A x + B u``, ``u = -sign(C x)``, with the plant in the observer canonical
form of di Bernardo, Johansson and Vasca (IJBC 11(4), 2001)::

    A = [[-(2 zeta omega + lam), 1, 0],      B = [1, -2 sigma rho, rho^2]^T,   C = [1, 0, 0],
         [-(2 zeta omega lam + omega^2), 0, 1],
         [-lam omega^2, 0, 0]]

whose transfer function is ``G(s) = (s^2 - 2 sigma rho s + rho^2) / ((s^2 + 2
zeta omega s + omega^2)(s + lam))``. ``C B = 1 > 0``, so a trajectory can slide on
``C x = 0``: Filippov's solution there is the flow with Utkin's equivalent control
``u_eq = -C A x / C B`` while ``|u_eq| < 1``. Every mode is linear with constant
forcing: ``exact`` solves it.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from nsbench.errors import ConfigError
from nsbench.problems import relay_feedback_spec as spec
from nsbench.problems.base import Guard, HybridProblem, Mode, NamedModes, Traits
from nsbench.problems.parameters import Bound, check_values

NAME = "relay-feedback"
_ANY = -np.inf
DEFAULTS = {"zeta": 0.05, "omega": 2.0, "lam": 0.02, "sigma": 2.0, "rho": 1.0, "x1_0": 1.0, "x2_0": 0.0, "x3_0": 0.0}
#: Published example values, each with where it was read (``case=NAME``). The Siconos example
#: cites di Bernardo, Johansson and Vasca (2001) for its sets but writes ``B = [1, 2 sigma rho,
#: rho^2]``, so its ``sigma = -1`` is ``sigma = 1`` here; nosnoc_py's example transcribes
#: Piiroinen and Kuznetsov (2008), equation (32), whose form is this one. Their values were not
#: checked against the papers themselves (not at hand); the problem sheet says what nsbench
#: computes for each.
CASES = {
    "siconos-sliding": {"zeta": 1.0, "omega": 1.0, "lam": 1.0, "sigma": 1.0, "rho": 1.0},
    "siconos-multisliding": {"zeta": 0.05, "omega": 8.0, "lam": 1.0, "sigma": 1.0, "rho": 1.0},
    "piiroinen-kuznetsov": {"zeta": 0.05, "omega": 25.0, "lam": 1.0, "sigma": 1.0, "rho": 1.0},
}
#: The source of each case.
CASE_SOURCES = {
    "siconos-sliding": "Siconos, examples/Control/RelayOscillator/RelayOscillatorWithSliding.cpp "
    "('limit cycles with sliding'; cites di Bernardo, Johansson and Vasca, IJBC 11(4), 2001)",
    "siconos-multisliding": "Siconos, examples/Control/RelayOscillator/RelayOscillatorWithSliding.cpp "
    "('multi-sliding periods'; cites di Bernardo, Johansson and Vasca, IJBC 11(4), 2001)",
    "piiroinen-kuznetsov": "nosnoc_py, examples/relay_feedback_system.py (P. T. Piiroinen and Yu. A. "
    "Kuznetsov, ACM TOMS 34(3), 2008, equation (32))",
}
BOUNDS = {
    "zeta": Bound(0.0, False, "damping ratio zeta"),
    "omega": Bound(0.0, False, "natural frequency omega"),
    "lam": Bound(0.0, False, "real pole lam"),
    "sigma": Bound(_ANY, False, "zero damping sigma"),
    "rho": Bound(0.0, False, "zero frequency rho"),
    "x1_0": Bound(_ANY, False, "start x1_0"),
    "x2_0": Bound(_ANY, False, "start x2_0"),
    "x3_0": Bound(_ANY, False, "start x3_0"),
}


def plant(zeta: float, omega: float, lam: float, sigma: float, rho: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(A, B, C)`` of the plant in di Bernardo, Johansson and Vasca's form (module docstring)."""
    a = np.array(
        [
            [-(2 * zeta * omega + lam), 1.0, 0.0],
            [-(2 * zeta * omega * lam + omega**2), 0.0, 1.0],
            [-lam * omega**2, 0.0, 0.0],
        ]
    )
    return a, np.array([1.0, -2.0 * sigma * rho, rho**2]), np.array([1.0, 0.0, 0.0])


class RelayFeedback(NamedModes, HybridProblem):
    """A linear plant under relay feedback, with sliding (see the module docstring)."""

    mode_names = spec.MODE_NAMES
    family = "relay"
    traits = Traits(sliding=True)
    problem_class = "sliding"
    law_module = "nsbench.problems.relay_feedback_law"
    guard_kinds = spec.GUARD_KINDS
    event_kinds = spec.EVENT_KINDS
    mode_columns = ("relay",)

    #: The cases the factory names: 1 (the defaults) and the published sets.
    cases = (1, *CASES)

    def __init__(self, params: dict[str, Any], parameters: dict[str, float], case: int | str | None = None) -> None:
        self._given(NAME, params, parameters, state_names=("x1", "x2", "x3"), position_rates={})
        self.case = case  # config() rebuilds the case's values from it (params holds the overrides only)
        self.A, self.B, self.C = plant(*(parameters[k] for k in ("zeta", "omega", "lam", "sigma", "rho")))
        values = dict(zip(spec.NAMES, [*self.A.ravel(), *self.B, *self.C]))
        self.packed = spec.LAYOUT.pack(values)

    def initial_state(self) -> np.ndarray:
        return np.array([self.parameters[k] for k in ("x1_0", "x2_0", "x3_0")])

    def guard_name(self, guard: Guard) -> str:
        return guard.kind

    @property
    def max_guards(self) -> int:
        return 2

    # ------------------------------------------------------------------ piecewise linear: exact's data
    @property
    def is_linear(self) -> bool:
        return True

    def sliding_matrix(self) -> np.ndarray:
        """``A - B C A / C B``: the field of the sliding mode (Utkin's equivalent control)."""
        return self.A - np.outer(self.B, self.C @ self.A) / float(self.C @ self.B)

    def linear_form(self, mode: Mode):
        m = int(mode[0])
        if m == spec.SLIDE:
            return self.sliding_matrix(), np.zeros(3), np.zeros(3), np.zeros(3)
        u = 1.0 if m == spec.UP else -1.0
        return self.A.copy(), u * self.B, np.zeros(3), np.zeros(3)

    def event_linearisation(self, kind: str, t: float, y_after) -> tuple[np.ndarray, np.ndarray]:
        """``(y_before, R_y)`` of an event (for saltation matrices, :mod:`nsbench.periodic.flow`):
        a crossing, a sliding entry or exit changes the mode, never the state."""
        return np.array(y_after, dtype=float), np.eye(3)

    # ------------------------------------------------------------------ a form for symbolic integrators
    #: The modes a symbolic integrator prepares at set-up.
    symbolic_modes = ((spec.UP,), (spec.DOWN,), (spec.SLIDE,))

    def symbolic_field(self, mode: Mode, t, y) -> list:
        """The field of :meth:`linear_form` written with ``+ - *`` only, so that ``y`` may hold heyoka's
        variables (its zero entries left out)."""
        a, b, _, _ = self.linear_form(mode)
        return [_affine(a[i], float(b[i]), y) for i in range(3)]

    def symbolic_guard(self, mode: Mode, kind: int, index: int, t, y):
        """The guard of :meth:`guard_row`, for symbolic integrators."""
        q = self.guard_row(mode, kind, index)
        return _affine(q[:3], float(q[3]), y)

    def guard_row(self, mode: Mode, kind: int, index: int) -> np.ndarray:
        q = np.zeros(6)
        if kind == spec.SWITCH:
            q[:3] = self.C
            return q
        ratio = self.C @ self.A / float(self.C @ self.B)  # -u_eq = ratio . x
        q[:3], q[3] = (ratio if kind == spec.LIMIT_UP else -ratio), 1.0
        return q


def _affine(row, constant: float, y):
    """``row . y + constant`` with ``+ - *`` only (``y`` numbers or symbolic variables)."""
    out = 0.0 * y[0] + constant
    for j, coefficient in enumerate(row):
        if coefficient != 0.0:
            out = out + float(coefficient) * y[j]
    return out


def relay_feedback(case: int | str | None = None, dimensional: bool = False, **params: Any) -> RelayFeedback:
    """Build the relay feedback system (parameters ``zeta omega lam sigma rho``, start ``x1_0 x2_0 x3_0``).

    Raises
    ------
    ConfigError
        An unknown case (1, or a name of :data:`CASES`: published example values, overridden by
        the parameters given), an unknown parameter, a non-finite or out-of-range value
        (``zeta``, ``omega``, ``lam``, ``rho`` must be > 0).
    """
    if case not in (None, 1, "1") and case not in CASES:
        raise ConfigError(
            f"{NAME}: unknown case {case!r}; allowed: 1 (the defaults) or one of {', '.join(CASES)} "
            "(published example values)"
        )
    given = check_values(NAME, params, tuple(DEFAULTS), BOUNDS)
    preset = CASES.get(case, {}) if isinstance(case, str) else {}
    return RelayFeedback(params, {**DEFAULTS, **preset, **given}, case=1 if case in (1, "1") else case)


# ---------------------------------------------------------------------- what is computed exactly
def _half_period_residual(problem: RelayFeedback, x2: float, x3: float, period: float) -> np.ndarray:
    """``x(T/2) + x(0)`` for the flow with ``u = -1`` from ``x(0) = (0, x2, x3)`` over ``T/2``."""
    from scipy.linalg import expm

    aug = np.zeros((4, 4))
    aug[:3, :3], aug[:3, 3] = problem.A, -problem.B
    z = expm(aug * (period / 2.0)) @ np.array([0.0, x2, x3, 1.0])
    return z[:3] + np.array([0.0, x2, x3])


def symmetric_orbit(problem: RelayFeedback, guess: tuple[float, float, float]) -> tuple[float, float, float]:
    """``(x2, x3, T)`` of a symmetric periodic orbit that crosses ``C x = 0`` without sliding.

    The orbit leaves the surface at ``(0, x2, x3)`` into ``C x > 0`` (``u = -1``) and
    is back on it at ``T / 2`` in the mirror point ``-(0, x2, x3)``: three equations
    in the closed-form flow, solved by Newton's method (``scipy.optimize.fsolve``)
    from ``guess`` to a residual below 1e-12. The orbit crosses (does not slide) while ``x2 = C A x > C B``.
    """
    from scipy.optimize import fsolve

    sol, info, ok, msg = fsolve(lambda v: _half_period_residual(problem, *v), guess, xtol=1e-13, full_output=True)
    if not np.abs(info["fvec"]).max() <= 1e-12:
        raise ValueError(f"{NAME}: no symmetric orbit found from {guess}: {msg}")
    a, b, c = (float(v) for v in sol)
    return a, b, c


def sliding_bifurcation(guess: tuple[float, float, float], **params: Any) -> tuple[float, float, float]:
    """``(lam, x3, T)`` where the symmetric crossing orbit reaches the sliding region's boundary.

    A symmetric orbit crossing at ``(0, x2, x3)`` slides once ``x2 = C A x`` falls to
    ``C B = 1`` (there the field of ``u = +1`` becomes tangent to the surface): a
    grazing-sliding bifurcation. With ``x2 = 1`` fixed, the half-period equations of
    :func:`symmetric_orbit` are solved for ``lam``, ``x3`` and ``T`` (the other
    parameters as given).
    """
    from scipy.optimize import fsolve

    def residual(v):
        lam, x3, period = v
        problem = relay_feedback(**{**params, "lam": lam})
        return _half_period_residual(problem, 1.0, x3, period)

    sol, info, ok, msg = fsolve(residual, guess, xtol=1e-13, full_output=True)
    if not np.abs(info["fvec"]).max() <= 1e-12:
        raise ValueError(f"{NAME}: no sliding bifurcation found from {guess}: {msg}")
    a, b, c = (float(v) for v in sol)
    return a, b, c
