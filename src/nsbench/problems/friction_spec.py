"""The vocabulary of the friction family, without numba: parameter layout, phases, guard and event kinds.

Shared by the compiled law (:mod:`nsbench.problems.friction_law`) and the Python
side (:mod:`nsbench.problems.oscillator`), which builds problems without
loading a compiler.
"""

from __future__ import annotations

from nsbench.model.layout import Layout

#: The parameter vector: the number of blocks, then per block its mass, damping, spring to the previous
#: block (to the ground for block 1), cubic coefficient, kinetic and static friction, the friction law's
#: parameters (high-speed level ``fk``, weakening ``delta``, Stribeck speed ``vs``, viscous ``cv``), then
#: the force, the belt speed and the friction law's code.
LAYOUT = Layout(
    head=("n_blocks",), fields=("m", "c", "k", "h", "fs", "fr", "fk", "delta", "vs", "cv"), tail=("F", "w", "v0", "law")
)
N_BLOCKS = LAYOUT.offset("n_blocks")
M, C, K, H, FS, FR = (LAYOUT.field(name) for name in ("m", "c", "k", "h", "fs", "fr"))
FK, DELTA, VS, CV = (LAYOUT.field(name) for name in ("fk", "delta", "vs", "cv"))
F_AMP, F_FREQ, V0, LAW = (LAYOUT.scalar(name) for name in ("F", "w", "v0", "law"))

#: Friction laws of a slipping block (the ``law`` slot): the slip force's magnitude as a function of the
#: slip speed ``u = s (v - v0)`` (:mod:`nsbench.problems.friction_laws`).
COULOMB, WEAKENING, STRIBECK = 0, 1, 2
LAW_NAMES = ("coulomb", "weakening", "stribeck")

#: Phases of a block (the entries of a mode).
STICK, SLIP_POS, SLIP_NEG = 0, 1, -1
#: Guard kinds: the velocity surface (in slip) and the static limits (in stick).
VELOCITY, UPPER, LOWER = 0, 1, 2
GUARD_KINDS = ("velocity", "upper", "lower")
#: Event kinds, the codes the transition returns.
EV_STICK, EV_SLIP, EV_REVERSE = 0, 1, 2
EVENT_KINDS = ("stick", "slip", "reverse")
