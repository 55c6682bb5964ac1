"""Energy balance along a computed trajectory: an invariant check for any integrator.

``E(t) - E(0) = W_friction + W_damping + W_force`` holds exactly along the true
solution (the spring forces are conservative). The works are integrated with
cumulative Simpson's rule arc by arc, splitting at every event, where the
friction force jumps; so the residual measures the integrator's error plus a
quadrature error of order ``dt^4`` for a trajectory sampled every ``dt``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, cast

import numpy as np
import pandas as pd
from scipy.integrate import cumulative_simpson

from nsbench.errors import ConfigError

if TYPE_CHECKING:  # pragma: no cover
    from nsbench.problems.oscillator import FrictionOscillator
    from nsbench.results import SimulationResult

COLUMNS = ["t", "energy_change", "work_friction", "work_damping", "work_force", "residual"]


def _modes_after(result: "SimulationResult") -> list[tuple]:
    """The mode after each event, from the event log's ``mode`` column."""
    return [result.problem.parse_mode(text) for text in result.events["mode"]]


def _cumulative(t: np.ndarray, f: np.ndarray) -> np.ndarray:
    if t.size == 1:
        return np.zeros(1)
    if t.size == 2:
        return np.array([0.0, 0.5 * (f[0] + f[1]) * (t[1] - t[0])])
    return np.concatenate([[0.0], cumulative_simpson(f, x=t)])


def energy_balance(result: "SimulationResult") -> pd.DataFrame:
    """Mechanical-energy change against the work of friction, damping and the force.

    Needs a result with a trajectory that starts at the initial time. Returns one
    row per trajectory sample and per side of each event, with the columns
    ``t, energy_change, work_friction, work_damping, work_force, residual``
    (``residual = energy_change - works``).
    """
    # energy and power are the friction oscillators' (a result of another problem has none)
    problem = cast("FrictionOscillator", result.problem)
    traj = result.trajectory
    names = list(problem.state_names)
    if traj.empty:
        raise ConfigError("energy_balance needs a trajectory: simulate with t_eval=...")
    times = traj["t"].to_numpy()
    states = traj[names].to_numpy().T
    phases = traj[list(problem.mode_columns)].to_numpy()
    t_start, y_start = float(times[0]), states[:, 0]
    modes_after = _modes_after(result)
    ev_t = result.events["t"].to_numpy()
    ev_y = result.events[names].to_numpy().T

    # Points of each arc: its start, the samples strictly inside, its end.
    arcs: list[tuple[list[float], list[np.ndarray], tuple]] = []
    bounds = [t_start, *ev_t.tolist(), float(times[-1])]
    starts = [y_start] + [ev_y[:, j] for j in range(ev_t.size)]
    arc_modes = [problem.initial_mode(t_start, y_start)] + modes_after
    for a in range(len(bounds) - 1):
        ta, tb = bounds[a], bounds[a + 1]
        if tb < ta:
            continue
        inside = (times > ta) & (times < tb)
        ts = [ta, *times[inside].tolist()]
        ys = [starts[a], *[states[:, k] for k in np.flatnonzero(inside)]]
        if a < ev_t.size:
            ts.append(tb)
            ys.append(ev_y[:, a])
        elif times[-1] > ta:
            ts.append(float(times[-1]))
            ys.append(states[:, -1])
        mode = arc_modes[a]
        if inside.any() and not np.all(phases[inside] == np.array(mode)):
            raise ConfigError("trajectory phases disagree with the event log; is the result complete?")
        arcs.append((ts, ys, mode))

    rows = []
    offset = np.zeros(3)
    e0 = float(problem.energy(y_start))
    for ts, ys, mode in arcs:
        t = np.array(ts)
        y = np.array(ys).T
        p = problem.power(mode, t, y)
        parts = np.vstack([np.broadcast_to(p[k], t.shape) for k in ("friction", "damping", "force")])
        work = np.vstack([_cumulative(t, parts[j]) for j in range(3)]) + offset[:, None]
        offset = work[:, -1].copy()
        de = problem.energy(y) - e0
        for k in range(t.size):
            rows.append((t[k], de[k], *work[:, k], de[k] - work[:, k].sum()))
    return pd.DataFrame(rows, columns=COLUMNS)
