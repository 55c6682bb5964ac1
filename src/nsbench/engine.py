"""``nsbench.simulate``: one run of a problem with an integrator, as tidy frames.

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
"""

from __future__ import annotations

import math
import time
from typing import Any, Iterable, Sequence

import numpy as np
import pandas as pd

from nsbench.errors import ConfigError
from nsbench.integrators import Integrator, get_integrator
from nsbench.integrators.whole import is_whole_system
from nsbench.hybrid.inference import run_whole
from nsbench.hybrid.records import event_frame
from nsbench.hybrid.run import run_hybrid, warm_up
from nsbench.problems.base import HybridProblem
from nsbench.results import SimulationResult
from nsbench.sections import Section, StateSection, TimeSection


def _resolve_integrator(integrator: Integrator | str, options: dict[str, Any] | None) -> Integrator:
    if isinstance(integrator, str):
        return get_integrator(integrator, **(options or {}))
    if options:
        raise ConfigError("pass options only together with an integrator name, not an instance")
    if not isinstance(integrator, Integrator):
        raise ConfigError(f"integrator must be a registered name or an Integrator, not {integrator!r}")
    return integrator


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
#: Longest streak of intervals the accumulation rule looks at (the core keeps that many event times).
MAX_ACCUMULATION = 10_000


