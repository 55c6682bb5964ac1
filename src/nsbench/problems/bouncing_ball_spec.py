"""The vocabulary of the bouncing ball, without numba: parameter layout, modes, guard and event kinds."""

from __future__ import annotations

from nsbench.model.layout import Layout

#: The parameter vector: gravity, restitution.
LAYOUT = Layout(tail=("g", "e"))
G, RESTITUTION = (LAYOUT.offset(name) for name in ("g", "e"))
#: The mode vector's one entry.
FLIGHT, REST = 0, 1
MODE_NAMES = {FLIGHT: "flight", REST: "rest"}
#: The guard (contact with the ground) and the event kinds.
CONTACT = 0
GUARD_KINDS = ("contact",)
EV_IMPACT, EV_REST = 0, 1
EVENT_KINDS = ("impact", "rest")
