"""A thermostat as an nsbench problem: the complete example of a problem plug-in, in one module.

A room at temperature ``x`` loses heat at rate ``a`` and a heater adds ``b`` while
it is on: ``x' = -a x + b`` (heating) or ``x' = -a x`` (cooling). The relay has
hysteresis: the heater switches off when ``x`` reaches ``x_hi`` and on again when
it falls to ``x_lo``. Two modes, one guard each, piecewise linear (so nsbench's
``exact`` solves it), and a closed form for every switching time.

What a problem module provides (nsbench.problems.base explains each part):

1. the law: compiled functions of the parameter vector ``p`` and the mode
   vector ``mode`` (here ``[HEATING]`` or ``[COOLING]``): ``rhs``, ``jacobian``,
   ``guard_value``, ``guard_rate``, ``guards_of``, ``transition``,
   ``initial_mode``, ``start_fresh`` (and optionally ``accumulation_limit``);
2. a subclass of ``HybridProblem`` naming the state, the modes, the guard and
   event kinds, and (for ``exact``) the linear form of each mode;
3. a factory ``f(case=None, dimensional=False, **params)`` that validates the
   parameters and builds the problem, registered under the entry point group
   ``nsbench.problems`` in pyproject.toml.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from nsbench.errors import ConfigError
from nsbench.model.layout import Layout
from nsbench.problems.base import HybridProblem

# ---------------------------------------------------------------------- the vocabulary
LAYOUT = Layout(tail=("a", "b", "x_lo", "x_hi"))  # the parameter vector, slot by slot
A, B, X_LO, X_HI = (LAYOUT.offset(name) for name in LAYOUT.tail)
COOLING, HEATING = 0, 1  # the one entry of the mode vector
TOO_WARM, TOO_COLD = 0, 1  # guard kinds
OFF, ON = 0, 1  # event kinds
jit = numba.njit(cache=True, nogil=True)


# ---------------------------------------------------------------------- 1. the law (compiled)
@jit
def rhs(p, mode, t, y, out):
    out[0] = -p[A] * y[0] + (p[B] if mode[0] == HEATING else 0.0)


@jit
def jacobian(p, mode, t, y, out):
    out[0, 0] = -p[A]


@jit
def guard_value(p, mode, kind, index, t, y):
    return p[X_HI] - y[0] if kind == TOO_WARM else y[0] - p[X_LO]


@jit
def guard_rate(p, mode, kind, index, t, y, dy):
    return -dy[0] if kind == TOO_WARM else dy[0]


@jit
def guards_of(p, mode, kinds, indices, signs):
    kinds[0] = TOO_WARM if mode[0] == HEATING else TOO_COLD
    indices[0], signs[0] = 0, 1  # the guard stays positive while the mode holds
    return 1


@jit
def transition(p, mode, kind, index, t, y, fresh):
    if kind == TOO_WARM:
        mode[0] = COOLING
        return OFF
    mode[0] = HEATING
    return ON


@jit
def initial_mode(p, t, y, mode):
    mode[0] = HEATING if y[0] < p[X_HI] else COOLING


@jit
def start_fresh(p, mode, t, y, fresh):
    fresh[0] = False  # no guard starts on its surface: the switches leave the other guard positive


# ---------------------------------------------------------------------- 2. the problem
class Thermostat(HybridProblem):
    """A room with a relay-controlled heater (see the module docstring)."""

    family = "relay"
    law_module = __name__
    guard_kinds = ("too-warm", "too-cold")
    event_kinds = ("off", "on")
    mode_columns = ("heater",)

    def __init__(self, params: dict, values: dict) -> None:
        self.name, self.case, self.dimensional = "thermostat", None, False
        self.params, self.parameters = dict(params), dict(values)
        self.state_names = ("x",)
        self.position_rates: dict[str, str] = {}  # first order: no state is another's rate (no peaks section)
        self.packed = LAYOUT.pack(values)

    def initial_state(self) -> np.ndarray:
        return np.array([self.parameters["x0"]])

    def mode_name(self, mode) -> str:
        return "heating" if mode[0] == HEATING else "cooling"

    def parse_mode(self, text: str):
        return (HEATING if text == "heating" else COOLING,)

    @property
    def max_guards(self) -> int:
        return 1

    # piecewise linear: what ``exact`` needs
    @property
    def is_linear(self) -> bool:
        return True

    def linear_form(self, mode):
        a, b = self.parameters["a"], self.parameters["b"]
        b0 = np.array([b if mode[0] == HEATING else 0.0])
        return np.array([[-a]]), b0, np.zeros(1), np.zeros(1)

    def guard_row(self, mode, kind, index):
        """The guard as ``q . [x, 1, cos, sin]``."""
        if kind == TOO_WARM:
            return np.array([-1.0, self.parameters["x_hi"], 0.0, 0.0])
        return np.array([1.0, -self.parameters["x_lo"], 0.0, 0.0])

    # what is known exactly
    def switching_times(self, count: int) -> list[tuple[float, str]]:
        """The first ``count`` switches in closed form: ``x(t) = x_eq + (x - x_eq) exp(-a t)``."""
        a, b, lo, hi = (self.parameters[k] for k in ("a", "b", "x_lo", "x_hi"))
        x, t, heating, out = self.parameters["x0"], 0.0, self.parameters["x0"] < hi, []
        while len(out) < count:
            eq, target = (b / a, hi) if heating else (0.0, lo)
            t += math.log((x - eq) / (target - eq)) / a
            out.append((t, "off" if heating else "on"))
            x, heating = target, not heating
        return out


# ---------------------------------------------------------------------- 3. the factory (the entry point)
DEFAULTS = {"a": 1.0, "b": 2.0, "x_lo": 1.0, "x_hi": 1.5, "x0": 0.0}


def thermostat(case=None, dimensional=False, **params) -> Thermostat:
    """Build the thermostat: ``a`` (loss rate), ``b`` (heater), ``x_lo < x_hi`` (switching levels), ``x0``."""
    if case not in (None, 1, "1"):
        raise ConfigError(f"thermostat: unknown case {case!r}; the problem has no cases")
    unknown = sorted(set(params) - set(DEFAULTS))
    if unknown:
        raise ConfigError(f"thermostat: unknown parameter {unknown[0]!r}; allowed: {', '.join(DEFAULTS)}")
    values = dict(DEFAULTS)
    for name, raw in params.items():
        try:
            values[name] = float(raw)
        except (TypeError, ValueError):
            raise ConfigError(f"thermostat: parameter {name} = {raw!r} is not a number") from None
        if not math.isfinite(values[name]):
            raise ConfigError(f"thermostat: parameter {name} = {raw!r} must be finite")
    a, b, lo, hi = (values[k] for k in ("a", "b", "x_lo", "x_hi"))
    if not a > 0:
        raise ConfigError(f"thermostat: parameter a = {a:g} is out of range: the loss rate must be > 0")
    if not 0 < lo < hi:
        raise ConfigError(f"thermostat: x_lo = {lo:g}, x_hi = {hi:g}: the levels must satisfy 0 < x_lo < x_hi")
    if not b / a > hi:
        raise ConfigError(
            f"thermostat: parameter b = {b:g} is out of range: the heater must reach x_hi (b / a > x_hi = {hi:g})"
        )
    return Thermostat(params, values)
