"""The locus of sticking phase: the path of a pair of block positions while a block sticks, and the sliding regions.

For the pair of blocks ``(a, b)`` (default ``(1, 2)``): sliding region I is
``|Ra| <= fra`` with every velocity at the belt speed, region II ``|Rb| <= frb``
(it moves with time when forced: evaluated at a given phase), region III their
overlap. With more than two blocks the other blocks' positions are those of the
trajectory at that phase (the regions are slices of the n-dimensional ones).
Mapping points are the slip events: where the locus leaves a sliding region.
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
    pair: tuple[int, int] = (1, 2)

    @property
    def mapping_points(self) -> pd.DataFrame:
        ev = self.events
        return ev[ev["kind"] == "slip"].reset_index(drop=True)

    def sticking_segments(self, block: int) -> list[np.ndarray]:
        """Polylines of the pair's positions ``(xa, xb)`` over the trajectory samples while ``block`` sticks."""
        traj = self.trajectory
        stuck = traj[f"phase{block}"].to_numpy() == 0
        pts = traj[[f"x{self.pair[0]}", f"x{self.pair[1]}"]].to_numpy()
        out, start = [], None
        for j, s in enumerate(np.append(stuck, False)):
            if s and start is None:
                start = j
            elif not s and start is not None:
                if j - start >= 1:
                    out.append(pts[start:j])
                start = None
        return out


def locus_run(
    problem,
    integrator: str | None = None,
    transient: float = 1500.0,
    duration: float = 200.0,
    samples_per_unit: float = 20.0,
    options: dict | None = None,
    value: float | None = None,
    pair: tuple[int, int] = (1, 2),
) -> LocusRun:
    """Integrate from rest; sample the trajectory densely over ``[transient, transient + duration]``.

    ``integrator`` defaults to ``exact`` for linear problems and ``henon-rk4``
    otherwise; ``pair`` is the two blocks (1-based) whose positions the locus shows.
    """
    from nsbench.engine import simulate
    from nsbench.errors import ConfigError

    a, b = (int(k) for k in pair)
    if problem.n_blocks >= 2 and (a == b or not (1 <= a <= problem.n_blocks and 1 <= b <= problem.n_blocks)):
        raise ConfigError(f"pair = {tuple(pair)!r} must be two different blocks among 1..{problem.n_blocks}")
    if integrator is None:
        integrator = "exact" if problem.is_linear else "henon-rk4"
    t_end = transient + duration
    grid = np.linspace(transient, t_end, int(duration * samples_per_unit) + 1)
    res = simulate(problem, integrator, t_end, options=options, t_eval=grid)
    ev = res.events[res.events["t"] >= transient].reset_index(drop=True)
    return LocusRun(problem, value, res.trajectory, ev, transient, t_end, res.integrator["name"], (a, b))


def region_masks(
    problem,
    t: float,
    xa: np.ndarray,
    xb: np.ndarray,
    pair: tuple[int, int] = (1, 2),
    others: dict[int, float] | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Boolean grids of the sliding regions of the pair's blocks at time ``t`` over the mesh ``(xa, xb)``.

    ``others`` gives the positions of the remaining blocks (needed with more than two).
    """
    a, b = pair
    x = []
    for k in range(1, problem.n_blocks + 1):
        if k == a:
            x.append(xa)
        elif k == b:
            x.append(xb)
        else:
            x.append(np.full_like(xa, (others or {})[k], dtype=float))
    return (np.asarray(problem.in_sliding_region(a, t, x)), np.asarray(problem.in_sliding_region(b, t, x)))
