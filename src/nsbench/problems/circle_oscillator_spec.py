"""The vocabulary of the oscillator with a circular switching surface, without numba."""

from __future__ import annotations

from nsbench.model.layout import Layout

#: The parameter vector: the rotation rate of both fields and the radius of the switching circle.
LAYOUT = Layout(tail=("omega", "radius"))
OMEGA, RADIUS = (LAYOUT.offset(name) for name in LAYOUT.tail)
#: The mode vector's one entry: inside the circle (counter-clockwise field) or outside (clockwise).
INSIDE, OUTSIDE = 0, 1
MODE_NAMES = {INSIDE: "inside", OUTSIDE: "outside"}
#: The guard: ``x1^2 + x2^2 - R^2`` (negative inside, positive outside); its one event kind.
CIRCLE = 0
GUARD_KINDS = ("circle",)
EV_CROSS = 0
EVENT_KINDS = ("cross",)
