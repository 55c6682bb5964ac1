"""The vocabulary of the friction family, without numba: parameter layout, phases, guard and event kinds.

Shared by the compiled law (:mod:`nsbench.problems.friction_law`) and the Python
side (:mod:`nsbench.problems.oscillator`), which builds problems without
loading a compiler.
"""

from __future__ import annotations

from nsbench.model.layout import Layout

#: The parameter vector: the number of blocks, then per block its mass, damping, spring to the previous
#: block (to the ground for block 1), cubic coefficient, kinetic and static friction, then the force.
LAYOUT = Layout(head=("n_blocks",), fields=("m", "c", "k", "h", "fs", "fr"), tail=("F", "w", "v0"))
N_BLOCKS = LAYOUT.offset("n_blocks")
M, C, K, H, FS, FR = (LAYOUT.field(name) for name in ("m", "c", "k", "h", "fs", "fr"))
F_AMP, F_FREQ, V0 = (LAYOUT.scalar(name) for name in ("F", "w", "v0"))

#: Phases of a block (the entries of a mode).
STICK, SLIP_POS, SLIP_NEG = 0, 1, -1
#: Guard kinds: the velocity surface (in slip) and the static limits (in stick).
VELOCITY, UPPER, LOWER = 0, 1, 2
GUARD_KINDS = ("velocity", "upper", "lower")
#: Event kinds, the codes the transition returns.
EV_STICK, EV_SLIP, EV_REVERSE = 0, 1, 2
EVENT_KINDS = ("stick", "slip", "reverse")
