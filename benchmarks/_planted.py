"""Integrators with a planted slowdown, for ``benchmarks/compare_false_alarms.py``.

- ``planted-dop853`` is ``scipy-dop853``; its twin ``planted-dop853-2x`` computes
  every arc twice and returns the second result: twice the integrator's work,
  really done (not a sleep), with the same results and counters, so that only
  the timing statistics of ``nsbench compare`` can see it (the arcs are nearly
  all of a run's time: about 1.9x the run).
- ``planted-rk4`` is ``henon-rk4`` (the whole run in its compiled kernel); its
  twin ``planted-rk4-2x`` takes half the step at each level: twice the steps and
  right-hand-side evaluations, so twice the counted work of the run (its
  short runs are timed in loops: :func:`nsbench.bench.timing.loops_for`).

They live in a module, not in the script, so that the bench's worker processes
can import them.
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
    """``henon-rk4`` under another name (the whole run in its compiled kernel)."""

    name = "planted-rk4"


class PlantedRK4Twice(PlantedRK4):
    """``planted-rk4`` at half the step of each level: twice the steps."""

    name = "planted-rk4-2x"
    accuracy_levels = tuple({"h": level["h"] / 2} for level in HenonRK4.accuracy_levels)


#: Each planted integrator and its twice-the-work twin.
PAIRS = {PlantedDOP853.name: PlantedDOP853Twice, PlantedRK4.name: PlantedRK4Twice}
ALL = (PlantedDOP853, PlantedDOP853Twice, PlantedRK4, PlantedRK4Twice)
