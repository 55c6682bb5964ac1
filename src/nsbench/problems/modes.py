"""Modes, guards and transitions: the explicit discontinuity structure of a problem.

A *mode* is a tuple with one phase per block: ``STICK`` (0), ``SLIP_POS`` (+1,
block faster than the belt) or ``SLIP_NEG`` (-1). Inside a mode the vector field
is smooth; a *guard* is a smooth function whose sign is known while the mode is
valid, and the engine switches mode when a guard reaches zero.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from typing import TYPE_CHECKING, Literal

import numpy as np

if TYPE_CHECKING:  # pragma: no cover
    from nsbench.problems.oscillator import FrictionOscillator

STICK = 0
SLIP_POS = 1
SLIP_NEG = -1
PHASE_NAMES = {STICK: "stick", SLIP_POS: "slip+", SLIP_NEG: "slip-"}

Mode = tuple[int, ...]
GuardKind = Literal["velocity", "upper", "lower"]
EventKind = Literal["stick", "slip", "reverse"]
EVENT_KINDS: tuple[str, ...] = ("stick", "slip", "reverse")


def mode_name(mode: Mode) -> str:
    """Readable name of a mode, e.g. ``'slip-|stick'``."""
    return "|".join(PHASE_NAMES[p] for p in mode)


def all_modes(n_blocks: int) -> tuple[Mode, ...]:
    """All ``3**n_blocks`` modes, slip- / stick / slip+ per block."""
    return tuple(itertools.product((SLIP_NEG, STICK, SLIP_POS), repeat=n_blocks))


@dataclass(frozen=True, eq=False)
class Guard:
    """A switching surface of the current mode.

    Attributes
    ----------
    problem
        The problem that evaluates it.
    block
        Block index, 1-based.
    kind
        ``'velocity'`` (``v_i - v0``, a slip phase), ``'upper'`` (``R_i - fr_i``)
        or ``'lower'`` (``R_i + fr_i``, both during stick).
    expected_sign
        Sign of the guard while the mode is valid. The mode ends when
        ``expected_sign * value`` reaches zero. At the start of a phase the guard
        of that phase is exactly zero, so integrators must test against this
        sign, never against the sign at the start of the arc.
    """

    problem: "FrictionOscillator"
    block: int
    kind: GuardKind
    expected_sign: int

    @property
    def name(self) -> str:
        i = self.block
        return {"velocity": f"v{i}-v0", "upper": f"R{i}-fr{i}", "lower": f"R{i}+fr{i}"}[self.kind]

    def value(self, t, y):
        """Guard value at ``(t, y)``; ``y`` of shape ``(n,)`` or ``(n, k)``."""
        return self.problem.guard_value(self, t, y)

    def rate(self, t, y, dydt):
        """Time derivative of the guard along ``dydt`` (same shapes as ``y``)."""
        return self.problem.guard_rate(self, t, y, dydt)

    def __repr__(self) -> str:
        return f"Guard({self.name}, expected_sign={self.expected_sign:+d})"


@dataclass(frozen=True)
class Transition:
    """What happens when a guard fires: the new mode and the state after the event."""

    mode: Mode
    y: np.ndarray
    kind: EventKind
    block: int
