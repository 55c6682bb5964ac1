"""Running one case, in a worker process: the untimed warm-up, the timed samples, the row.

A case runs in two steps, which the runner schedules apart (see
:mod:`nsbench.bench.scheduler`): :func:`warm_up` sets the integrator up
(compilation, operators) and runs a short untimed stretch of the span (first
use), and :func:`time_case` times ``case.repeats`` samples (each one run, or a
loop of runs shorter than ``case.min_sample_time``: :mod:`nsbench.bench.timing`)
and computes the metrics of the first run. Nothing a case does may end the suite: an integrator
that refuses the problem, fails, diverges or raises comes back as a row with its
status and reason. Only ``KeyboardInterrupt`` (and other ``BaseException``) propagates.

In a worker the wall-clock limit is enforced by the parent, which stops the
worker; :func:`run_case` (the in-process fallback) can only check it between
arcs, with :class:`TimeLimited`.
"""

from __future__ import annotations

import datetime as _dt
import gc
import math
import time
import traceback
from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

from nsbench.bench.keys import jsonable, problem_label
from nsbench.bench.metrics import case_metrics, dense_states_text, event_log_text
from nsbench.bench.reference import Reference
from nsbench.bench.schema import COLUMN_NAMES
from nsbench.bench.timing import loops_for, loops_within, needs_more, summarize
from nsbench.bench.suite import Case
from nsbench.errors import UnsupportedProblemError
from nsbench.integrators.base import ArcRequest, ArcResult, Integrator
from nsbench.results import Status


class TimeLimited(Integrator):
    """Wraps an integrator so that a run ends once ``limit`` seconds have passed.

    The check happens between arcs (one arc spans at most one phase), so a run
    overshoots the limit by at most one arc, and an integrator that runs the whole
    span in compiled code is not stopped at all. It is therefore only the
    in-process fallback's limit; in a worker the parent enforces the limit by
    ending the worker. The wrapped integrator's name, config and capabilities are
    reported unchanged.
    """

    def __init__(self, inner: Integrator, limit: float) -> None:  # no option parsing: a wrapper
        self.inner = inner
        self.name = inner.name  # type: ignore[misc]
        self.capabilities = inner.capabilities  # type: ignore[misc]
        self.settings = inner.settings
        self.limit = float(limit)
        self.deadline = math.inf
        self.hit = False

    def config(self) -> dict[str, Any]:
        return self.inner.config()

    def setup(self, problem) -> None:
        self.inner.setup(problem)
        self.deadline = time.perf_counter() + self.limit  # the engine times setup separately
        self.hit = False

    def advance(self, request: ArcRequest) -> ArcResult:
        if time.perf_counter() > self.deadline:
            self.hit = True
            return ArcResult(
                t=request.t0,
                y=np.array(request.y0),
                fired=None,
                y_eval=np.empty((request.problem.n_states, 0)),
                status=Status.BUDGET_EXHAUSTED,
                message=f"wall-clock limit of {self.limit:g} s reached at t = {request.t0:.6g}",
            )
        return self.inner.advance(request)


def base_row(case: Case, suite: str) -> dict[str, Any]:
    """The columns known before running: identity, configs, defaults for the rest."""
    from nsbench.integrators import get_integrator, integrator_class

    row: dict[str, Any] = {name: None for name in COLUMN_NAMES}
    cls = integrator_class(case.integrator)
    step_option = cls.capabilities.step_option
    try:
        config = get_integrator(case.integrator, **case.options).config()
    except Exception:  # validated when the suite was expanded; keep the row anyway
        config = {"name": case.integrator, "options": dict(case.options)}
    step_value = config["options"].get(step_option) if step_option else None
    row.update(
        case_id=case.case_id,
        suite=suite,
        problem=case.problem["name"],
        case=case.problem.get("case"),
        problem_label=problem_label(case.problem),
        problem_config=jsonable(case.problem),
        integrator=case.integrator,
        family=cls.capabilities.family,
        integrator_config=jsonable(config),
        options=jsonable(case.options),
        level=case.level,
        step_option=step_option or "",
        step_value=float(step_value) if isinstance(step_value, (int, float)) else math.nan,
        t0=case.t0,
        t_end=case.t_end,
        message="",
        wall_times=[],
        integrator_times=[],
        cpu_times=[],
        n_repeats=0,
        counters_extra="{}",
        reference="",
        reference_config="null",
        event_t=[],
        event_err=[],
        event_cert=[],
        event_log="",
        dense_states="",
    )
    return row


