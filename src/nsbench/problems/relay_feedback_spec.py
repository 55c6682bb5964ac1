"""The vocabulary of the relay feedback system, without numba: parameter layout, modes, guard and event kinds."""

from __future__ import annotations

from nsbench.model.layout import Layout

#: The parameter vector: the plant's matrices, row by row (``A`` 3x3, ``B``, ``C``), built from the
#: problem's parameters in Python so that the law reads them by name.
NAMES = ("a11", "a12", "a13", "a21", "a22", "a23", "a31", "a32", "a33", "b1", "b2", "b3", "c1", "c2", "c3")
LAYOUT = Layout(tail=NAMES)
A0 = LAYOUT.offset("a11")
B0 = LAYOUT.offset("b1")
C0 = LAYOUT.offset("c1")
#: The mode vector's one entry: the relay's output +1 (``C x < 0``), -1 (``C x > 0``), or sliding on ``C x = 0``.
UP, DOWN, SLIDE = 0, 1, 2
MODE_NAMES = {UP: "u+", DOWN: "u-", SLIDE: "slide"}
#: Guards: the switching function ``C x`` (off the surface); ``1 - u_eq`` and ``1 + u_eq`` (sliding).
SWITCH, LIMIT_UP, LIMIT_DOWN = 0, 1, 2
GUARD_KINDS = ("switch", "limit+", "limit-")
#: ``touch``: the surface reached tangentially from a side whose field turns back (no switch).
EV_CROSS, EV_SLIDE, EV_EXIT, EV_TOUCH = 0, 1, 2, 3
EVENT_KINDS = ("cross", "slide", "exit", "touch")
