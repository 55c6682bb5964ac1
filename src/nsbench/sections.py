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


#: Names a state's rate may have beside it, tried in this order: ``v1`` for ``x1`` (``v`` for ``x``),
#: ``dy`` for ``y``, ``px`` for ``x`` (a Hamiltonian's momentum). A candidate counts only when the
#: problem's own field confirms it (:func:`rate_state`): a name alone never decides.
_RATE_NAMES = (lambda n: "v" + n[1:] if n.startswith("x") else "", lambda n: "d" + n, lambda n: "p" + n)


def rate_state(problem, name: str) -> str | None:
    """The state variable that is the time derivative of state ``name`` in ``problem``, or ``None``.

    A problem that declares its ``position_rates`` answers from them: no field runs, so a command
    checks a section without compiling anything. For one that does not (a plug-in may leave them
    ``None``), see :func:`rate_on_field`.
    """
    names = tuple(problem.state_names)
    if name not in names:
        raise ConfigError(f"unknown state variable {name!r}; allowed: {', '.join(names)}")
    declared = getattr(problem, "position_rates", None)
    if declared is not None:
        return declared.get(name)
    return rate_on_field(problem, name)


def rate_on_field(problem, name: str) -> str | None:
    """The state that is the time derivative of state ``name``, found on ``problem``'s field.

    Candidates come from the names (``v1`` for ``x1``, ``dy`` for ``y``, ``px`` for ``x``) and are
    confirmed on the problem's field: ``name``'s rate must equal the candidate at the initial
    state and at two other states, in the initial mode (a position's rate is the velocity in every
    mode of a mechanical problem; a first-order law such as a thermostat's ``x' = -a x + b`` has
    no such state). This runs the problem's (compiled) field; the conformance kit compares it with
    a problem's declared ``position_rates``.
    """
    names = tuple(problem.state_names)
    i = names.index(name)
    candidates = [c for c in (rule(name) for rule in _RATE_NAMES) if c and c != name and c in names]
    if not candidates:
        return None
    y0 = np.asarray(problem.initial_state(), dtype=float)
    mode = problem.initial_mode(0.0, y0)
    # three states, the initial one and two spread off it, so that a coincidence at one state does not count
    states = [y0, y0 + 0.37 + 0.11 * np.arange(len(y0)), y0 - 0.23 * (1.0 + np.arange(len(y0)))]
    rates = [np.asarray(problem.rhs(mode, 0.0, y), dtype=float) for y in states]
    for c in candidates:
        j = names.index(c)
        if all(math.isclose(r[i], y[j], rel_tol=1e-12, abs_tol=1e-12) for r, y in zip(rates, states)):
            return c
    return None


def peak_variables(problem) -> tuple[tuple[str, str], ...]:
    """``(position, rate)`` for every state whose rate is another state (:func:`rate_state`), in state order:
    the variables whose local maxima a ``peaks`` section can record."""
    pairs = []
    for name in problem.state_names:
        rate = rate_state(problem, name)
        if rate is not None:
            pairs.append((name, rate))
    return tuple(pairs)


def peaks(problem: "FrictionOscillator", block: int = 1) -> StateSection:
    """Local maxima of the ``block``-th position (``x_block`` of a friction oscillator): its rate ``= 0``
    crossed downward.

    The positions and their rates are the problem's declared ``position_rates`` (else found by its
    state names and field: :func:`peak_variables`); a problem with none (a first-order law) is refused with a
    ``ConfigError`` naming its states.
    """
    pairs = peak_variables(problem)
    if not pairs:
        raise ConfigError(
            f"section peaks records the local maxima of a position whose rate is another state (v1 = 0 "
            f"crossed downward for x1); no state of {problem.name} ({', '.join(problem.state_names)}) has "
            "its rate among the states"
        )
    if not 1 <= block <= len(pairs):
        raise ConfigError(
            f"peaks of position {block}: {problem.name} has {len(pairs)} ({', '.join(p for p, _ in pairs)})"
        )
    position, rate = pairs[block - 1]
    coeffs = [0.0] * problem.n_states
    coeffs[problem.state_names.index(rate)] = 1.0
    return StateSection(f"peaks_{position}", tuple(coeffs), 0.0, -1)


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