def _finish(row: dict[str, Any]) -> dict[str, Any]:
    row["timestamp"] = _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds")
    return row


#: Share of the span the warm-up run covers: enough to reach every mode's code, short next to the timing.
WARMUP_FRACTION = 0.1

#: ``stage(what, limit)``: told before each step of a case (the worker forwards it to the parent).
StageCallback = Callable[[str, "float | None"], None]


def _quiet(what: str, limit: float | None) -> None:
    return None


def _error_message(exc: Exception) -> str:
    return f"{type(exc).__name__}: {exc} | " + traceback.format_exc(limit=3).strip().splitlines()[-2].strip()


@dataclass(frozen=True)
class WarmResult:
    """What a warm-up leaves for the row: the cold setup and warm-up times, or a final row.

    ``row`` is set when the case cannot be timed (``unsupported``, ``error``,
    ``time limit`` in-process); it is then the case's row.
    """

    setup_time: float
    warmup_time: float
    row: dict[str, Any] | None = None
    #: the probe (:func:`probe_run`), NaN without one: the share of the span it ran, its engine run time
    #: and its whole call (set-up of the warm integrator and the result included)
    probe_span: float = math.nan
    probe_wall: float = math.nan
    probe_call: float = math.nan


def _components(case: Case, limit: float | None) -> tuple[Any, Integrator]:
    from nsbench.integrators import get_integrator
    from nsbench.problems import problem_from_config

    from nsbench.integrators.whole import is_whole_system

    integ = get_integrator(case.integrator, **case.options)
    # a whole-system method runs its span in one call: there is no arc between which to check the limit
    # (in a worker, the parent's limit applies as to every integrator)
    limited = limit is not None and not is_whole_system(integ)
    return problem_from_config(case.problem), (TimeLimited(integ, limit) if limited else integ)


def warm_up(
    case: Case, suite: str = "suite", stage: StageCallback = _quiet, in_process: bool = False, probe: bool = False
) -> WarmResult:
    """Set ``case`` up and run the first :data:`WARMUP_FRACTION` of its span, untimed.

    The setup compiles what the integrator compiles (numba kernels into numba's
    disk cache, heyoka models into heyoka's per-process cache); the short run
    pays every other first-use cost, so the timed runs that follow are warm.
    ``in_process`` checks the time limit between arcs (a worker is stopped by its parent instead).
    ``probe``: then time a warm stretch of the span too (:func:`probe_run`), the cost of a case the
    plan has no measured cost for.
    """
    from nsbench.engine import simulate

    row = base_row(case, suite)
    t_end = case.t0 + WARMUP_FRACTION * (case.t_end - case.t0)
    grid = np.linspace(case.t0, case.t_end, case.dense_points)
    try:
        problem, integ = _components(case, case.time_limit if in_process else None)
        stage("setup", case.setup_limit)  # compilation included: generous, a setup that never ends is the target
        tic = time.perf_counter()
        integ.setup(problem)
        setup_time = time.perf_counter() - tic
        stage("warm-up run", case.time_limit)
        res = simulate(problem, integ, t_end, t0=case.t0, t_eval=grid[grid <= t_end], max_steps=case.max_steps)
    except UnsupportedProblemError as exc:
        row.update(status="unsupported", message=str(exc))
        return WarmResult(math.nan, math.nan, _finish(row))
    except Exception as exc:  # a bug or a refusal we do not know: a row, never a lost suite
        row.update(status="error", message=_error_message(exc))
        return WarmResult(math.nan, math.nan, _finish(row))
    if isinstance(integ, TimeLimited) and integ.hit:
        row.update(
            status="time limit", message=f"{res.message} (warm-up run)", t_final=res.t_final, setup_time=setup_time
        )
        return WarmResult(setup_time, res.wall_time, _finish(row))
    if not (probe and res.ok):
        return WarmResult(setup_time, res.wall_time)
    try:
        stage("probe run", case.time_limit)
        span, wall, call = probe_run(problem, integ, case, grid, float(res.wall_time))
    except Exception:  # the probe only informs the plan: the case is timed (and fails, if it does) as any other
        return WarmResult(setup_time, res.wall_time)
    return WarmResult(setup_time, res.wall_time, probe_span=span, probe_wall=wall, probe_call=call)


