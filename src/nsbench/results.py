"""Named results of a simulation: status, counters, event log, sections, trajectory.

Column conventions (documented, relied on by reports):

- events: ``t, kind, block, x1, v1[, x2, v2, ...], mode``; ``kind`` in ``stick, slip,
  reverse``; the state and the mode (e.g. ``'stick|slip-'``) are those *after* the transition.
- sections: ``section, t, x1, v1[, x2, v2]``.
- trajectory: ``t, x1, v1[, x2, v2], phase1[, phase2]`` with phases -1 (slip-),
  0 (stick), +1 (slip+): the problem's ``mode_columns``, the entries of the mode.

Other problems name their own event kinds, states and mode entries (``problem.event_kinds``,
``problem.state_names``, ``problem.mode_columns``); ``block`` is the 1-based index of the
element the event's guard belongs to.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any, cast

import numpy as np

from nsbench.problems.base import Mode
from nsbench.status import Status

__all__ = ["Status", "Counters", "SimulationResult", "event_columns"]

if TYPE_CHECKING:  # pragma: no cover
    import pandas as pd

    from nsbench.problems.base import HybridProblem
    from nsbench.problems.oscillator import FrictionOscillator


@dataclass
class Counters:
    """Cost counters. ``extra`` holds integrator-specific ones (iterations, segments, ...)."""

    nfev: int = 0
    njev: int = 0
    nsteps: int = 0
    n_events: int = 0
    extra: dict[str, float] = field(default_factory=dict)

    def add(self, nfev: int = 0, njev: int = 0, nsteps: int = 0, extra: dict[str, float] | None = None) -> None:
        self.nfev += int(nfev)
        self.njev += int(njev)
        self.nsteps += int(nsteps)
        for key, value in (extra or {}).items():
            self.extra[key] = self.extra.get(key, 0) + value

    def as_dict(self) -> dict[str, float]:
        """Flat dict: the four standard counters then the extras."""
        out: dict[str, float] = {"nfev": self.nfev, "njev": self.njev, "nsteps": self.nsteps, "n_events": self.n_events}
        out.update(self.extra)
        return out


def event_columns(state_names: tuple[str, ...]) -> list[str]:
    """Columns of an event log for a problem with these state names."""
    return ["t", "kind", "block", *state_names, "mode"]


@dataclass(frozen=True)
class SimulationResult:
    """Everything one run of the hybrid engine produced.

    Attributes
    ----------
    problem
        The problem that was integrated (its units are the result's units).
    integrator
        Config dict of the integrator (``{'name': ..., 'options': {...}}``).
    status, message
        How the run ended and why.
    events
        The event log (see module docstring), in the problem's units.
    sections
        Observation-section hits.
    trajectory
        States on the requested grid, or an empty frame if none was requested.
    counters
        Cost counters summed over the run.
    t_final, y_final, mode_final
        Where the run stopped.
    wall_time
        Seconds the run took (excluding ``setup_time``): the integrator and nsbench's hybrid core.
    setup_time
        Seconds spent in the integrator's ``setup`` (compilation, operators) and loading the core.
    integrator_time
        Seconds spent inside the integrator: its compiled arc kernels, or its ``advance``
        calls; ``wall_time - integrator_time`` is the core's share (events, records).
        NaN where the platform offers no clock to compiled code.
    cpu_time
        CPU seconds of this process over the same stretch as ``wall_time``: the work
        done, without the time other programs held the core (NaN if not measured).
    loop
        Who ran the event loop (:data:`nsbench.integrators.base.LOOP_PATHS`): ``'native'`` (the
        integrator's own loop, calling the core's compiled rules), ``'per-arc'`` (the core's loop,
        one ``advance`` per arc), ``'kernel'`` (the core's loop with a compiled arc kernel),
        ``'whole-system'`` (a time-stepping, switch-model or smoothing method).
    loop_note
        Why an integrator with a loop of its own ran per arc (its ``loop`` option, or what it
        cannot run natively: a start on a double zero); empty otherwise.
    internal
        A whole-system method's own states beside the problem's (``lugre``'s bristle
        deflections ``z1 .. zn``), one row per step with its time ``t``; ``None`` for the others.
    """

    problem: "HybridProblem"
    integrator: dict[str, Any]
    status: Status
    message: str
    events: pd.DataFrame
    sections: pd.DataFrame
    trajectory: pd.DataFrame
    counters: Counters
    t_final: float
    y_final: np.ndarray
    mode_final: Mode
    wall_time: float
    setup_time: float
    integrator_time: float = float("nan")
    cpu_time: float = float("nan")
    loop: str = "per-arc"
    loop_note: str = ""
    internal: pd.DataFrame | None = None

    @property
    def ok(self) -> bool:
        return self.status.ok

    def summary(self) -> str:
        """A few lines for a terminal: status, events by kind and block, counters, times."""
        lines = [
            f"problem     {self.problem!r}",
            f"integrator  {self.integrator['name']} {self.integrator.get('options', {})}",
            f"status      {self.status.value}" + (f": {self.message}" if self.message else ""),
            f"loop        {self.loop}" + (f" ({self.loop_note})" if self.loop_note else ""),
            f"t_final     {self.t_final:.6g}   final mode {self.problem.mode_name(self.mode_final)}",
        ]
        if len(self.events):
            table = self.events.groupby(["kind", "block"]).size()
            parts = [f"{kind}@{block}: {n}" for (kind, block), n in table.items()]
            lines.append(f"events      {len(self.events)} ({', '.join(parts)})")
        else:
            lines.append("events      0")
        counters = ", ".join(f"{k}={v:g}" for k, v in self.counters.as_dict().items())
        lines.append(f"counters    {counters}")
        lines.append(
            f"wall time   {self.wall_time:.4g} s, of which {self.integrator_time:.4g} s in the "
            f"integrator (setup {self.setup_time:.3g} s)"
        )
        return "\n".join(lines)

    def dimensionless(self) -> "SimulationResult":
        """The same result with every table in dimensionless units (MODEL.md section 2)."""
        from nsbench.units import dimensionless_problem, to_dimensionless

        if not self.problem.dimensional:
            return self
        # only the friction oscillators are built in dimensional units
        problem = cast("FrictionOscillator", self.problem)
        s = problem.scales
        y = np.array(self.y_final, dtype=float)
        y[0::2] /= s.length
        y[1::2] /= s.velocity
        return replace(
            self,
            problem=dimensionless_problem(problem),
            events=to_dimensionless(self.events, s),
            sections=to_dimensionless(self.sections, s),
            trajectory=to_dimensionless(self.trajectory, s),
            t_final=self.t_final / s.time,
            y_final=y,
        )
