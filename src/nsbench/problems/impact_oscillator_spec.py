"""The vocabulary of the impact oscillator, without numba: parameter layout, modes, guard and event kinds."""

from __future__ import annotations

from nsbench.model.layout import Layout

#: The parameter vector: damping ratio, forcing amplitude and frequency, stop position, restitution.
LAYOUT = Layout(tail=("zeta", "F", "w", "sigma", "r"))
ZETA, AMP, FREQ, STOP, RESTITUTION = (LAYOUT.offset(name) for name in ("zeta", "F", "w", "sigma", "r"))
#: The mode vector's one entry: moving freely, or held against the stop.
FREE, STUCK = 0, 1
MODE_NAMES = {FREE: "free", STUCK: "stuck"}
#: Guards: the gap to the stop (free), the force that presses the mass on the stop (stuck).
GAP, PRESS = 0, 1
GUARD_KINDS = ("gap", "press")
EV_IMPACT, EV_STICK, EV_RELEASE = 0, 1, 2
EVENT_KINDS = ("impact", "stick", "release")