#: Seconds a probe run aims at: long enough for a rate (hundreds of scheduler slices), short next to
#: a suite's timing (a hundred unmeasured cases cost 20 s of workers more).
PROBE_SECONDS = 0.2


def probe_run(problem, integ, case: Case, grid: np.ndarray, warm_wall: float) -> tuple[float, float, float]:
    """``(share of the span, engine run seconds, whole call seconds)`` of a warm run of about
    :data:`PROBE_SECONDS` from ``case.t0``.

    Its share of the span comes from the warm-up run (``warm_wall`` over :data:`WARMUP_FRACTION`), which
    may hold first-use costs (a lazy compilation in the first step) and so overstate the rate: a probe
    far shorter than aimed at runs once more, longer, from its own rate (at most three runs, each aimed
    at :data:`PROBE_SECONDS`). No compilation is in it: the warm-up paid for it.
    """
    from nsbench.engine import simulate

    span, length = WARMUP_FRACTION, case.t_end - case.t0
    rate = max(float(warm_wall), 1e-6) / span  # engine seconds per whole span
    for _ in range(3):
        span = min(1.0, PROBE_SECONDS / rate, 20.0 * span)
        t_end = case.t0 + span * length
        tic = time.perf_counter()
        res = simulate(problem, integ, t_end, t0=case.t0, t_eval=grid[grid <= t_end], max_steps=case.max_steps)
        call = time.perf_counter() - tic
        wall = float(res.wall_time)
        if not res.ok or span >= 1.0 or call >= PROBE_SECONDS / 4:
            break
        rate = max(wall, 1e-6) / span
    return span, wall, call


@dataclass
class _Sample:
    """One timed sample: ``loops`` runs back to back, their mean per run on each clock, and the first run's result."""

    wall: float
    cpu: float
    inner: float
    setup: float
    run: Any  # the first run's SimulationResult (the failing run's, if one failed)
    hit: bool = False  # the in-process time limit ended it


def _quiet_heap() -> None:
    """Collect the garbage of what ran before, then freeze the survivors (:func:`gc.freeze`).

    With heyoka, numba and pandas loaded a full collection walks a few hundred
    thousand objects (0.3-0.45 s measured on the 2-core development machine); a
    frozen object is never walked again, so the collection here and any the
    interpreter starts during the sample only see the sample's own objects (5e-5 s).
    Nothing frozen is freed by the cycle collector afterwards; survivors are
    what the worker keeps anyway (modules, compiled code, the case's objects).
    """
    gc.collect()
    gc.freeze()


def _sample(problem, integ, case: Case, grid: np.ndarray, loops: int) -> _Sample:
    """``loops`` full runs of ``case``, timed by the engine (each run's own clocks, summed).

    The first run goes through :func:`nsbench.engine.simulate` (its result is the sample's); the
    others through :func:`nsbench.engine.run`, the same run without the event log and trajectory
    frames, which only their clocks are read from: building the frames is nsbench's glue, outside
    every clock here but 3-5 ms a run (measured: a looped sample of 50 heyoka runs of 1 ms took
    0.26 s with them), so a looped sample took several times its ``min_sample_time``. A run that
    fails ends the sample with its own result. The caller quiets the heap first
    (:func:`_quiet_heap`), before it announces the sample's stage, so the collection never counts
    against the time limit.
    """
    from nsbench.engine import result_of, run, simulate

    first = simulate(problem, integ, case.t_end, t0=case.t0, t_eval=grid, max_steps=case.max_steps)
    wall, cpu, inner, setup = float(first.wall_time), float(first.cpu_time), float(first.integrator_time), 0.0
    setup = float(first.setup_time)
    hit = isinstance(integ, TimeLimited) and integ.hit
    if hit or not first.ok:  # a failed run ends the sample; it is not repeated
        return _Sample(first.wall_time, first.cpu_time, first.integrator_time, setup, first, hit)
    for _ in range(max(1, loops) - 1):
        rec = run(problem, integ, case.t_end, t0=case.t0, t_eval=grid, max_steps=case.max_steps)
        wall += float(rec.wall_time)
        cpu += float(getattr(rec, "cpu_time", math.nan))
        inner += float(getattr(rec, "integrator_time", math.nan))  # NaN where the engine has no clock
        hit = isinstance(integ, TimeLimited) and integ.hit
        if hit or not rec.status.ok:
            failed = result_of(problem, integ, rec, setup)
            return _Sample(failed.wall_time, failed.cpu_time, failed.integrator_time, setup, failed, hit)
    n = max(1, loops)
    return _Sample(wall / n, cpu / n, inner / n, setup, first)