def _check_budgets(max_steps: Any, max_events: Any, zeno_events: Any, zeno_span: Any, accumulation: Any = 8) -> None:
    """Budgets are whole numbers from 1 to :data:`MAX_BUDGET`, the storm span a finite time > 0,
    ``accumulation`` 0 (off) or a whole number from 2 (one ratio of intervals) to :data:`MAX_ACCUMULATION`."""
    import numbers

    whole = isinstance(accumulation, numbers.Integral) and not isinstance(accumulation, bool)
    if not (whole and (accumulation == 0 or 2 <= accumulation <= MAX_ACCUMULATION)):
        raise ConfigError(
            f"accumulation = {accumulation!r} must be 0 (no accumulation rule) or a whole number "
            f"from 2 to {MAX_ACCUMULATION} (intervals of a streak; a ratio needs two)"
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
#: ``check_points`` of a run given no ``t_eval`` (the default of ``nsbench simulate --samples``).
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


def _frames(
    problem: HybridProblem,
    raw,
    dense_times: np.ndarray,
    traj_mask: np.ndarray,
    strobe_names: list[str | None],
    state_sections: Sequence[StateSection],
):
    """Event log, sections (state crossings and stroboscopic states) and trajectory of a run."""
    names = list(problem.state_names)
    rec = raw.records
    events = event_frame(problem, rec, raw.n_events, raw.located_t)
    rows = [(state_sections[int(rec.hk[j])].name, float(rec.ht[j]), *rec.hy[j]) for j in range(raw.n_hits)]
    k = raw.n_dense
    states = rec.y_eval[:k]
    times = dense_times[:k]
    for j in range(k):
        if strobe_names[j] is not None:
            for sec_name in strobe_names[j].split("\n"):
                rows.append((sec_name, float(times[j]), *states[j]))
    sections = pd.DataFrame(rows, columns=["section", "t", *names])
    sections = sections.sort_values(["t"], kind="stable").reset_index(drop=True)
    mask = traj_mask[:k]
    traj = pd.DataFrame(states[mask], columns=names)
    traj.insert(0, "t", times[mask])
    phases = _phases_at(events, raw, times[mask], problem)
    for i, column in enumerate(problem.mode_columns):
        traj[column] = phases[:, i]
    return events, sections, traj


def _phases_at(events: pd.DataFrame, raw, times: np.ndarray, problem: HybridProblem) -> np.ndarray:
    """The mode at each trajectory time: the mode after the last event at or before it (before the first
    event: the start mode), from the event log's ``mode`` column."""
    out = np.empty((times.size, problem.mode_size), np.int8)
    if not times.size:
        return out
    ev_modes = raw.records.ev_mode[: raw.n_events]
    ev_t = raw.records.ev_t[: raw.n_events]
    start = np.asarray(raw.start_mode, np.int8)
    # a state at an event time is the one just before the transition (the arc's end), except at the
    # start, where the requested states are those after the start's own transitions
    idx = np.searchsorted(ev_t, times, side="left") - 1
    at_start = times <= raw.t0
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
    accumulation: int = 8,
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
        When this many consecutive intervals between events of one guard shrink
        geometrically, the events accumulate (Zeno): the accumulation time is
        extrapolated and the problem's declared limit behaviour applied there,
        with an event of its own (the bouncing ball comes to rest). 0: never;
        otherwise a whole number from 2 to :data:`MAX_ACCUMULATION`.
    check_points
        Evenly spaced times in ``[t0, t_end]`` (a whole number, 0 or from 2 to
        :data:`MAX_CHECK_POINTS`) at which the integrator's dense states are computed
        but not returned, so that the core checks each guard's sign there as at
        ``t_eval``: a guard on its wrong side and back on its own side inside one
        arc ends the run with ``EVENT_MISSED`` (docs/core.md, "Missed events").
        ``None`` (the default): :data:`DEFAULT_CHECK_POINTS` when no ``t_eval`` is
        given, none beside a ``t_eval`` (whose states are checked). With 0 and
        without ``t_eval`` no state inside a step is seen, and a crossing pair
        inside one step goes unnoticed; callers that compare the run with a
        reference themselves (the bench) pass 0 so that only the integrator's
        work is timed.
        ``nsbench simulate`` passes its ``--samples``.

    Returns
    -------
    SimulationResult
        Event log, sections, trajectory, counters, status, timings.

    Raises
    ------
    ConfigError
        Bad input (span, state, grid, unknown integrator or option) or an
        integrator that refuses the problem.
    """
    _check_budgets(max_steps, max_events, zeno_events, zeno_span, accumulation)
    if check_points is None:
        check_points = DEFAULT_CHECK_POINTS if t_eval is None and float(t_end) > float(t0) else 0
    _check_points(check_points)
    integ = _resolve_integrator(integrator, options)
    y = problem.initial_state() if y0 is None else np.array(list(y0), dtype=float)
    grid = np.empty(0) if t_eval is None else np.asarray(list(t_eval), dtype=float).ravel()
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
    for s in strobes:
        for ts in s.times(t0, t_end):
            labels.setdefault(float(ts), []).append(s.name)
    dense_times = np.union1d(grid, np.array(sorted(labels), dtype=float))
    if check_points:  # states only the core's missed-crossing check sees (traj_mask leaves them out)
        dense_times = np.union1d(dense_times, np.linspace(t0, t_end, int(check_points)))
    traj_mask = np.isin(dense_times, grid)
    strobe_names = ["\n".join(labels[float(ts)]) if float(ts) in labels else None for ts in dense_times]

    whole = is_whole_system(integ)
    tic = time.perf_counter()
    integ.setup(problem)
    if not whole:
        warm_up(problem, integ)  # the compiled loop is loaded (or compiled) before the timed run
    setup_time = time.perf_counter() - tic

    span = zeno_span if zeno_span is not None else 1e-9 * max(1.0, problem.time_scale)
    tic, cpu_tic = time.perf_counter(), time.process_time()
    if whole:  # time-stepping, switch model, smoothing: events inferred from the steps (nsbench.hybrid.inference)
        raw = run_whole(
            problem, integ, t_end, t0=t0, y0=y, sections=state_sections, t_eval=dense_times, max_steps=max_steps
        )
    else:
        raw = run_hybrid(
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
            zeno_span=span,
            accumulation=accumulation,
        )
    # tables built for modes visited for the first time are first use (setup), not the run
    wall = time.perf_counter() - tic - raw.prepare_time
    # the process's CPU clock over the same stretch: on a shared machine the wall clock also counts
    # the time other programs held the core, the CPU clock only the work done (nsbench.bench.compare)
    cpu = max(0.0, time.process_time() - cpu_tic - raw.prepare_time)
    setup_time += raw.prepare_time
    events, section_frame, trajectory = _frames(problem, raw, dense_times, traj_mask, strobe_names, state_sections)
    return SimulationResult(
        problem=problem,
        integrator=integ.config(),
        status=raw.status,
        message=raw.message,
        events=events,
        sections=section_frame,
        trajectory=trajectory,
        counters=raw.counters,
        t_final=raw.t,
        y_final=np.array(raw.y, dtype=float),
        mode_final=raw.mode,
        wall_time=wall,
        setup_time=setup_time,
        integrator_time=raw.integrator_time,
        cpu_time=cpu,
        internal=raw.internal,
    )
