"""The hybrid event-driven engine: it owns the stick/slip/reverse logic of MODEL.md.

The engine asks an integrator to advance one frozen mode until a guard fires,
applies the problem's transition map, fires at once any guard of the new mode
that is already on its wrong side (degenerate points only), and repeats. It
records the event log, the section hits and the trajectory, sums the counters,
and turns budget exhaustion, event storms and integrator failures into a
:class:`~nsbench.results.Status` instead of an exception or a hang.
"""

from __future__ import annotations

import math
import time
from collections import deque
from typing import Any, Iterable, Sequence

import numpy as np
import pandas as pd

from nsbench.errors import ConfigError
from nsbench.integrators import Integrator, get_integrator
from nsbench.integrators.base import ArcRequest
from nsbench.problems.modes import STICK, Guard, Mode, mode_name
from nsbench.problems.oscillator import FrictionOscillator
from nsbench.results import Counters, SimulationResult, Status, event_columns
from nsbench.sections import Section, StateSection, TimeSection

_EPS = np.finfo(float).eps


def _resolve_integrator(integrator: Integrator | str, options: dict[str, Any] | None) -> Integrator:
    if isinstance(integrator, str):
        return get_integrator(integrator, **(options or {}))
    if options:
        raise ConfigError("pass options only together with an integrator name, not an instance")
    if not isinstance(integrator, Integrator):
        raise ConfigError(f"integrator must be a registered name or an Integrator, not {integrator!r}")
    return integrator


def _check_inputs(problem: FrictionOscillator, t0: float, t_end: float, y0: np.ndarray,
                  t_eval: np.ndarray) -> None:
    if not (math.isfinite(t0) and math.isfinite(t_end)):
        raise ConfigError(f"time span [{t0}, {t_end}] must be finite")
    if not t_end > t0:
        raise ConfigError(f"t_end = {t_end:g} must be greater than t0 = {t0:g}")
    if y0.shape != (problem.n_states,):
        raise ConfigError(f"y0 has shape {y0.shape}; {problem.name} needs {problem.n_states} states "
                          f"({', '.join(problem.state_names)})")
    if not np.all(np.isfinite(y0)):
        raise ConfigError(f"y0 = {y0.tolist()} must be finite")
    if t_eval.size:
        if not np.all(np.isfinite(t_eval)) or np.any(np.diff(t_eval) < 0):
            raise ConfigError("t_eval must be finite and sorted in increasing order")
        if t_eval[0] < t0 or t_eval[-1] > t_end:
            raise ConfigError(f"t_eval must lie in [t0, t_end] = [{t0:g}, {t_end:g}]")


def _low_part(t: float, t_lo: float) -> float:
    """An integrator's low-order time part, or 0 if it is not a valid correction of ``t``."""
    t_lo = float(t_lo)
    return t_lo if math.isfinite(t_lo) and abs(t_lo) <= math.ulp(t) else 0.0


def _wrong_side(guard: Guard, t: float, y: np.ndarray, dydt: np.ndarray) -> bool:
    """Whether ``guard`` is already past its surface, or on it and heading the wrong way."""
    g = float(guard.value(t, y))
    phi = guard.expected_sign * g
    scale = max(1.0, abs(g), float(np.max(np.abs(y))))
    tol = 64.0 * _EPS * scale
    if phi < -tol:
        return True
    if abs(phi) <= tol:
        return guard.expected_sign * float(guard.rate(t, y, dydt)) < 0.0
    return False


def _pending_guard(problem: FrictionOscillator, mode: Mode, t: float, y: np.ndarray,
                   fresh: set[int]) -> Guard | None:
    """First guard of ``mode`` that must fire at once at ``(t, y)``.

    Blocks in ``fresh`` have just started a slip phase whose direction the
    transition rule chose from the forces; their velocity guard is zero by
    construction and is not re-tested.
    """
    dydt = None
    for guard in problem.guards(mode):
        if guard.kind == "velocity" and guard.block in fresh:
            continue
        if dydt is None:
            dydt = problem.rhs(mode, t, y)
        if _wrong_side(guard, t, y, dydt):
            return guard
    return None


