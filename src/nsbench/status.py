"""One status vocabulary, from the compiled kernel to the report.

:class:`Status` says how something ended: a run (``simulate``: success, an
exhausted budget, an event storm, an integrator failure, a missed event) and a
case of a suite or sweep (``unsupported``, ``error``, ``crashed``, ``time
limit``, on top of the run's own) and a value of a bifurcation sweep
(``rest``, ``incomplete``). Its value is the text written in results,
tables and reports; compare with the members, never with literal strings. The
compiled core's outcome codes map to it one to one (:mod:`nsbench.hybrid.run`).

:class:`OutcomeKind` says what became of a job in a supervised worker (:mod:`nsbench.workers.jobs`):
returned, raised, past its time limit, crashed; :attr:`OutcomeKind.status` is the case status
each of them gives.
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
    # outcomes of locating a bifurcation target, beyond a run's own (nsbench.bench.targets)
    NO_REFERENCE = "no reference"  # the target's reference could not be located
    NO_BRACKET = "no bracket"  # the probes at the bracket's ends do not straddle the change of pattern
    PROBE_BUDGET = "probe budget"  # the probes ran out with the bracket still wider than xtol

    @property
    def ok(self) -> bool:
        return self is Status.SUCCESS

    def __str__(self) -> str:
        return self.value


class OutcomeKind(str, Enum):
    """What became of a job (:attr:`Outcome.kind`); compare with the members, never with literal strings."""

    PARTIAL = "partial"  # an emitted part of the result; more follow
    DONE = "done"  # the job returned
    FAILED = "failed"  # the job raised
    TIME_LIMIT = "time limit"  # its step ran past its limit; the worker was ended
    CRASHED = "crashed"  # the worker died during the step

    @property
    def status(self) -> Status:
        """The case status of a job that ended this way: ``error``, ``time limit`` or ``crashed``
        (``success`` for a job that returned; a partial outcome has none)."""
        if self is OutcomeKind.PARTIAL:
            raise ValueError("a partial outcome has no status: the job goes on")
        return {OutcomeKind.DONE: Status.SUCCESS, OutcomeKind.FAILED: Status.ERROR}.get(self) or Status(self.value)

    def __str__(self) -> str:
        return self.value


class ReferenceStatus(str, Enum):
    """What became of a reference (the ``reference_status`` of a result row, a bifurcation target's
    reference): ``ok``, or a text that says why there is none. A failed one's text starts with
    ``reference failed`` (:meth:`failed`); any other text (no candidate accepts the problem) is
    :attr:`UNAVAILABLE`. Compare with the members (:meth:`of`), never with literal strings."""

    OK = "ok"
    FAILED = "reference failed"  # a candidate accepted the problem, and its run raised, failed or crashed
    UNAVAILABLE = "unavailable"  # no candidate accepts the problem: nothing to grade against

    @classmethod
    def of(cls, text: object) -> "ReferenceStatus":
        """The kind of a stored status text."""
        text = str(text)
        if text == cls.OK.value:
            return cls.OK
        return cls.FAILED if text.startswith(cls.FAILED.value) else cls.UNAVAILABLE

    @staticmethod
    def failed(reason: str) -> str:
        """The status text of a reference that failed, with its reason."""
        return f"{ReferenceStatus.FAILED.value}: {reason}"

    def __str__(self) -> str:
        return self.value


class TargetOutcome(str, Enum):
    """What one method did at one accuracy target on one problem (a cell of the fixed-target table:
    :func:`nsbench.bench.tables.fixed_target`). Compare with the members, never with literal strings."""

    REACHED = "reached"  # a configuration reached the target: its cheapest one's cost is the cell
    NOT_REACHED = "not reached"
    NOT_GRADED = "not graded"  # below what the reference can certify or double precision can resolve
    NO_REFERENCE = "no reference"
    UNSUPPORTED = "unsupported"  # the method refuses the problem
    REFERENCE = "reference"  # the problem's reference itself: its cost is informative, its error 0

    @property
    def graded(self) -> bool:
        """Whether the (problem, target) pair is graded at all: it has a reference that can grade the target,
        and this is not the reference itself. A refused problem is graded (the method does not solve it)."""
        return self not in (TargetOutcome.NO_REFERENCE, TargetOutcome.NOT_GRADED, TargetOutcome.REFERENCE)

    def __str__(self) -> str:
        return self.value
