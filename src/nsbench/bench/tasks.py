"""The suite runner's tasks for its workers (:mod:`nsbench.workers`): a reference, a warm-up, a timing round.

Each is a :class:`nsbench.workers.protocol.Task`: the worker unpickles it (which
imports this module, and only then the runner's modules it needs) and calls its
``perform``. The worker floor itself knows nothing of suites, cases or rows.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from nsbench.bench.execute import WarmResult
    from nsbench.bench.reference import Reference
    from nsbench.bench.suite import Case
    from nsbench.workers.protocol import Context


@dataclass(frozen=True)
class ComputeReference:
    """Compute the reference of ``problem`` over ``[t0, t_end]`` from the first of ``candidates`` that passes."""

    task: int
    problem: dict[str, Any]
    candidates: list[dict[str, Any]]
    t0: float
    t_end: float
    dense_points: int

    def perform(self, context: Context) -> Reference:
        from nsbench.bench.reference import compute_reference

        return compute_reference(self.problem, self.candidates, self.t0, self.t_end, self.dense_points)


@dataclass(frozen=True)
class WarmUp:
    """Set up ``case`` and run it once, short and untimed (compilation, first use); with ``probe``, then time
    a short warm run too (the cost of a case the plan has no measure of, :func:`nsbench.bench.execute.probe_run`)."""

    task: int
    case: Case
    suite: str
    probe: bool = False

    def perform(self, context: Context) -> WarmResult:
        from nsbench.bench.execute import warm_up

        return warm_up(self.case, self.suite, context.stage, probe=self.probe)


@dataclass(frozen=True)
class TimeCase:
    """Time ``runs`` warm samples of ``case`` in timing round ``round``; return the row.

    Round 0 gives the full row (metrics against ``reference``, and ``loops``, the
    runs per sample its calibration run chose), which the worker stores; a later
    round gives only its timings, taken with the ``loops`` of round 0, which the
    runner joins to it. ``warm`` is the case's first warm-up (its cold setup and
    warm-up times go in the row).
    """

    task: int
    case: Case
    suite: str
    reference: Reference
    warm: WarmResult
    round: int = 0
    runs: int = 1
    loops: int | None = None

    def perform(self, context: Context) -> Any:
        from nsbench.bench import storage
        from nsbench.bench.execute import complete_row, time_case

        stage = context.stage
        if self.round > 0:  # timings only: the runner joins them to the stored row
            return time_case(
                self.case,
                self.reference,
                self.suite,
                stage,
                count=self.runs,
                metrics=False,
                first_run=self.round,
                loops=self.loops,
            )
        row = complete_row(time_case(self.case, self.reference, self.suite, stage, count=self.runs), self.warm)
        stage("storing the row", None)  # raises ParentGone if the parent died meanwhile: then no row
        storage.append_row(context.hello.out, row, context.hello.provenance)  # here, not in the busy parent
        return row
