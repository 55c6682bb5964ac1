"""``exact-jit`` and ``henon-rk4-jit``: the compiled fast path as ordinary registered integrators.

Each ``advance`` runs one compiled arc (:mod:`._jit_exact`, or the compiled
``henon-rk4`` kernel :mod:`nsbench.integrators._henon_kernel`)
under the Python engine, so ``nsbench.simulate`` can use them and their event
logs can be checked against ``exact`` and ``henon-rk4``. Bifurcation sweeps call
:meth:`JitIntegrator.run` instead, which runs the whole hybrid loop compiled
(:func:`._jit_hybrid.hybrid_run`). numba is imported only when one of them is
set up; compiled code is cached on disk (``cache=True``).
"""

from __future__ import annotations

import numpy as np

from nsbench.bifurcation.flowtable import empty_table, flow_table
from nsbench.integrators.base import ArcRequest, ArcResult, Integrator, SectionHit
from nsbench.integrators.exact import ExactIntegrator
from nsbench.integrators.henon_rk4 import HenonRK4
from nsbench.results import Status

def _section_arrays(sections, n):
    sc = np.array([s.coeffs for s in sections], dtype=float).reshape(len(sections), n)
    sl = np.array([s.level for s in sections], dtype=float)
    sd = np.array([s.direction for s in sections], dtype=np.int64)
    return sc, sl, sd


class JitIntegrator(Integrator):
    """Shared machinery of the compiled integrators (not registered itself)."""

    method: int = -1

    def _tables(self, problem):
        raise NotImplementedError

    def _opts(self) -> np.ndarray:
        raise NotImplementedError

    def setup(self, problem) -> None:
        super().setup(problem)
        from nsbench.problems import kernels

        self._problem = problem
        self._p = kernels.pack(problem)
        self._ft = self._tables(problem)
        # Compile (or load from the disk cache) now, so that compilation is
        # setup time and never part of a timed run.
        y0 = problem.initial_state()
        mode = problem.initial_mode(0.0, y0)
        self.advance(ArcRequest(problem, mode, 0.0, y0, 1e-3, problem.guards(mode)))

    def _ensure(self, problem) -> None:
        if getattr(self, "_problem", None) is not problem:
            self.setup(problem)

    def advance(self, request: ArcRequest) -> ArcResult:
        from nsbench.bifurcation._jit_hybrid import _arc

        problem = request.problem
        self._ensure(problem)
        n = problem.n_states
        mode = np.array(request.mode, dtype=np.int64)
        sc, sl, sd = _section_arrays(request.sections, n)
        t_eval = np.ascontiguousarray(request.t_eval, dtype=float)
        cap = 64
        while True:
            cnt = np.zeros(4, np.int64)
            y_eval = np.empty((t_eval.size, n))
            hit_t, hit_y, hit_k = np.empty(cap), np.empty((cap, n)), np.empty(cap, np.int64)
            y_out = np.empty(n)
            t, fired, i_eval, nh = _arc(self.method, self._p, self._ft, self._opts(), mode, request.t0,
                                        np.array(request.y0, dtype=float), request.t_end,
                                        request.max_steps, sc, sl, sd, t_eval, 0, y_eval,
                                        hit_t, hit_y, hit_k, cap, -np.inf, y_out, cnt)
            if fired != -2 and nh < cap:
                break
            cap *= 8  # more section crossings than the buffer holds: redo with a larger one
        status, message = Status.SUCCESS, ""
        if fired == -3:
            status, message = Status.BUDGET_EXHAUSTED, f"step budget exhausted at t = {t:.6g}"
        elif fired == -4:
            status, message = Status.INTEGRATOR_FAILURE, f"non-finite state after t = {t:.6g}"
        # ``fired`` indexes the guards in the order of problem.guards (tested equal)
        hits = sorted((SectionHit(int(hit_k[j]), float(hit_t[j]), hit_y[j].copy()) for j in range(nh)),
                      key=lambda h: h.t)
        return ArcResult(
            t=float(t), y=y_out, fired=int(fired) if fired >= 0 else None, y_eval=y_eval[:i_eval].T,
            section_hits=hits, nfev=int(cnt[0]), njev=0, nsteps=int(cnt[1]),
            extra=self._extra(cnt), status=status, message=message,
        )

    def _extra(self, cnt) -> dict[str, float]:
        return {}

    def run(self, problem, *, t_end: float, section: str = "peaks", t_rec: float = 0.0, n_rec: int = 0,
            times: np.ndarray | None = None, t0: float = 0.0, y0=None, mode=None,
            max_steps: int = 50_000_000, max_events: int = 5_000_000, zeno_events: int = 64,
            zeno_span: float = 1e-9):
        """Run the compiled hybrid loop; return a :class:`FastRun`.

        ``section`` is ``'peaks'`` (``v1 = 0`` downward), ``'strobe'`` (states at
        ``times``), ``'stick'`` or ``'mapping'`` (events after their transition).
        """
        from nsbench.bifurcation._jit_hybrid import (
            N_COUNTERS, SEC_SLIP, SEC_STATE, SEC_STICK, SEC_TIME, hybrid_run,
        )

        self._ensure(problem)
        n = problem.n_states
        kind = {"peaks": SEC_STATE, "strobe": SEC_TIME, "stick": SEC_STICK, "mapping": SEC_SLIP}[section]
        sc = np.zeros((1, n))
        sc[0, 1] = 1.0
        sl = np.zeros(1)
        sd = np.array([-1], dtype=np.int64)
        t_eval = np.ascontiguousarray(times if times is not None else np.empty(0), dtype=float)
        if kind == SEC_TIME:
            n_rec = t_eval.size
        m = np.zeros(problem.n_blocks, np.int64) if mode is None else np.array(mode, dtype=np.int64)
        y = problem.initial_state() if y0 is None else np.array(y0, dtype=float)
        rec_t, rec_y = np.full(n_rec, np.nan), np.full((n_rec, n), np.nan)
        rec_kind, rec_block = np.zeros(n_rec, np.int64), np.zeros(n_rec, np.int64)
        cnt = np.zeros(N_COUNTERS, np.int64)
        status, t, y_fin, nr = hybrid_run(
            self.method, self._p, self._ft, self._opts(), float(t0), y, m, mode is not None, float(t_end),
            kind, sc, sl, sd, t_eval, float(t_rec), int(n_rec), rec_t, rec_y, rec_kind, rec_block,
            int(max_steps), int(max_events), int(zeno_events), float(zeno_span), cnt)
        return FastRun(int(status), float(t), np.array(y_fin), m, int(nr), rec_t[:nr], rec_y[:nr],
                       rec_kind[:nr], rec_block[:nr], cnt)


