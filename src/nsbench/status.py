"""One status vocabulary, from the compiled kernel to the report.

:class:`Status` says how something ended: a run (``simulate``: success, an
exhausted budget, an event storm, an integrator failure, a missed event) and a
case of a suite or sweep (``unsupported``, ``error``, ``crashed``, ``time
limit``, on top of the run's own) and a value of a bifurcation sweep
(``rest``, ``incomplete``). Its value is the text written in results,
tables and reports; compare with the members, never with literal strings. The
compiled core's outcome codes map to it one to one (:mod:`nsbench.hybrid.run`).
"""

from __future__ import annotations

from enum import Enum


class Status(str, Enum):
    """How a run or a case ended. The value is the human-readable text stored in results."""

    SUCCESS = "success"
    BUDGET_EXHAUSTED = "step budget exhausted"
    EVENT_STORM = "event storm (Zeno)"
    INTEGRATOR_FAILURE = "integrator failure"
    EVENT_MISSED = "event missed"
    # outcomes of a case run by the bench or a sweep, beyond a run's own
    UNSUPPORTED = "unsupported"
    ERROR = "error"
    CRASHED = "crashed"
    TIME_LIMIT = "time limit"
    # outcomes of a bifurcation-sweep value, beyond a run's own
    REST = "rest"  # the motion came to rest (sliding equilibrium) before its points: its final state is one point
    INCOMPLETE = "incomplete"  # fewer section points than asked within the recording window

    @property
    def ok(self) -> bool:
        return self is Status.SUCCESS

    def __str__(self) -> str:
        return self.value
