"""The locus of sticking phase: the path of ``(x1, x2)`` while a block sticks, and the sliding regions.

Sliding region I is ``|R1| <= fr1`` with every velocity at the belt speed,
region II ``|R2| <= fr2`` (it moves with time when forced: evaluated at a given
phase), region III their overlap. Mapping points are the slip events: where
the locus leaves a sliding region.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd


@dataclass
class LocusRun:
    """A trajectory over a recording window, with its events, for locus and portrait figures."""

    problem: object
    value: float | None
    trajectory: pd.DataFrame
    events: pd.DataFrame
    t_start: float
    t_end: float
    integrator: str

    @property
    def mapping_points(self) -> pd.DataFrame:
        ev = self.events
        return ev[ev["kind"] == "slip"].reset_index(drop=True)

    def sticking_segments(self, block: int) -> list[np.ndarray]:
        """``(x1, x2)`` polylines of the trajectory samples while ``block`` sticks."""
        traj = self.trajectory
        stuck = traj[f"phase{block}"].to_numpy() == 0
        pts = traj[["x1", "x2"]].to_numpy()
        out, start = [], None
        for j, s in enumerate(np.append(stuck, False)):
            if s and start is None:
                start = j
            elif not s and start is not None:
                if j - start >= 1:
                    out.append(pts[start:j])
                start = None
        return out


def locus_run(problem, integrator: str = "exact-jit", transient: float = 1500.0, duration: float = 200.0,
              samples_per_unit: float = 20.0, options: dict | None = None, value: float | None = None) -> LocusRun:
    """Integrate from rest; sample the trajectory densely over ``[transient, transient + duration]``."""
    from nsbench.engine import simulate

    t_end = transient + duration
    grid = np.linspace(transient, t_end, int(duration * samples_per_unit) + 1)
    res = simulate(problem, integrator, t_end, options=options, t_eval=grid)
    ev = res.events[res.events["t"] >= transient].reset_index(drop=True)
    return LocusRun(problem, value, res.trajectory, ev, transient, t_end, res.integrator["name"])


def region_masks(problem, t: float, x1: np.ndarray, x2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Boolean grids of sliding regions I and II at time ``t`` over the mesh ``(x1, x2)``."""
    return (np.asarray(problem.in_sliding_region(1, t, [x1, x2])),
            np.asarray(problem.in_sliding_region(2, t, [x1, x2])))