def time_case(
    case: Case,
    reference: Reference,
    suite: str = "suite",
    stage: StageCallback = _quiet,
    in_process: bool = False,
    count: int | None = None,
    metrics: bool = True,
    first_run: int = 0,
    loops: int | None = None,
) -> dict[str, Any]:
    """Time ``count`` samples of ``case`` (default ``case.repeats``; after :func:`warm_up` in this process).

    Without ``loops`` (the first timing round) a *calibration* run comes first:
    it gives the events, counters and, with ``metrics``, the metrics against
    ``reference`` (runs are deterministic), and its time sets ``loops``, the runs
    per sample (:func:`nsbench.bench.timing.loops_for` with the case's
    ``min_sample_time``). A run that long is itself the first sample; a shorter
    one is not counted. Later rounds (``loops`` given, ``metrics=False``) time
    their samples with the same ``loops``. A run that does not succeed ends the
    timing (no further samples). The row's ``setup_time`` and ``warmup_time`` are
    the warm-up's: the caller sets them. The runner's workers time one sample
    per call, in rounds over all cases (``first_run``: the samples of the case
    timed before, which numbers the stages), and join the rounds with
    :func:`merge_runs`.
    """
    from nsbench.engine import simulate

    row = base_row(case, suite)
    row.update(reference_config=jsonable(reference.config), **reference.columns())
    grid = np.linspace(case.t0, case.t_end, case.dense_points)
    samples: list[_Sample] = []
    n_samples = case.repeats if count is None else int(count)
    total = max(case.repeats, first_run + n_samples)
    try:
        problem, integ = _components(case, case.time_limit if in_process else None)
        first = None
        if loops is None:
            _quiet_heap()
            stage(f"timed sample {first_run + 1} of {total} (its calibration run)", case.time_limit)
            tic = time.perf_counter()
            first = simulate(problem, integ, case.t_end, t0=case.t0, t_eval=grid, max_steps=case.max_steps)
            call = time.perf_counter() - tic
            loops = loops_for(float(first.wall_time), case.min_sample_time)
            # the time limit covers a whole sample (one stage): a run of 0.1 ms in a call of 2 ms (setting up,
            # building the result) loops 500 times, a 1 s sample; keep a looped sample within a quarter of the
            # limit, a 4x margin for a busy machine
            loops = loops_within(loops, call, case.time_limit / 4.0)
            hit = isinstance(integ, TimeLimited) and integ.hit
            if loops == 1 or hit or not first.ok:  # long enough (or failed): it is the first sample
                samples.append(
                    _Sample(first.wall_time, first.cpu_time, first.integrator_time, first.setup_time, first, hit)
                )
        while len(samples) < n_samples and not (samples and (samples[-1].hit or not samples[-1].run.ok)):
            k = first_run + len(samples) + 1
            _quiet_heap()  # before the stage: a full collection (0.3-0.45 s idle) is no part of a run's limit
            stage(f"timed sample {k} of {total}" + (f" ({loops} runs)" if loops > 1 else ""), case.time_limit)
            samples.append(_sample(problem, integ, case, grid, loops))
    except Exception as exc:  # after a clean warm-up: rare, but a row all the same
        row.update(status="error", message=_error_message(exc))
        return _finish(row)
    lead = first if first is not None else samples[0].run
    last = samples[-1]
    if last.hit:
        row.update(status="time limit", message=last.run.message, t_final=last.run.t_final)
        return _finish(row)
    notes = [lead.message] if lead.message else []
    notes += [
        f"timed sample {k + 1} ended with {s.run.status.value}: {s.run.message}"
        for k, s in enumerate(samples)
        if s.run.status != lead.status
    ]
    wall = [float(s.wall) for s in samples]
    inner = [float(s.inner) for s in samples]
    cpu = [float(s.cpu) for s in samples]
    counters = lead.counters.as_dict()
    extra = {k: v for k, v in counters.items() if k not in ("nfev", "njev", "nsteps", "n_events")}
    row.update(
        status=lead.status.value,
        message=" | ".join(notes),
        loop=lead.loop,
        t_final=lead.t_final,
        nfev=int(counters["nfev"]),
        njev=int(counters["njev"]),
        nsteps=int(counters["nsteps"]),
        n_events=int(counters["n_events"]),
        counters_extra=jsonable(extra),
        event_log=event_log_text(lead.events),  # kept so that an archive re-grades the run from it
        wall_times=wall,
        n_repeats=len(wall),
        integrator_times=inner,
        cpu_times=cpu,
        loops=int(loops),
        setup_time_timed=max(float(s.setup) for s in samples),
        **summarize(wall, inner, cpu),
    )
    dense = None
    if lead.ok and len(lead.trajectory) == case.dense_points:
        dense = lead.trajectory[list(problem.state_names)].to_numpy().T
        row["dense_states"] = dense_states_text(dense, lead.y_final)  # an archive re-grades the state errors
    if metrics and reference.ok:
        belt = problem.v0 if problem.traits.belt_blocks else None  # the stick creep needs a belt
        from nsbench.bench.metrics import creep_cone

        cone = None
        if belt is not None and reference.y_dense is not None:
            cone = creep_cone(problem, grid, reference.y_dense, dense)
        metrics = case_metrics(
            reference.events,
            lead.events,
            reference.y_dense,
            dense,
            reference.y_final,
            lead.y_final,
            times=grid,
            v_belt=belt,
            t_end=case.t_end,
            cone=cone,
        )
        if problem.traits.impacts and hasattr(problem, "energy"):
            from nsbench.bench.metrics import impact_metrics

            metrics["penetration"], metrics["energy_err"] = impact_metrics(
                problem.energy, dense, reference.y_final, lead.y_final if lead.ok else None
            )
        if lead.ok and reference.t_dense.size:
            # the order on a smooth arc, apart from the switches: one more short run, untimed
            from nsbench.bench.families import smooth_arc_error

            metrics["arc_err"] = smooth_arc_error(
                problem, integ, reference.events, reference.t_dense, reference.y_dense, belt
            )
        if metrics.pop("truncated"):
            row["message"] = (
                row["message"] + " | " if row["message"] else ""
            ) + "event logs too long: only their starts were aligned"
        row.update(metrics)
    return _finish(row)


