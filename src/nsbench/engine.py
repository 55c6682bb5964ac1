"""``nsbench.simulate``: one run of a problem with an integrator, as tidy frames; :func:`run`: the same run as buffers.

For an event-driven integrator the work is done by the hybrid core (:mod:`nsbench.hybrid`): the compiled loop
applies the stick/slip/reverse rules of MODEL.md, runs the integrator's compiled
arc kernel or calls its ``advance`` once per arc, records events, section hits
and states, and turns budget exhaustion, event storms and integrator failures
into a :class:`~nsbench.results.Status` instead of an exception or a hang. A
whole-system method (time-stepping, switch model, smoothing:
:mod:`nsbench.integrators.whole`) advances the whole system itself, and its
events are inferred from its steps (:mod:`nsbench.hybrid.inference`) into the
same records, so the result is the same type with the same columns. This
module checks the input, merges the requested times with stroboscopic
sections, times the run (``wall_time``, and ``cpu_time`` on the process's CPU clock;
``integrator_time`` is the part spent inside the integrator) and builds the frames.

:func:`run` is the entry below :func:`simulate` for the commands that want the
run's buffers rather than frames (sweeps, Lyapunov exponents, periodic orbits and
continuation): the same input checks, the same defaults (the storm span scaled by
the problem's time scale, the same budgets) and the same missed-crossing check
(:func:`check_points_for`), with the extra controls those commands need (a start
mode, stopping at the n-th section hit or event of a kind, keeping only what comes
after a transient). It returns a :class:`RunRecord` (events, section hits, dense
states, counters, by name); :func:`simulate` is :func:`run` plus the frames. No
module above this one imports :mod:`nsbench.hybrid` (``tests/test_layers.py``).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Iterable, Sequence, cast

import numpy as np

from nsbench.errors import ConfigError
from nsbench.integrators import Integrator, get_integrator
from nsbench.integrators.base import require_event_driven
from nsbench.integrators.whole import is_whole_system
from nsbench.hybrid.inference import run_whole
from nsbench.hybrid.run import run_hybrid, warm_up
from nsbench.hybrid.records import extrapolated as extrapolated_events  # noqa: F401 - for the layers above
from nsbench.hybrid.records import labels as event_labels  # noqa: F401 - for the layers above
from nsbench.hybrid.records import ACCUMULATION_ERROR, has_accumulation_limit
from nsbench.hybrid.records import match_accumulation_tails  # noqa: F401 - for the layers above
from nsbench.problems.base import HybridProblem
from nsbench.results import Counters, SimulationResult
from nsbench.sections import Section, StateSection, TimeSection
from nsbench.status import Status

if TYPE_CHECKING:  # pragma: no cover
    import pandas as pd

    from nsbench.integrators.whole import WholeSystem

# pandas is imported where the frames are made (simulate): the commands that read a run's buffers
# (a sweep's workers, Lyapunov's) do not load it (about half a CPU second per process)


def _resolve_integrator(integrator: Integrator | str, options: dict[str, Any] | None) -> Integrator:
    if isinstance(integrator, str):
        return get_integrator(integrator, **(options or {}))
    if options:
        raise ConfigError("pass options only together with an integrator name, not an instance")
    if not isinstance(integrator, Integrator):
        raise ConfigError(f"integrator must be a registered name or an Integrator, not {integrator!r}")
    return integrator


def _check_arguments(problem: Any, t_end: Any, t0: Any, options: Any) -> None:
    """The argument types of :func:`simulate`, checked at its entry: a text ``t_end`` was read as a
    number, and ``None`` for the problem ended in an ``AttributeError``."""
    import numbers

    if not isinstance(problem, HybridProblem):
        raise ConfigError(
            f"problem must be a problem from nsbench.get_problem (a HybridProblem), got "
            f"{type(problem).__name__} {problem!r}"[:200]
        )
    for name, value in (("t_end", t_end), ("t0", t0)):
        if isinstance(value, bool) or not isinstance(value, numbers.Real):
            raise ConfigError(f"{name} = {value!r} must be a number (a time), got {type(value).__name__}"[:200])
        try:
            float(value)
        except OverflowError:
            raise ConfigError(f"{name} = {str(value)[:20]}... is too large for a double") from None
    if options is not None and not isinstance(options, dict):
        raise ConfigError(f"options = {options!r} must be a dict of integrator options or None"[:200])


def _as_array(value: Any, name: str) -> np.ndarray:
    """``value`` (an iterable of numbers) as a float array; anything else is a :class:`ConfigError`."""
    try:
        return np.array(list(value), dtype=float)
    except (TypeError, ValueError, OverflowError) as exc:
        raise ConfigError(f"{name} must be an iterable of numbers: {exc}") from None


def _check_inputs(problem: HybridProblem, t0: float, t_end: float, y0: np.ndarray, t_eval: np.ndarray) -> None:
    if not (math.isfinite(t0) and math.isfinite(t_end)):
        raise ConfigError(f"time span [{t0}, {t_end}] must be finite")
    if not t_end > t0:
        raise ConfigError(f"t_end = {t_end:g} must be greater than t0 = {t0:g}")
    if y0.shape != (problem.n_states,):
        raise ConfigError(
            f"y0 has shape {y0.shape}; {problem.name} needs {problem.n_states} states "
            f"({', '.join(problem.state_names)})"
        )
    if not np.all(np.isfinite(y0)):
        raise ConfigError(f"y0 = {y0.tolist()} must be finite")
    if t_eval.size:
        if not np.all(np.isfinite(t_eval)) or np.any(np.diff(t_eval) < 0):
            raise ConfigError("t_eval must be finite and sorted in increasing order")
        if t_eval[0] < t0 or t_eval[-1] > t_end:
            raise ConfigError(f"t_eval must lie in [t0, t_end] = [{t0:g}, {t_end:g}]")


#: Largest step or event budget of a run (the compiled core counts in 64-bit integers).
MAX_BUDGET = 2**62
#: Default tolerance of an extrapolated accumulation time, relative to ``max(1, |t|)``.
DEFAULT_ACCUMULATION = 1e-14
#: Loosest tolerance ``accumulation`` takes: up to it the rule's error estimate covers the true error of
#: the accumulation time 2.7-3 times over on the impact oscillator (docs/core.md); at 1e-3 it fell below it.
MAX_ACCUMULATION = 1e-4


def _check_budgets(
    max_steps: Any, max_events: Any, zeno_events: Any, zeno_span: Any, accumulation: Any = DEFAULT_ACCUMULATION
) -> None:
    """Budgets are whole numbers from 1 to :data:`MAX_BUDGET`, the storm span a finite time > 0,
    ``accumulation`` 0 (off) or a tolerance in ``(0, MAX_ACCUMULATION]``."""
    import numbers

    real = isinstance(accumulation, numbers.Real) and not isinstance(accumulation, bool)
    if not (real and (accumulation == 0 or 0 < accumulation <= MAX_ACCUMULATION)):
        raise ConfigError(
            f"accumulation = {accumulation!r} must be 0 (no accumulation rule) or the tolerance of an "
            f"extrapolated accumulation time relative to max(1, |t|), a number in (0, {MAX_ACCUMULATION:g}] "
            f"(default {DEFAULT_ACCUMULATION:g}; no longer a count of intervals)"
        )
    for name, value in (("max_steps", max_steps), ("max_events", max_events), ("zeno_events", zeno_events)):
        whole = isinstance(value, numbers.Integral) and not isinstance(value, bool)
        if not (whole and 1 <= value <= MAX_BUDGET):
            raise ConfigError(
                f"{name} = {value!r} must be a whole number from 1 to {MAX_BUDGET} (nsbench.engine.MAX_BUDGET)"
            )
    if zeno_span is not None:
        real = isinstance(zeno_span, numbers.Real) and not isinstance(zeno_span, bool)
        if not (real and math.isfinite(zeno_span) and zeno_span > 0):
            raise ConfigError(
                f"zeno_span = {zeno_span!r} must be a finite time > 0 (or None: 1e-9 times the problem's time scale)"
            )


#: Largest ``check_points`` (as many dense states as ``nsbench simulate --samples`` allows).
MAX_CHECK_POINTS = 10**7
#: ``check_points`` of a run of an integrator that does not check its own steps (the default of
#: ``nsbench simulate --samples``): see :func:`check_points_for`.
DEFAULT_CHECK_POINTS = 3001


def _check_points(value: Any) -> None:
    """``check_points`` is 0 or a whole number from 2 to :data:`MAX_CHECK_POINTS`."""
    import numbers

    whole = isinstance(value, numbers.Integral) and not isinstance(value, bool)
    if not (whole and (value == 0 or 2 <= value <= MAX_CHECK_POINTS)):
        raise ConfigError(
            f"check_points = {value!r} must be 0 (no check points) or a whole number from 2 to "
            f"{MAX_CHECK_POINTS} (nsbench.engine.MAX_CHECK_POINTS)"
        )


def check_points_for(integ: Integrator) -> int:
    """The check points of a run of ``integ`` when the caller gives none (``check_points=None``).

    0 for an integrator that checks every guard on every accepted step itself
    (``capabilities.checks_steps``: every built-in event-driven integrator but ``henon-rk4``,
    whose fixed step is not sized to the guards; it locates a crossing pair inside one step
    instead of stepping over it) and for a whole-system method (its events are inferred from
    its steps; no state of the core is checked); :data:`DEFAULT_CHECK_POINTS` evenly spaced
    states over the span otherwise (``henon-rk4``, a plug-in whose root finding sees only the
    signs at its step ends), with or without a ``t_eval``.
    """
    if is_whole_system(integ) or integ.capabilities.checks_steps:
        return 0
    return DEFAULT_CHECK_POINTS


@dataclass(frozen=True)
class EventRecord:
    """The events a run kept, one row each, in time order.

    Attributes
    ----------
    t
        Event times.
    kind
        Codes into ``problem.event_kinds``.
    block
        1-based index of the element whose guard fired (the event log's ``block``).
    y, mode
        The state and the mode after each event, shapes ``(k, n_states)``, ``(k, mode_size)``.
    located
        A whole-system method's own time of each event (``SystemResult.switch_times``), NaN
        where it located none; ``None``: it locates none.
    err
        At an event the Zeno rule extrapolated, the error estimate of its time
        (:func:`nsbench.model.rules.tail_estimate`); NaN at every other event. ``None``: not kept.
    """

    t: np.ndarray
    kind: np.ndarray
    block: np.ndarray
    y: np.ndarray
    mode: np.ndarray
    located: np.ndarray | None = None
    err: np.ndarray | None = None

    def __len__(self) -> int:
        return int(self.t.shape[0])


@dataclass(frozen=True)
class HitRecord:
    """The section hits a run kept: ``section`` (index into the run's state sections), ``t``, ``y``."""

    section: np.ndarray
    t: np.ndarray
    y: np.ndarray

    def __len__(self) -> int:
        return int(self.t.shape[0])


@dataclass(frozen=True)
class DenseRecord:
    """The states at the requested times the run reached (``t`` a prefix of ``t_eval``), ``y`` of shape
    ``(k, n_states)``; the engine's check points are not among them."""

    t: np.ndarray
    y: np.ndarray

    def __len__(self) -> int:
        return int(self.t.shape[0])


@dataclass(frozen=True)
class RunRecord:
    """One run of :func:`run`, by name.

    Attributes
    ----------
    status, message
        How the run ended (:class:`~nsbench.status.Status`) and why.
    t, t_lo, y, mode
        Where it ended: time (compensated, ``t + t_lo``), state and mode.
    t0, start_mode
        Where it started (the mode after the start rule, before any event).
    events, hits, dense
        What it kept (:class:`EventRecord`, :class:`HitRecord`, :class:`DenseRecord`).
    n_events_total
        Every event of the run, kept or not (``record_from`` drops the earlier ones).
    stopped
        Whether it ended at its ``hit_stop``-th hit or its ``stop_count``-th event of ``stop_kind``.
    counters
        Cost counters of the whole run.
    wall_time, cpu_time
        Seconds of the run on the wall clock and on the process's CPU clock, without the first
        use of a mode's data (``prepare_time``).
    integrator_time
        Seconds inside the integrator (NaN where compiled code has no clock).
    prepare_time
        Seconds building the data of newly visited modes (first use, set-up rather than run).
    check_points
        The evenly spaced states the core checked the guards at besides ``t_eval``
        (:func:`check_points_for`); 0 with ``checked_steps`` true: the integrator checked
        every step itself.
    checked_steps
        Whether the integrator checks every guard on every accepted step.
    loop, loop_note
        Who ran the event loop (``'native'``: the integrator, whole-run protocol; ``'per-arc'``:
        the core, one arc per call; ``'whole-system'``: a time-stepping method, events inferred)
        and why an integrator with a loop of its own ran per arc (``''`` if it did not).
    internal
        A whole-system method's own states beside the problem's, one row per step (a DataFrame,
        ``SimulationResult.internal``); ``None`` for the others.
    batch
        The lanes of the batch the run went through with others (:func:`run_batch`: heyoka's
        batch mode, ``loop`` ``'native'``); 0: it ran alone.
    """

    status: Status
    message: str
    t: float
    t_lo: float
    y: np.ndarray
    mode: tuple[int, ...]
    t0: float
    start_mode: tuple[int, ...]
    events: EventRecord
    hits: HitRecord
    dense: DenseRecord
    n_events_total: int
    stopped: bool
    counters: Counters
    wall_time: float
    cpu_time: float
    integrator_time: float
    prepare_time: float
    check_points: int
    checked_steps: bool
    loop: str = "per-arc"
    loop_note: str = ""
    internal: Any = None
    batch: int = 0

    @property
    def ok(self) -> bool:
        return self.status.ok

    @property
    def crossings_checked(self) -> bool:
        """Whether a crossing pair the integrator stepped over would have been seen: the integrator checks
        its steps, or the core checked its evenly spaced check points inside the arcs. A ``t_eval`` of
        the caller's alone does not count (a handful of strobe times sees no excursion between them)."""
        return self.checked_steps or self.check_points > 0


def _records(raw, grid: np.ndarray, merged: np.ndarray | None) -> tuple[EventRecord, HitRecord, DenseRecord]:
    """The kept parts of a core run's buffers (views where no copy is needed); ``merged``: the dense
    times the core saw when check points were added to ``grid`` (None: it saw ``grid`` alone)."""
    rec, k, h = raw.records, raw.n_events, raw.n_hits
    ev = rec.events
    located = None if raw.located_t is None else np.asarray(raw.located_t, dtype=float)[:k]
    events = EventRecord(
        ev.t[:k], ev.kind[:k], (ev.index[:k] + 1).astype(np.int64), ev.y[:k], ev.mode[:k], located, ev.err[:k]
    )
    hits = HitRecord(rec.hits.index[:h], rec.hits.t[:h], rec.hits.y[:h])
    if merged is None:
        dense = DenseRecord(grid[: raw.n_dense], rec.dense.y[: raw.n_dense])
    else:  # the requested times' rows among the merged ones (a repeated time keeps its rows)
        rows = np.searchsorted(merged, grid)
        reached = int(np.count_nonzero(rows < raw.n_dense))
        dense = DenseRecord(grid[:reached], rec.dense.y[rows[:reached]])
    return events, hits, dense


#: The controls of :func:`run` that only the hybrid core has (a whole-system method runs none of them).
_CORE_ONLY = ("t0_lo", "mode", "hit_from", "hit_stop", "record_from", "stop_kind", "stop_count")


def run(
    problem: HybridProblem,
    integ: Integrator,
    t_end: float,
    *,
    t0: float = 0.0,
    t0_lo: float = 0.0,
    y0: Iterable[float] | None = None,
    mode: Sequence[int] | None = None,
    sections: Sequence[StateSection] = (),
    t_eval: Iterable[float] | None = None,
    hit_from: float = -math.inf,
    hit_stop: int = -1,
    record_from: float = -math.inf,
    stop_kind: str | None = None,
    stop_count: int = 0,
    max_steps: int = 5_000_000,
    max_events: int = 1_000_000,
    zeno_events: int = 64,
    zeno_span: float | None = None,
    accumulation: float = DEFAULT_ACCUMULATION,
    check_points: int | None = None,
) -> RunRecord:
    """Run ``problem`` with the set-up integrator ``integ`` over ``[t0, t_end]``: the buffers of the run.

    The entry of the commands that read a run's arrays (sweeps, Lyapunov exponents, periodic
    orbits, continuation), and what :func:`simulate` runs underneath: the same checks of the
    input, the same defaults and the same missed-crossing check.

    Parameters
    ----------
    problem, integ
        The problem and an integrator set up for it (:func:`prepare`).
    t_end, t0, t0_lo, y0, mode
        The span, the start time (compensated: ``t0 + t0_lo``), state (default: the problem's
        start state) and mode (default: the mode of the state, then the start rule).
    sections, t_eval
        State sections (:class:`~nsbench.sections.StateSection`) to record, and sorted times
        in ``[t0, t_end]`` for states.
    hit_from, hit_stop
        Section hits at ``t >= hit_from`` are kept; the run stops at the ``hit_stop``-th (-1: never).
    record_from, stop_kind, stop_count
        Events at ``t >= record_from`` are kept; the run stops after ``stop_count`` of kind
        ``stop_kind`` (one of ``problem.event_kinds``) among them.
    max_steps, max_events, zeno_events, zeno_span, accumulation
        As in :func:`simulate` (``zeno_span`` None: ``1e-9`` times the problem's time scale).
    check_points
        As in :func:`simulate`; None: :func:`check_points_for`.

    Returns
    -------
    RunRecord

    Raises
    ------
    ConfigError
        Bad input, or a control only the hybrid core has (``mode``, the stops, ``record_from``)
        asked of a whole-system method.
    """
    a = _checked(
        problem,
        integ,
        t_end,
        t0,
        t0_lo,
        y0,
        mode,
        sections,
        t_eval,
        hit_from,
        hit_stop,
        record_from,
        stop_kind,
        stop_count,
        max_steps,
        max_events,
        zeno_events,
        zeno_span,
        accumulation,
        check_points,
    )
    tic, cpu_tic = time.perf_counter(), time.process_time()
    if a.whole:  # time-stepping, switch model, smoothing: events inferred from the steps (nsbench.hybrid.inference)
        raw = run_whole(
            problem,
            cast("WholeSystem", integ),
            a.t_end,
            t0=a.hybrid["t0"],
            y0=a.hybrid["y0"],
            sections=a.hybrid["sections"],
            t_eval=a.hybrid["t_eval"],
            max_steps=max_steps,
        )
    else:
        raw = run_hybrid(problem, integ, a.t_end, **a.hybrid)
    # tables built for modes visited for the first time are first use (setup), not the run
    wall = time.perf_counter() - tic - raw.prepare_time
    # the process's CPU clock over the same stretch: on a shared machine the wall clock also counts
    # the time other programs held the core, the CPU clock only the work done (nsbench.bench.compare)
    cpu = max(0.0, time.process_time() - cpu_tic - raw.prepare_time)
    return _record(a, integ, raw, wall, cpu)


@dataclass(frozen=True)
class _Checked:
    """The checked arguments of one :func:`run`: the core's keyword arguments (``hybrid``, of
    :func:`~nsbench.hybrid.run.run_hybrid`), the requested grid and the merged one with check points."""

    t_end: float
    hybrid: dict[str, Any]
    grid: np.ndarray
    merged: np.ndarray | None
    check_points: int
    whole: bool


def _checked(
    problem,
    integ,
    t_end,
    t0,
    t0_lo,
    y0,
    mode,
    sections,
    t_eval,
    hit_from,
    hit_stop,
    record_from,
    stop_kind,
    stop_count,
    max_steps,
    max_events,
    zeno_events,
    zeno_span,
    accumulation,
    check_points,
) -> _Checked:
    """:func:`run`'s checks of its input (its arguments in its order) and its defaults."""
    _check_budgets(max_steps, max_events, zeno_events, zeno_span, accumulation)
    if check_points is None:
        check_points = check_points_for(integ)
    _check_points(check_points)
    y = problem.initial_state() if y0 is None else _as_array(y0, "y0")
    if t_eval is None:
        grid = np.empty(0)
    else:
        values = t_eval if isinstance(t_eval, np.ndarray) else list(t_eval)
        grid = np.ascontiguousarray(values, dtype=float).ravel()
    t0, t_end = float(t0), float(t_end)
    _check_inputs(problem, t0, t_end, y, grid)
    for s in sections:
        if not isinstance(s, StateSection):
            raise ConfigError(f"unknown section object {s!r}: the core records state sections (nsbench.sections)")
        if len(s.coeffs) != problem.n_states:
            raise ConfigError(
                f"section {s.name!r} has {len(s.coeffs)} coefficients; {problem.name} has {problem.n_states} states"
            )
    if mode is not None and len(mode) != problem.mode_size:
        raise ConfigError(f"mode {tuple(mode)!r} has {len(mode)} entries; {problem.name} has {problem.mode_size}")
    merged = None
    if check_points:  # states only the core's missed-crossing check sees (left out of the dense record)
        merged = np.union1d(grid, np.linspace(t0, t_end, int(check_points)))
    dense_times = grid if merged is None else merged
    span = zeno_span if zeno_span is not None else 1e-9 * max(1.0, problem.time_scale)
    whole = is_whole_system(integ)
    if whole:
        given = (t0_lo != 0.0, mode is not None, hit_from != -math.inf, hit_stop != -1, record_from != -math.inf)
        asked = [name for name, on in zip(_CORE_ONLY, (*given, stop_kind is not None, stop_count != 0)) if on]
        if asked:
            require_event_driven(integ, f"a run with {', '.join(asked)}")
    hybrid = dict(
        t0=t0,
        t0_lo=t0_lo,
        y0=y,
        mode=mode,
        sections=tuple(sections),
        t_eval=dense_times,
        hit_from=hit_from,
        hit_stop=hit_stop,
        record_from=record_from,
        stop_kind=stop_kind,
        stop_count=stop_count,
        max_steps=max_steps,
        max_events=max_events,
        zeno_events=zeno_events,
        zeno_span=span,
        accumulation=accumulation,
    )
    return _Checked(t_end, hybrid, grid, merged, int(check_points), whole)


def _record(a: _Checked, integ: Integrator, raw, wall: float, cpu: float) -> RunRecord:
    """The :class:`RunRecord` of a core run ``raw`` of the checked arguments ``a``."""
    events, hits, dense = _records(raw, a.grid, a.merged)
    return RunRecord(
        status=raw.status,
        message=raw.message,
        t=raw.t,
        t_lo=raw.t_lo,
        y=raw.y,
        mode=raw.mode,
        t0=raw.t0,
        start_mode=raw.start_mode,
        events=events,
        hits=hits,
        dense=dense,
        n_events_total=raw.n_events_total,
        stopped=raw.stopped,
        counters=raw.counters,
        wall_time=wall,
        cpu_time=cpu,
        integrator_time=raw.integrator_time,
        prepare_time=raw.prepare_time,
        check_points=a.check_points,
        checked_steps=bool(not a.whole and integ.capabilities.checks_steps),
        loop="whole-system" if a.whole else raw.loop,
        loop_note="" if a.whole else raw.loop_note,
        internal=getattr(raw, "internal", None),
        batch=int(getattr(raw, "batch", 0)),
    )


#: :func:`run`'s keyword arguments in :func:`_checked`'s order, and their defaults.
_RUN_NAMES = (
    "t0",
    "t0_lo",
    "y0",
    "mode",
    "sections",
    "t_eval",
    "hit_from",
    "hit_stop",
    "record_from",
    "stop_kind",
    "stop_count",
    "max_steps",
    "max_events",
    "zeno_events",
    "zeno_span",
    "accumulation",
    "check_points",
)
_RUN_DEFAULTS: dict[str, Any] = dict(run.__kwdefaults__ or {})


def batch_size(integ: Integrator) -> int:
    """How many runs :func:`run_batch` makes together with ``integ`` at most (its batch mode's lanes; 1
    for an integrator without one): a caller that hands out runs in groups sizes them so."""
    size = getattr(integ, "batch_size", None)
    return max(1, int(size())) if callable(size) and callable(getattr(integ, "run_batch", None)) else 1


class Each:
    """One value per problem for an argument of :func:`run_batch` (``Each([...])``: the i-th for the i-th
    problem); an argument given plainly is every problem's."""

    def __init__(self, values: Iterable[Any]) -> None:
        self.values = list(values)

    def __repr__(self) -> str:
        return f"Each({self.values!r})"


def _per_problem(n: int, t_end: Any, kwargs: dict[str, Any]) -> list[dict[str, Any]]:
    """The arguments of each of ``n`` runs (``t_end`` among them) from :func:`run_batch`'s."""
    given = dict(kwargs, t_end=t_end)
    for name, value in given.items():
        if isinstance(value, Each) and len(value.values) != n:
            raise ConfigError(f"{name} = Each(...) has {len(value.values)} values for {n} problems")
    return [{k: (v.values[i] if isinstance(v, Each) else v) for k, v in given.items()} for i in range(n)]


def run_batch(
    problems: Sequence[HybridProblem], integ: Integrator, t_end: "float | Each", **kwargs: Any
) -> list[RunRecord]:
    """:func:`run` of each problem with ``integ`` (the same arguments: plain, or :class:`Each` for one per
    problem), made together where the integrator has a batch mode that takes them.

    The problems differ only in runtime parameters (a sweep's values: ``v0``, the forcing) and each
    must run on the integrator's own loop (``native``); heyoka (double precision) then runs up to
    its SIMD width of them at once, one per lane (:mod:`nsbench.integrators._heyoka_batch`), each
    with its own records, budgets and checks, so that each record means what :func:`run` of that
    problem gives (``RunRecord.batch``: the lanes; its ``wall_time`` and ``cpu_time``: the batch's
    shared evenly). Otherwise (another integrator, a configuration or a problem that runs per
    arc, structures that differ) each problem is set up and run in turn by :func:`run`: the same
    records, with ``batch`` 0. The checks of :func:`run` are made on every run's arguments first.

    Returns
    -------
    list[RunRecord]
        One per problem, in order.
    """
    from nsbench.hybrid.run import batch_refusal, run_hybrid_batch

    each = _per_problem(len(problems), t_end, kwargs)
    names = ("t_end", *_RUN_NAMES)
    bad = sorted(set(kwargs) - set(names))
    if bad:
        raise ConfigError(f"run_batch: unknown argument {bad[0]!r}; run takes {', '.join(names)}")
    checked = [
        _checked(p, integ, a["t_end"], *[a.get(name, _RUN_DEFAULTS[name]) for name in _RUN_NAMES])
        for p, a in zip(problems, each)
    ]
    runs = [dict(c.hybrid, t_end=c.t_end) for c in checked]
    if len(problems) < 2 or any(c.whole for c in checked) or batch_refusal(problems, integ, runs):
        out = []
        for p, a in zip(problems, each):
            if len(problems) > 1:
                integ.setup(p)
            out.append(run(p, integ, **a))
        return out
    tic, cpu_tic = time.perf_counter(), time.process_time()
    raws = run_hybrid_batch(problems, integ, runs)
    prepared = sum(r.prepare_time for r in raws)
    wall = (time.perf_counter() - tic - prepared) / len(raws)
    cpu = max(0.0, time.process_time() - cpu_tic - prepared) / len(raws)
    return [_record(c, integ, raw, wall, cpu) for c, raw in zip(checked, raws)]


def prepare(problem: HybridProblem, integ: Integrator) -> None:
    """Set ``integ`` up for ``problem`` and load (or, on a machine's first use, compile) the core's loop for
    it: what :func:`run` needs before its first call on the problem (untimed)."""
    integ.setup(problem)
    if not is_whole_system(integ):
        warm_up(problem, integ)


def events_frame(problem: HybridProblem, events: EventRecord) -> pd.DataFrame:
    """The event log: ``t, kind, block, <states>, mode`` (the state and the mode after each event).

    ``kind`` is the event kind's name (``problem.event_kinds``), ``block`` the 1-based
    index of the element its guard belongs to, ``mode`` the problem's name of the mode;
    ``t_located`` after ``t`` where the method located its own switches (``events.located``).
    A problem whose law declares an accumulation limit also has the column
    ``accumulation_error`` (:data:`nsbench.hybrid.records.ACCUMULATION_ERROR`): the Zeno rule's
    error estimate at an event it extrapolated, NaN at every other event.
    """
    import pandas as pd

    k = len(events)
    frame = pd.DataFrame(events.y, columns=list(problem.state_names))
    frame.insert(0, "t", events.t.copy())
    frame.insert(
        1, "kind", np.asarray(problem.event_kinds, dtype=object)[events.kind] if k else np.empty(0, dtype=object)
    )
    frame.insert(2, "block", events.block)
    cache: dict[bytes, str] = {}
    texts = []
    for row in events.mode:
        key = row.tobytes()
        if key not in cache:
            cache[key] = problem.mode_name(tuple(int(v) for v in row))
        texts.append(cache[key])
    frame["mode"] = pd.Series(texts, dtype=object)
    if has_accumulation_limit(problem):
        err = events.err if events.err is not None else np.full(k, np.nan)
        frame[ACCUMULATION_ERROR] = np.asarray(err, dtype=float).copy()
    if events.located is not None:
        frame.insert(1, "t_located", events.located.copy())
    return frame


def _frames(
    problem: HybridProblem,
    rec: RunRecord,
    traj_mask: np.ndarray,
    strobe_names: list[str | None],
    state_sections: Sequence[StateSection],
):
    """Event log, sections (state crossings and stroboscopic states) and trajectory of a run."""
    import pandas as pd

    names = list(problem.state_names)
    events = events_frame(problem, rec.events)
    hits = rec.hits
    rows = [(state_sections[int(hits.section[j])].name, float(hits.t[j]), *hits.y[j]) for j in range(len(hits))]
    k = len(rec.dense)
    states, times = rec.dense.y, rec.dense.t
    for j in range(k):
        label = strobe_names[j]
        if label is not None:
            for sec_name in label.split("\n"):
                rows.append((sec_name, float(times[j]), *states[j]))
    sections = pd.DataFrame(rows, columns=["section", "t", *names])
    sections = sections.sort_values(["t"], kind="stable").reset_index(drop=True)
    mask = traj_mask[:k]
    traj = pd.DataFrame(states[mask], columns=names)
    traj.insert(0, "t", times[mask])
    phases = _phases_at(rec, times[mask], problem)
    for i, column in enumerate(problem.mode_columns):
        traj[column] = phases[:, i]
    return events, sections, traj


def _phases_at(rec: RunRecord, times: np.ndarray, problem: HybridProblem) -> np.ndarray:
    """The mode at each trajectory time: the mode after the last event at or before it (before the first
    event: the start mode), from the event record's modes."""
    out = np.empty((times.size, problem.mode_size), np.int8)
    if not times.size:
        return out
    ev_modes, ev_t = rec.events.mode, rec.events.t
    start = np.asarray(rec.start_mode, np.int8)
    # a state at an event time is the one just before the transition (the arc's end), except at the
    # start, where the requested states are those after the start's own transitions
    idx = np.searchsorted(ev_t, times, side="left") - 1
    at_start = times <= rec.t0
    idx[at_start] = np.searchsorted(ev_t, times[at_start], side="right") - 1
    out[:] = start
    has = idx >= 0
    out[has] = ev_modes[idx[has]]
    return out


def simulate(
    problem: HybridProblem,
    integrator: Integrator | str,
    t_end: float,
    *,
    options: dict[str, Any] | None = None,
    t0: float = 0.0,
    y0: Iterable[float] | None = None,
    t_eval: Iterable[float] | None = None,
    sections: Sequence[Section] = (),
    max_steps: int = 5_000_000,
    max_events: int = 1_000_000,
    zeno_events: int = 64,
    zeno_span: float | None = None,
    accumulation: float = DEFAULT_ACCUMULATION,
    check_points: int | None = None,
) -> SimulationResult:
    """Integrate ``problem`` with ``integrator`` over ``[t0, t_end]`` through every event.

    Parameters
    ----------
    problem
        A problem from :func:`nsbench.get_problem`.
    integrator
        A registered name (with ``options``) or a configured :class:`Integrator`.
    t_end
        End of the time span, in the problem's units.
    options
        Integrator options when ``integrator`` is a name.
    t0, y0
        Start time and state; default 0 and the problem's start state (its
        parameters; every block at rest at the origin for the friction problems).
    t_eval
        Times in ``[t0, t_end]`` for the trajectory (sorted).
    sections
        Observation sections (:mod:`nsbench.sections`) recorded into ``result.sections``.
    max_steps
        Step budget for the whole run (status ``BUDGET_EXHAUSTED`` past it): a
        whole number from 1 to :data:`MAX_BUDGET`.
    max_events
        Event budget for the whole run (the same range).
    zeno_events, zeno_span
        More than ``zeno_events`` (a whole number >= 1) consecutive events within
        ``zeno_span`` (a finite time > 0; default ``1e-9`` times the time scale)
        end the run with ``EVENT_STORM``.
    accumulation
        Consecutive events of one guard whose intervals shrink geometrically
        accumulate (Zeno): the accumulation time is extrapolated from the
        geometric tail and the problem's declared limit behaviour applied there,
        with an event of its own (the bouncing ball comes to rest) whose
        ``accumulation_error`` is the tail's error estimate. The rule
        extrapolates once that estimate is within this tolerance (relative to
        ``max(1, |t|)``, a number in ``(0, MAX_ACCUMULATION]``), at the rounding
        of the event times, or where more events cannot improve it or would not
        be resolved in double precision (docs/core.md, "Zeno accumulation").
        0: never.
    check_points
        Evenly spaced times in ``[t0, t_end]`` (a whole number, 0 or from 2 to
        :data:`MAX_CHECK_POINTS`) at which the integrator's dense states are computed
        but not returned, so that the core checks each guard's sign there as at
        ``t_eval``: a guard on its wrong side and back on its own side inside one
        arc ends the run with ``EVENT_MISSED`` (docs/core.md, "Missed events").
        ``None`` (the default): :func:`check_points_for`, none for an integrator that
        declares a check of every guard on each of its steps (every built-in event-driven
        integrator but ``henon-rk4``: a crossing pair inside one step is located, not
        stepped over), :data:`DEFAULT_CHECK_POINTS` for one that does not. With 0, an integrator
        that does not check its steps and no ``t_eval``, no state inside a step is
        seen and a crossing pair inside one step goes unnoticed; callers that compare
        the run with a reference themselves (the bench) pass 0 so that only the
        integrator's work is timed. ``nsbench simulate`` passes its ``--samples``.

    Returns
    -------
    SimulationResult
        Event log, sections, trajectory, counters, status, timings.

    Raises
    ------
    ConfigError
        Bad input (a problem that is not one, a time that is not a number, span, state, grid,
        unknown integrator or option) or an
        integrator that refuses the problem.
    """
    _check_arguments(problem, t_end, t0, options)
    _check_budgets(max_steps, max_events, zeno_events, zeno_span, accumulation)
    if check_points is not None:
        _check_points(check_points)
    integ = _resolve_integrator(integrator, options)
    y = problem.initial_state() if y0 is None else _as_array(y0, "y0")
    grid = np.empty(0) if t_eval is None else _as_array(t_eval, "t_eval").ravel()
    t0, t_end = float(t0), float(t_end)
    _check_inputs(problem, t0, t_end, y, grid)
    state_sections = tuple(s for s in sections if isinstance(s, StateSection))
    for s in state_sections:
        if len(s.coeffs) != problem.n_states:
            raise ConfigError(
                f"section {s.name!r} has {len(s.coeffs)} coefficients; {problem.name} has {problem.n_states} states"
            )
    strobes = [s for s in sections if isinstance(s, TimeSection)]
    unknown = [s for s in sections if not isinstance(s, (StateSection, TimeSection))]
    if unknown:
        raise ConfigError(f"unknown section objects {unknown!r}; use nsbench.sections")

    # Dense requests: the trajectory grid plus stroboscopic times, merged.
    labels: dict[float, list[str]] = {}
    for strobe in strobes:
        for ts in strobe.times(t0, t_end):
            labels.setdefault(float(ts), []).append(strobe.name)
    dense_times = np.union1d(grid, np.array(sorted(labels), dtype=float))
    traj_mask = np.isin(dense_times, grid)
    strobe_names = ["\n".join(labels[float(ts)]) if float(ts) in labels else None for ts in dense_times]

    tic = time.perf_counter()
    prepare(problem, integ)  # the compiled loop is loaded (or compiled) before the timed run
    setup_time = time.perf_counter() - tic
    rec = run(
        problem,
        integ,
        t_end,
        t0=t0,
        y0=y,
        sections=state_sections,
        t_eval=dense_times,
        max_steps=max_steps,
        max_events=max_events,
        zeno_events=zeno_events,
        zeno_span=zeno_span,
        accumulation=accumulation,
        check_points=check_points,
    )
    return _result(problem, integ, rec, setup_time, traj_mask, strobe_names, state_sections)


def result_of(problem: HybridProblem, integ: Integrator, rec: RunRecord, setup_time: float = 0.0) -> SimulationResult:
    """The :class:`SimulationResult` of ``rec``, a run of :func:`run` without stroboscopic sections (its
    ``t_eval`` states are the trajectory, its state sections' hits are not kept).

    For a caller that repeats a run and reads only the clocks of all but one (the bench's timed samples):
    building the event log and trajectory frames is nsbench's glue, milliseconds beside a run of one.
    """
    k = len(rec.dense)
    return _result(problem, integ, rec, setup_time, np.ones(k, dtype=bool), [None] * k, ())


def _result(
    problem: HybridProblem,
    integ: Integrator,
    rec: RunRecord,
    setup_time: float,
    traj_mask: np.ndarray,
    strobe_names: list[str | None],
    state_sections: Sequence[StateSection],
) -> SimulationResult:
    events, section_frame, trajectory = _frames(problem, rec, traj_mask, strobe_names, state_sections)
    return SimulationResult(
        problem=problem,
        integrator=integ.config(),
        status=rec.status,
        message=rec.message,
        events=events,
        sections=section_frame,
        trajectory=trajectory,
        counters=rec.counters,
        t_final=rec.t,
        y_final=np.array(rec.y, dtype=float),
        mode_final=rec.mode,
        wall_time=rec.wall_time,
        setup_time=setup_time + rec.prepare_time,
        integrator_time=rec.integrator_time,
        cpu_time=rec.cpu_time,
        loop=rec.loop,
        loop_note=rec.loop_note,
        internal=rec.internal,
    )