class FastRun:
    """Outcome of :meth:`JitIntegrator.run`: status code, end point, records and counters."""

    STATUS = ("success", "step budget exhausted", "event storm (Zeno)", "integrator failure")
    COUNTERS = ("nfev", "nsteps", "roots", "bisections", "n_events", "sticks1", "sticks2",
                "slips1", "slips2", "reverses1", "reverses2")

    def __init__(self, status, t, y, mode, n, rec_t, rec_y, rec_kind, rec_block, cnt):
        self.status = self.STATUS[status]
        self.t, self.y, self.mode, self.n = t, y, mode, n
        self.rec_t, self.rec_y, self.rec_kind, self.rec_block = rec_t, rec_y, rec_kind, rec_block
        self.counters = dict(zip(self.COUNTERS, (int(c) for c in cnt)))


class ExactJit(JitIntegrator):
    """``exact`` compiled: closed-form flow of each linear mode, bracketing scan and Brent roots."""

    name = "exact-jit"
    method = 0
    capabilities = ExactIntegrator.capabilities
    options = ExactIntegrator.options

    def _tables(self, problem):
        return flow_table(problem)

    def _opts(self) -> np.ndarray:
        return np.array([self.settings["scan"], self.settings["max_scan"]])

    def _extra(self, cnt) -> dict[str, float]:
        return {"roots": int(cnt[2])}


class HenonRK4Jit(JitIntegrator):
    """``henon-rk4`` with the whole hybrid loop compiled (sweeps); its arcs are ``henon-rk4``'s kernel."""

    name = "henon-rk4-jit"
    method = 1
    capabilities = HenonRK4.capabilities
    options = HenonRK4.options
    accuracy_levels = HenonRK4.accuracy_levels

    def _tables(self, problem):
        return empty_table(len(problem.modes))

    def _opts(self) -> np.ndarray:
        return np.array([self.settings["h"]])

    def _extra(self, cnt) -> dict[str, float]:
        return {"henon_steps": int(cnt[2]), "bisections": int(cnt[3])}
