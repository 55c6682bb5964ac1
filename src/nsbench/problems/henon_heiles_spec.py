"""The vocabulary of the Henon-Heiles problem, without numba: parameter layout, modes, guard and event kinds."""

from __future__ import annotations

from nsbench.model.layout import Layout

#: The parameter vector: the cubic coupling (1 in Henon and Heiles' potential).
LAYOUT = Layout(tail=("coupling",))
COUPLING = LAYOUT.offset("coupling")
#: The mode vector's one entry: the side of the section plane ``x = 0`` the orbit is on (the field is the same).
LEFT, RIGHT = 0, 1
MODE_NAMES = {LEFT: "x<0", RIGHT: "x>0"}
#: The guard (the section plane) and the event kinds: ``section`` is a crossing with ``px > 0`` (a point
#: of the Poincare section), ``return`` one with ``px < 0``.
PLANE = 0
GUARD_KINDS = ("plane",)
EV_SECTION, EV_RETURN = 0, 1
EVENT_KINDS = ("section", "return")