def merge_runs(row: dict[str, Any], more: dict[str, Any]) -> dict[str, Any]:
    """``row`` (a case's earlier timed samples, with its metrics) joined with the samples of ``more``.

    ``more`` is a later round of the same case (:func:`time_case` without
    metrics). Its timings are added and the summary columns recomputed; a round
    that ended otherwise than the first (a time limit, a crash, another status)
    adds no timing and leaves a note in the message, never replaces the row.
    """
    out = dict(row)
    if more.get("status") != row.get("status") or not more.get("wall_times"):
        note = f"a later timed sample ended with {more.get('status')}: {more.get('message') or 'no message'}"
        out["message"] = f"{out['message']} | {note}" if out.get("message") else note
        return out
    joined = {
        name: [float(w) for w in row.get(name) or []] + [float(w) for w in more.get(name) or []]
        for name in ("wall_times", "integrator_times", "cpu_times")
    }
    out.update(
        joined,
        n_repeats=len(joined["wall_times"]),
        **summarize(joined["wall_times"], joined["integrator_times"], joined["cpu_times"]),
        setup_time_timed=max(float(row["setup_time_timed"]), float(more["setup_time_timed"])),
    )
    return out


def complete_row(row: dict[str, Any], warm: WarmResult) -> dict[str, Any]:
    """The timed ``row`` with the warm-up's cold setup time and warm-up run time."""
    row.update(setup_time=warm.setup_time, warmup_time=warm.warmup_time)
    return row


def run_case(case: Case, reference: Reference, suite: str = "suite") -> dict[str, Any]:
    """Warm ``case`` up and time it in this process (the fallback without workers); its row.

    Its planned samples first, then, while they spread widely, one more at a time up to
    ``case.max_repeats`` (:func:`nsbench.bench.timing.needs_more`).
    """
    warm = warm_up(case, suite, in_process=True)
    if warm.row is not None:
        return warm.row
    row = time_case(case, reference, suite, in_process=True)
    while needs_more(row, case.max_repeats or case.repeats):
        more = time_case(
            case,
            reference,
            suite,
            in_process=True,
            count=1,
            metrics=False,
            first_run=int(row["n_repeats"]),
            loops=int(row["loops"]),
        )
        grown = merge_runs(row, more)
        if grown["n_repeats"] == row["n_repeats"]:  # the sample failed: its note is kept, no more
            row = grown
            break
        row = grown
    return complete_row(row, warm)