class _Recorder:
    """Accumulates event rows, section rows and trajectory samples."""

    def __init__(self, problem: FrictionOscillator, dense_times: np.ndarray, traj_mask: np.ndarray,
                 strobe_names: list[str | None], state_sections: Sequence[StateSection]) -> None:
        self.problem = problem
        self.events: list[tuple] = []
        self.section_rows: list[tuple] = []
        self.dense_times = dense_times
        self.traj_mask = traj_mask
        self.strobe_names = strobe_names
        self.state_sections = state_sections
        self.dense_states: list[np.ndarray] = []
        self.dense_modes: list[Mode] = []
        self.n_dense = 0

    def event(self, t: float, kind: str, block: int, y: np.ndarray) -> None:
        self.events.append((t, kind, block, *map(float, y)))

    def dense(self, y_eval: np.ndarray, mode: Mode) -> None:
        k = y_eval.shape[1]
        if k:
            self.dense_states.append(np.array(y_eval, dtype=float))
            self.dense_modes.extend([mode] * k)
            self.n_dense += k

    def section(self, name: str, t: float, y: np.ndarray) -> None:
        self.section_rows.append((name, t, *map(float, y)))

    def frames(self) -> tuple[pd.DataFrame, pd.DataFrame, pd.DataFrame]:
        names = self.problem.state_names
        events = pd.DataFrame(self.events, columns=event_columns(names))
        events["block"] = events["block"].astype("int64")
        states = (np.hstack(self.dense_states) if self.dense_states
                  else np.empty((self.problem.n_states, 0)))
        times = self.dense_times[: self.n_dense]
        for j in range(self.n_dense):
            name = self.strobe_names[j]
            if name is not None:
                for sec_name in name.split("\n"):
                    self.section(sec_name, float(times[j]), states[:, j])
        sections = pd.DataFrame(self.section_rows, columns=["section", "t", *names])
        sections = sections.sort_values(["t"], kind="stable").reset_index(drop=True)
        mask = self.traj_mask[: self.n_dense]
        traj = pd.DataFrame(states[:, mask].T, columns=list(names))
        traj.insert(0, "t", times[mask])
        modes = np.array(self.dense_modes, dtype=np.int8).reshape(self.n_dense, self.problem.n_blocks)
        for i in range(self.problem.n_blocks):
            traj[f"phase{i + 1}"] = modes[mask, i]
        return events, sections, traj


