"""Integrators with a planted slowdown, for ``benchmarks/compare_false_alarms.py``.

``planted-dop853`` and ``planted-rk4`` are ``scipy-dop853`` and ``henon-rk4`` run
through the per-arc ``advance`` path; their ``-2x`` twins compute every arc twice
and return the second result: twice the work, really done (not a sleep), with
the same results and the same counters (so that only the timing statistics of
``nsbench compare`` can see the difference). They live in a module, not in the
script, so that the bench's worker processes can import them.
"""

from __future__ import annotations

from nsbench.integrators.base import ArcRequest, ArcResult
from nsbench.integrators.henon_rk4 import HenonRK4
from nsbench.integrators.scipy_ import ScipyDOP853


class PlantedDOP853(ScipyDOP853):
    """``scipy-dop853`` under another name."""

    name = "planted-dop853"


class PlantedDOP853Twice(PlantedDOP853):
    """``planted-dop853`` computing every arc twice."""

    name = "planted-dop853-2x"

    def advance(self, request: ArcRequest) -> ArcResult:
        super().advance(request)
        return super().advance(request)


class PlantedRK4(HenonRK4):
    """``henon-rk4`` one arc per call (its compiled kernel per arc, the hybrid core in Python between)."""

    name = "planted-rk4"

    def advance(self, request: ArcRequest) -> ArcResult:
        return super().advance(request)


class PlantedRK4Twice(PlantedRK4):
    """``planted-rk4`` computing every arc twice."""

    name = "planted-rk4-2x"

    def advance(self, request: ArcRequest) -> ArcResult:
        super().advance(request)
        return super().advance(request)


#: Each planted integrator and its twice-the-work twin.
PAIRS = {PlantedDOP853.name: PlantedDOP853Twice, PlantedRK4.name: PlantedRK4Twice}
ALL = (PlantedDOP853, PlantedDOP853Twice, PlantedRK4, PlantedRK4Twice)
