"""The modes of the friction family: one phase per block, and their names.

A friction mode is a tuple with one phase per block: ``STICK`` (0), ``SLIP_POS``
(+1, block faster than the belt) or ``SLIP_NEG`` (-1). (Modes of other problems
are any int tuples their law defines: :mod:`nsbench.problems.base`.)
"""

from __future__ import annotations

import itertools

from nsbench.problems.base import Guard, Mode, Transition
from nsbench.problems.friction_spec import EVENT_KINDS, GUARD_KINDS, SLIP_NEG, SLIP_POS, STICK

PHASE_NAMES = {STICK: "stick", SLIP_POS: "slip+", SLIP_NEG: "slip-"}

__all__ = [
    "STICK",
    "SLIP_POS",
    "SLIP_NEG",
    "PHASE_NAMES",
    "EVENT_KINDS",
    "GUARD_KINDS",
    "Guard",
    "Mode",
    "Transition",
    "mode_name",
    "all_modes",
]


def mode_name(mode: Mode) -> str:
    """Readable name of a friction mode, e.g. ``'slip-|stick'``."""
    return "|".join(PHASE_NAMES[p] for p in mode)


def all_modes(n_blocks: int) -> tuple[Mode, ...]:
    """All ``3**n_blocks`` modes, slip- / stick / slip+ per block."""
    return tuple(itertools.product((SLIP_NEG, STICK, SLIP_POS), repeat=n_blocks))
