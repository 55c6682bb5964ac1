"""The vocabulary of Casella's sliding test, without numba: parameter layout, modes, guard and event kinds."""

from __future__ import annotations

from nsbench.model.layout import Layout

#: The parameter vector: the four constant rates (``x' = a1`` where ``x > y``, else ``a2``; ``y' = b1``
#: where ``y > x``, else ``b2``) and the Filippov weight of the side ``x > y`` on the surface.
LAYOUT = Layout(tail=("a1", "a2", "b1", "b2", "weight"))
A1, A2, B1, B2, WEIGHT = (LAYOUT.offset(name) for name in LAYOUT.tail)
#: The mode vector's one entry: the side of ``x = y`` (``x > y``, ``x < y``) or sliding on it.
ABOVE, BELOW, SLIDE = 0, 1, 2
MODE_NAMES = {ABOVE: "x>y", BELOW: "x<y", SLIDE: "slide"}
#: The guard: the switching function ``x - y`` (off the surface). The sliding mode has none: the
#: boundaries of a Filippov sliding region are where a side's weight reaches 0, and with constant
#: fields the weights are constants (a trajectory that slides slides for ever).
SWITCH = 0
GUARD_KINDS = ("switch",)
EV_CROSS, EV_SLIDE = 0, 1
EVENT_KINDS = ("cross", "slide")
