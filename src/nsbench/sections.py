"""Observation hooks: non-terminal section events that never change the mode.

Two kinds cover Poincare sections and bifurcation diagrams:

- :class:`StateSection`: a linear function of the state crossing a level in a
  given direction (``v1 = 0`` downward marks the peaks of ``x1``). Each
  integrator locates these with its own event machinery.
- :class:`TimeSection`: fixed times ``t = phase + k * period`` (stroboscopic
  sampling at the forcing period); states there come from the integrator's
  dense output.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Union

import numpy as np

from nsbench.errors import ConfigError

if TYPE_CHECKING:  # pragma: no cover
    from nsbench.problems.oscillator import FrictionOscillator


@dataclass(frozen=True)
class StateSection:
    """The hyperplane ``coeffs . y = level``, recorded when crossed in ``direction``.

    ``direction`` is +1 (value increasing), -1 (decreasing) or 0 (both).
    """

    name: str
    coeffs: tuple[float, ...]
    level: float = 0.0
    direction: int = 0

    def __post_init__(self) -> None:
        if self.direction not in (-1, 0, 1):
            raise ConfigError(f"section {self.name!r}: direction {self.direction!r} must be -1, 0 or +1")
        if not all(math.isfinite(c) for c in self.coeffs) or not any(self.coeffs):
            raise ConfigError(f"section {self.name!r}: coefficients {self.coeffs} must be finite and not all zero")

    def value(self, t, y):
        """``coeffs . y - level`` for ``y`` of shape ``(n,)`` or ``(n, k)``."""
        return np.tensordot(np.asarray(self.coeffs), np.asarray(y, dtype=float), axes=1) - self.level

    def rate(self, t, y, dydt):
        """Time derivative of :meth:`value` along ``dydt``."""
        return np.tensordot(np.asarray(self.coeffs), np.asarray(dydt, dtype=float), axes=1)

    def crossed(self, before: float, after: float) -> bool:
        """Whether going from value ``before`` to ``after`` crosses the section in ``direction``.

        Starting exactly on the section is not a crossing (it was counted when
        it was reached); landing exactly on it is.
        """
        if before == 0.0 or (after != 0.0 and (before < 0.0) == (after < 0.0)):
            return False
        upward = before < 0.0
        return self.direction == 0 or (self.direction > 0) == upward


@dataclass(frozen=True)
class TimeSection:
    """Stroboscopic times ``phase + k * period`` (``k`` integer)."""

    name: str
    period: float
    phase: float = 0.0

    def __post_init__(self) -> None:
        if not (math.isfinite(self.period) and self.period > 0):
            raise ConfigError(f"section {self.name!r}: period {self.period!r} must be finite and > 0")

    def times(self, t0: float, t1: float) -> np.ndarray:
        """All section times in ``[t0, t1]``."""
        k0 = math.ceil((t0 - self.phase) / self.period - 1e-12)
        k1 = math.floor((t1 - self.phase) / self.period + 1e-12)
        ks = np.arange(k0, k1 + 1)
        t = self.phase + ks * self.period
        return t[(t >= t0) & (t <= t1)]


Section = Union[StateSection, TimeSection]


def peaks(problem: "FrictionOscillator", block: int = 1) -> StateSection:
    """Local maxima of ``x_block``: ``v_block = 0`` crossed downward."""
    coeffs = [0.0] * problem.n_states
    coeffs[2 * (block - 1) + 1] = 1.0
    return StateSection(f"peaks_x{block}", tuple(coeffs), 0.0, -1)


def level_crossing(
    problem: "FrictionOscillator", variable: str, level: float = 0.0, direction: int = 0
) -> StateSection:
    """A Poincare section ``variable = level`` (``variable`` one of the state names)."""
    if variable not in problem.state_names:
        raise ConfigError(f"unknown state variable {variable!r}; allowed: {', '.join(problem.state_names)}")
    coeffs = [0.0] * problem.n_states
    coeffs[problem.state_names.index(variable)] = 1.0
    return StateSection(f"{variable}={level:g}", tuple(coeffs), float(level), direction)


def stroboscopic(problem: "FrictionOscillator", phase: float = 0.0) -> TimeSection:
    """States at ``t = phase + 2 pi k / w``, the forcing period of ``problem``."""
    w = problem.forcing_frequency
    if w <= 0:
        raise ConfigError(f"stroboscopic section needs a forcing frequency > 0; the problem has {w:g}")
    return TimeSection("strobe", 2.0 * math.pi / w, phase)
