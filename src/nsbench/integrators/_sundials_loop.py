"""Pieces of the SUNDIALS stepping loop: data for the compiled callbacks, trajectory output, root bookkeeping."""

from __future__ import annotations

import math

import numpy as np

from nsbench.integrators.base import ArcRequest

ROOT_RETURN, TSTOP_RETURN = 2, 1  # SUNDIALS return flags (CV_/IDA_ROOT_RETURN, *_TSTOP_RETURN)


class CallbackData:
    """The mutable data a solver's compiled callbacks read: mode, guards, sections (set per arc)."""

    def __init__(self, n_guards: int, n_sections: int, n_states: int) -> None:
        self.mode = np.zeros(0, dtype=np.int64)
        self.kinds = np.zeros(n_guards, dtype=np.int64)
        self.blocks = np.zeros(n_guards, dtype=np.int64)
        self.signs = np.zeros(n_guards, dtype=np.int64)
        self.sec_coeffs = np.zeros((n_sections, n_states))
        self.sec_levels = np.zeros(n_sections)

    def load(self, request: ArcRequest) -> None:
        self.mode = np.ascontiguousarray(request.mode, dtype=np.int64)
        for q, g in enumerate(request.guards):
            self.kinds[q], self.blocks[q], self.signs[q] = g.code, g.block - 1, g.expected_sign
        for j, sec in enumerate(request.sections):
            self.sec_coeffs[j] = sec.coeffs
            self.sec_levels[j] = sec.level


def forget_roots(eventsfn) -> None:
    """Empty the root lists scikit-sundae keeps on the events function.

    It appends every root to them and rebuilds arrays from them at each call
    (``step`` and ``solve`` alike), which would grow costly over a long run:
    the index, time and state of each root, and for IDA its derivative too
    (``_yp``, once left to grow: scikit-sundae's ``step`` then took 37 us per
    IDA step on 2-DOF case 1 over [0, 3000], 20 us with it emptied).
    """
    for name in ("_i", "_t", "_y", "_yp"):
        store = getattr(eventsfn, name, None)
        if store is not None:
            store.clear()


class InterpolatedOutput:
    """Trajectory points from the solver's own interpolant over its last step.

    Read right after a plain step return (``tn``), and between two readings
    the solver is sent back to ``tn``: SUNDIALS checks for roots between the
    last returned time and a requested one, and read backwards from ``tn``
    a crossing filtered out by its direction would be reported as a root.
    """

    def __init__(self, solver, t_eval: np.ndarray, n: int) -> None:
        self.solver, self.t_eval, self.n = solver, t_eval, n
        self.rows: list[np.ndarray] = []
        self.done = 0
        self.fallbacks = 0
        # the last step end (t, y), for the rare fallback; y as the solver returned it (a fresh
        # array per return, never written to), sliced only when used
        self.last: tuple[float, np.ndarray] | None = None
        # the first time not recorded yet, as a Python float: most steps hold none, and this
        # comparison is all they cost (numpy's searchsorted call was a few us per step)
        self._next = float(t_eval[0]) if t_eval.size else math.inf

    def pending(self, t: float) -> bool:
        return t >= self._next

    def step_end(self, t: float, y: np.ndarray) -> None:
        """A plain step return at ``t`` with the solver's state ``y``: record the requested times it passed."""
        if t < self._next:  # most steps: no requested time, nothing to do but remember the step end
            self.last = (t, y)
            return
        self.upto(t, t, (t, y))

    def upto(self, t: float, tn: float, known: tuple[float, np.ndarray]) -> None:
        """Record every requested time ``<= t``; the solver's last step ends at ``tn``.

        ``known`` is a solution point at or after ``t`` (the step end, or the
        root that ends the arc), used only by the fallback.
        """
        if t < self._next:  # no requested time in this step
            self.last = (known[0], np.asarray(known[1]))
            return
        stop = int(np.searchsorted(self.t_eval, t, side="right"))
        for te in self.t_eval[self.done : stop]:
            got = self.solver.step(float(te), method="normal")
            if got.status < 0 or got.status == ROOT_RETURN:  # te left the last step's window
                self.fallbacks += 1
                self.rows.append(self._linear(float(te), *known))
            else:
                self.rows.append(np.asarray(got.y)[: self.n].copy())
            if te < tn:
                self.solver.step(tn, method="normal")
        self.done = max(self.done, stop)
        self._next = float(self.t_eval[self.done]) if self.done < self.t_eval.size else math.inf
        self.last = (known[0], np.asarray(known[1]))

    def _linear(self, te: float, tb: float, yb: np.ndarray) -> np.ndarray:
        yb = np.asarray(yb)[: self.n]
        if self.last is None or tb == self.last[0]:
            return yb.copy()
        ta, ya = self.last[0], self.last[1][: self.n]
        w = (te - ta) / (tb - ta)
        return (1.0 - w) * ya + w * yb

    def states(self) -> np.ndarray:
        return np.array(self.rows).T.reshape(self.n, -1) if self.rows else np.empty((self.n, 0))