def simulate(
    problem: FrictionOscillator,
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
        Start time and state; default 0 and the standard initial condition
        (every block at rest at the origin).
    t_eval
        Times in ``[t0, t_end]`` for the trajectory (sorted).
    sections
        Observation sections (:mod:`nsbench.sections`) recorded into ``result.sections``.
    max_steps
        Step budget for the whole run (status ``BUDGET_EXHAUSTED`` past it).
    max_events
        Event budget for the whole run.
    zeno_events, zeno_span
        More than ``zeno_events`` consecutive events within ``zeno_span`` (default
        ``1e-9`` times the time scale) end the run with ``EVENT_STORM``.

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
    integ = _resolve_integrator(integrator, options)
    y = problem.initial_state() if y0 is None else np.array(list(y0), dtype=float)
    grid = np.empty(0) if t_eval is None else np.asarray(list(t_eval), dtype=float).ravel()
    t0, t_end = float(t0), float(t_end)
    _check_inputs(problem, t0, t_end, y, grid)
    state_sections = tuple(s for s in sections if isinstance(s, StateSection))
    for s in state_sections:
        if len(s.coeffs) != problem.n_states:
            raise ConfigError(f"section {s.name!r} has {len(s.coeffs)} coefficients; "
                              f"{problem.name} has {problem.n_states} states")
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
    traj_mask = np.isin(dense_times, grid)
    strobe_names = ["\n".join(labels[float(ts)]) if float(ts) in labels else None for ts in dense_times]
    rec = _Recorder(problem, dense_times, traj_mask, strobe_names, state_sections)

    tic = time.perf_counter()
    integ.setup(problem)
    setup_time = time.perf_counter() - tic

    counters = Counters()
    status, message = Status.SUCCESS, ""
    span = zeno_span if zeno_span is not None else 1e-9 * max(1.0, problem.scales.time if problem.dimensional else 1.0)
    recent: deque[float] = deque(maxlen=zeno_events + 1)
    t = t0
    t_lo = 0.0  # compensated time: the current time is t + t_lo (see ArcRequest.t0_lo)
    tic = time.perf_counter()

    def settle(mode: Mode, t: float, y: np.ndarray, guard: Guard | None,
               fresh: set[int]) -> tuple[Mode, np.ndarray, tuple[Status, str] | None]:
        """Apply ``guard``'s transition and every one that must follow at the same time."""
        while guard is not None:
            tr = problem.transition(mode, guard, t, y)
            rec.event(t, tr.kind, tr.block, tr.y)
            counters.n_events += 1
            recent.append(t)
            if counters.n_events >= max_events:
                return tr.mode, tr.y, (Status.BUDGET_EXHAUSTED,
                                       f"event budget of {max_events} events reached at t = {t:.17g}")
            if len(recent) > zeno_events and recent[-1] - recent[0] <= span:
                return tr.mode, tr.y, (Status.EVENT_STORM, (
                    f"{zeno_events + 1} events within {recent[-1] - recent[0]:.3g} time units "
                    f"ending at t = {t:.17g} (mode {mode_name(tr.mode)})"
                ))
            mode, y = tr.mode, tr.y
            if tr.mode[tr.block - 1] != STICK:
                fresh = fresh | {tr.block}
            else:
                fresh = fresh - {tr.block}
            guard = _pending_guard(problem, mode, t, y, fresh)
        return mode, y, None

    # At t0 the state may sit on a surface: the same rule as after a transition.
    mode = problem.initial_mode(t0, y)
    fresh0 = {i + 1 for i, p in enumerate(mode) if p != STICK and y[2 * i + 1] == problem.v0}
    mode, y, stop = settle(mode, t0, y, _pending_guard(problem, mode, t0, y, fresh0), fresh0)
    n_at_start = int(np.searchsorted(dense_times, t0, side="right"))
    if n_at_start:
        rec.dense(np.repeat(y[:, None], n_at_start, axis=1), mode)
    if stop is not None:
        status, message = stop

    while status.ok and t < t_end:
        guards = problem.guards(mode)
        y_in = y.copy()
        y_in.flags.writeable = False
        request = ArcRequest(
            problem=problem, mode=mode, t0=t, y0=y_in, t_end=t_end, guards=guards,
            sections=state_sections, t_eval=dense_times[rec.n_dense:],
            max_steps=max_steps - counters.nsteps, t0_lo=t_lo,
        )
        try:
            arc = integ.advance(request)
        except Exception as exc:  # protocol violation by the integrator: keep what we have
            status, message = Status.INTEGRATOR_FAILURE, f"{type(exc).__name__}: {exc}"
            break
        counters.add(arc.nfev, arc.njev, arc.nsteps, arc.extra)
        expected = int(np.searchsorted(request.t_eval, arc.t, side="right"))
        y_eval = np.asarray(arc.y_eval, dtype=float).reshape(problem.n_states, -1)
        if arc.status.ok and y_eval.shape[1] != expected:
            status, message = Status.INTEGRATOR_FAILURE, (
                f"{integ.name} returned {y_eval.shape[1]} dense states for {expected} requested times"
            )
            break
        rec.dense(y_eval[:, :expected], mode)
        for hit in arc.section_hits:
            rec.section(state_sections[hit.index].name, float(hit.t), np.asarray(hit.y))
        if not arc.status.ok:
            status, message = arc.status, arc.message
            t, y = float(arc.t), np.asarray(arc.y, dtype=float)
            break
        if not (math.isfinite(arc.t) and np.all(np.isfinite(arc.y))):
            status, message = Status.INTEGRATOR_FAILURE, f"non-finite state at t = {arc.t}"
            break
        if arc.t < t or arc.t > t_end:
            status, message = Status.INTEGRATOR_FAILURE, (
                f"{integ.name} stopped at t = {arc.t!r} outside the arc [{t!r}, {t_end!r}]"
            )
            break
        t, y = float(arc.t), np.array(arc.y, dtype=float)
        t_lo = _low_part(t, arc.t_lo)
        if arc.fired is None:
            if t < t_end:
                status, message = Status.INTEGRATOR_FAILURE, (
                    f"{integ.name} stopped at t = {t!r} < t_end without an event"
                )
            break
        if counters.nsteps >= max_steps:
            status, message = Status.BUDGET_EXHAUSTED, f"{max_steps} steps used by t = {t:.6g}"
        mode, y, stop = settle(mode, t, y, guards[arc.fired], set())
        if stop is not None:
            status, message = stop

    wall = time.perf_counter() - tic
    events, section_frame, trajectory = rec.frames()
    return SimulationResult(
        problem=problem, integrator=integ.config(), status=status, message=message,
        events=events, sections=section_frame, trajectory=trajectory, counters=counters,
        t_final=t, y_final=np.array(y, dtype=float), mode_final=mode,
        wall_time=wall, setup_time=setup_time,
    )
