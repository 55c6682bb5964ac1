"""The Python side of the hybrid core: run a problem with an integrator through the compiled loop.

:func:`run_hybrid` is what :func:`nsbench.simulate`, the bench runner, sweeps,
the Lyapunov estimate and the conformance kit call. It prepares the state
arrays, calls :func:`nsbench.hybrid.loop.hybrid_loop` and does what the loop
hands back: grows buffers, builds the tables of a newly visited mode, or, for an
integrator without a compiled kernel, runs its ``advance`` for one arc
(:func:`_python_arc`), checking the result against the protocol.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Callable, Sequence

import numpy as np

from nsbench.hybrid import abi
from nsbench.hybrid.records import Records, mode_text
from nsbench.results import Counters, Status

if TYPE_CHECKING:  # pragma: no cover
    from nsbench.integrators.base import Integrator
    from nsbench.problems.oscillator import FrictionOscillator
    from nsbench.sections import StateSection

#: ``integrator_time`` of a kernel when the platform has no readable monotonic clock.
_PY_FAILURE = abi.K_FAIL + 100  # an arc computed in Python failed (its message is kept in Python)
_BUDGET_PY = abi.K_FAIL + 101   # an arc computed in Python ran out of budget (its message is kept)


@dataclass
class ArcKernel:
    """A compiled arc kernel an integrator provides (see :meth:`Integrator.kernel`).

    Attributes
    ----------
    method
        Kernel code of :mod:`nsbench.hybrid.loop` (``M_EXACT``, ``M_HENON``, ``M_PICARD``).
    data
        The kernel's data (tables, operators), in the loop's ``kd`` slot of its method.
    options
        Float options the kernel reads (``fo``).
    counters
        Names of the method-specific counter slots, in order.
    prepare_mode
        Called with a mode (int array) the kernel has no tables for; returns the new ``data``.
    prepare_run
        Called with the number of sections before a run or an arc; returns the ``data`` to use.
    failure
        ``failure(code, t)``: the message of a method-specific failure code.
    """

    method: int
    data: tuple
    options: np.ndarray
    counters: tuple[str, ...] = ()
    prepare_mode: Callable[[np.ndarray], tuple] | None = None
    prepare_run: Callable[[int], tuple] | None = None
    failure: Callable[[int, float], str] | None = None

    def data_for(self, n_sections: int) -> tuple:
        return self.prepare_run(n_sections) if self.prepare_run is not None else self.data


@dataclass
class RawRun:
    """What one run through the core produced, as arrays (:func:`nsbench.simulate` makes frames of it)."""

    status: Status
    message: str
    t: float
    t_lo: float
    y: np.ndarray
    mode: tuple[int, ...]
    records: Records
    n_events: int
    n_hits: int
    n_dense: int
    n_events_total: int
    counters: Counters
    integrator_time: float
    stopped: bool
    t0: float
    start_mode: tuple[int, ...]
    prepare_time: float = 0.0  # seconds building tables of newly visited modes (first use, not the run)


_DUMMY: dict[str, Any] = {}


def _dummy_data() -> tuple[tuple, tuple, tuple]:
    """Data of the right types for the kernel slots a run does not use (one compiled loop for all)."""
    if not _DUMMY:
        from nsbench.integrators._exact_layout import empty_tables

        z = np.zeros
        _DUMMY["kd"] = (empty_tables(1, 1), (z((2, 2)),), (z(2), z(2), z((2, 2)), z((2, 2)), z((6, 2, 2)),
                                                             z((2, 2, 2)), z((8, 2))))
    return _DUMMY["kd"]


def _kd(method: int, data: tuple) -> tuple:
    from nsbench.hybrid import loop

    kd = list(_dummy_data())
    slot = {loop.M_EXACT: 0, loop.M_HENON: 1, loop.M_PICARD: 2}.get(method)
    if slot is not None:
        kd[slot] = data
    return tuple(kd)


def section_arrays(sections: Sequence["StateSection"], n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Coefficient rows, levels and directions of linear state sections."""
    sc = np.array([s.coeffs for s in sections], dtype=float).reshape(len(sections), n)
    sl = np.array([s.level for s in sections], dtype=float)
    sd = np.array([s.direction for s in sections], dtype=np.int64)
    return sc, sl, sd


def kernel_of(integ: "Integrator", problem: "FrictionOscillator") -> ArcKernel | None:
    return integ.kernel(problem)


def run_hybrid(problem: "FrictionOscillator", integ: "Integrator", t_end: float, *, t0: float = 0.0,
               t0_lo: float = 0.0, y0: np.ndarray | None = None, mode: Sequence[int] | None = None,
               sections: Sequence["StateSection"] = (), t_eval: np.ndarray | None = None,
               hit_from: float = -math.inf, hit_stop: int = -1, record_from: float = -math.inf,
               stop_kind: str | None = None, stop_count: int = 0, max_steps: int = 5_000_000,
               max_events: int = 1_000_000, zeno_events: int = 64, zeno_span: float = 1e-9) -> RawRun:
    """Run ``problem`` with the (set-up) integrator ``integ`` from ``t0`` to ``t_end`` through every event.

    Parameters
    ----------
    t0, t0_lo, y0, mode
        Start time (compensated: ``t0 + t0_lo``), state (default: rest at the
        origin) and mode (default: the mode of the state, then the start rule).
    sections, t_eval
        Linear state sections to record, and sorted times for states.
    hit_from, hit_stop
        Section hits at ``t >= hit_from`` are kept; the run stops at the ``hit_stop``-th.
    record_from, stop_kind, stop_count
        Events at ``t >= record_from`` are kept; the run stops after ``stop_count`` of
        kind ``stop_kind`` (``'stick'``, ``'slip'``, ``'reverse'``) among them.
    max_steps, max_events, zeno_events, zeno_span
        Budgets; more than ``zeno_events`` consecutive events within ``zeno_span`` are a storm.
    """
    from nsbench.hybrid import loop, rules
    from nsbench.problems.modes import EVENT_KINDS

    n, nb = problem.n_states, problem.n_blocks
    p = problem.packed
    kernel = integ.kernel(problem)
    method = kernel.method if kernel is not None else loop.M_PYTHON
    kd = _kd(method, kernel.data_for(len(sections)) if kernel is not None else ())
    fo = kernel.options if kernel is not None else np.zeros(1)
    y = problem.initial_state() if y0 is None else np.array(y0, dtype=float)
    mode_arr = np.zeros(nb, np.int64)
    if mode is None:
        rules.initial_mode(p, float(t0), y, mode_arr)
    else:
        mode_arr[:] = np.asarray(mode, dtype=np.int64)
    grid = np.ascontiguousarray(np.empty(0) if t_eval is None else t_eval, dtype=float)
    sc, sl, sd = section_arrays(sections, n)
    rec = Records(n, nb, grid.size)
    fresh = np.zeros(nb, np.bool_)
    gk, gb, gs = (np.empty(2 * nb, np.int64) for _ in range(3))
    ring = np.full(max(int(zeno_events), 1), -np.inf)
    sf = np.zeros(loop.N_SF)
    sf[loop.SF_T], sf[loop.SF_TLO] = float(t0), float(t0_lo)
    si = np.zeros(abi.N_SI, np.int64)
    cnt = np.zeros(abi.N_COUNTERS, np.int64)
    y_arc = np.empty(n)
    dy = np.empty(n)
    iw = np.zeros(abi.N_COUNTERS + 2, np.int64)
    kind_code = -1 if stop_kind is None else EVENT_KINDS.index(stop_kind)
    start_mode = tuple(int(v) for v in mode_arr)
    prepare_time = 0.0
    py = _PythonArcs(problem, integ, sections, grid, float(t_end), int(max_steps), float(hit_from),
                     int(hit_stop))
    while True:
        code = loop.hybrid_loop(method, kd, fo, p, float(t_end), int(max_steps), int(max_events),
                                float(zeno_span), sc, sl, sd, float(hit_from), int(hit_stop), rec.hk, rec.ht,
                                rec.hy, grid, rec.y_eval, float(record_from), kind_code, int(stop_count),
                                rec.ev_t, rec.ev_kind, rec.ev_block, rec.ev_y, rec.ev_mode, y, mode_arr, fresh,
                                gk, gb, gs, ring, sf, si, cnt, y_arc, dy, iw)
        if code == loop.R_DONE:
            break
        if code == loop.R_GROW_EVENTS:
            rec.grow_events(int(si[rules.SI_RECORDED]))
        elif code == loop.R_GROW_HITS:
            rec.grow_hits(int(si[abi.SI_NHITS]))
        elif code == loop.R_NEED_MODE:
            tic = time.perf_counter()
            kd = _kd(method, kernel.prepare_mode(mode_arr.copy()))
            prepare_time += time.perf_counter() - tic
        else:  # R_NEED_ARC
            py.arc(rec, y, mode_arr, gk, gb, gs, sf, si, cnt, y_arc)
    status, message = _outcome(int(si[abi.SI_STATUS]), int(si[abi.SI_DETAIL]), sf, ring, si, py, kernel,
                               mode_arr, max_steps, max_events, zeno_events, rec)
    counters = Counters(nfev=int(cnt[abi.NFEV]), njev=int(cnt[abi.NJEV]), nsteps=int(cnt[abi.NSTEPS]),
                        n_events=int(si[rules.SI_EVENTS]))
    if kernel is not None:
        for k, name in enumerate(kernel.counters):
            counters.extra[name] = int(cnt[abi.X0 + k])
        from nsbench.hybrid.clock import AVAILABLE

        integ_time = si[abi.SI_CLOCK] * 1e-9 if AVAILABLE else math.nan
    else:
        counters.extra.update(py.extra)
        integ_time = py.seconds
    return RawRun(status=status, message=message, t=float(sf[loop.SF_T]), t_lo=float(sf[loop.SF_TLO]),
                  y=y.copy(), mode=tuple(int(v) for v in mode_arr), records=rec,
                  n_events=int(si[rules.SI_RECORDED]), n_hits=int(si[abi.SI_NHITS]),
                  n_dense=int(si[abi.SI_IEVAL]), n_events_total=int(si[rules.SI_EVENTS]),
                  counters=counters, integrator_time=float(integ_time), stopped=bool(si[abi.SI_STOPPED]),
                  t0=float(t0), start_mode=start_mode, prepare_time=prepare_time)


def _storm_detail(rec, si, span: float, zeno_events: int) -> str:
    """Which guards chattered in a storm, and whether time passed between the events.

    Events that all happen at one instant are a cycle of the settle rules at a
    degenerate point (a guard on its surface with a rate zero to rounding): a
    numerical storm, never physics. Events spread over a positive span may be a
    genuine accumulation (Zeno behaviour of the model) and are worth comparing
    with the reference.
    """
    from nsbench.hybrid import rules
    from nsbench.problems.modes import EVENT_KINDS

    if rec is None:
        return ""
    k = int(si[rules.SI_RECORDED])
    m = min(k, zeno_events + 1)
    if m == 0:
        return ""
    counts: dict[tuple[int, int], int] = {}
    for b, kind in zip(rec.ev_block[k - m:k], rec.ev_kind[k - m:k]):
        counts[(int(b), int(kind))] = counts.get((int(b), int(kind)), 0) + 1
    top = sorted(counts.items(), key=lambda item: -item[1])[:4]
    chatter = ", ".join(f"{n} {EVENT_KINDS[kind]} of block {b}" for (b, kind), n in top)
    where = ("all at one instant: a numerical storm (the rules cycle at a degenerate point)" if span == 0.0
             else "spread over time: an accumulation of events, possibly genuine (compare with the reference)")
    return f"; chattering: {chatter}; {where}"


def _outcome(run_status, detail, sf, ring, si, py, kernel, mode_arr, max_steps, max_events,
             zeno_events, rec=None) -> tuple[Status, str]:
    from nsbench.hybrid import loop

    t = float(sf[loop.SF_T])
    if run_status == loop.RUN_SUCCESS:
        return Status.SUCCESS, ""
    if run_status == loop.RUN_STEP_BUDGET:
        return Status.BUDGET_EXHAUSTED, py.message or f"{max_steps} steps used by t = {t:.6g}"
    if run_status == loop.RUN_EVENT_BUDGET:
        return Status.BUDGET_EXHAUSTED, f"event budget of {max_events} events reached at t = {t:.17g}"
    if run_status == loop.RUN_STORM:
        span = t - float(np.min(ring))
        return Status.EVENT_STORM, (f"{zeno_events + 1} events within {span:.3g} time units ending at "
                                    f"t = {t:.17g} (mode {mode_text(mode_arr)})" + _storm_detail(rec, si, span,
                                                                                               zeno_events))
    if run_status == loop.RUN_NONFINITE:
        return Status.INTEGRATOR_FAILURE, py.message or f"non-finite state after t = {t:.6g}"
    if detail == _PY_FAILURE or kernel is None or kernel.failure is None:
        return Status.INTEGRATOR_FAILURE, py.message or f"integrator failure (code {detail}) at t = {t:.6g}"
    return Status.INTEGRATOR_FAILURE, kernel.failure(detail, t)


def low_part(t: float, t_lo: float) -> float:
    """An integrator's low-order time part, or 0 if it is not a valid correction of ``t`` (at most an ulp)."""
    t_lo = float(t_lo)
    return t_lo if math.isfinite(t_lo) and abs(t_lo) <= math.ulp(t) else 0.0


class _PythonArcs:
    """Runs one arc of an integrator without a compiled kernel and stores its outcome for the loop."""

    def __init__(self, problem, integ, sections, t_eval, t_end, max_steps, hit_from, hit_stop) -> None:
        self.problem, self.integ = problem, integ
        self.sections = tuple(sections)
        self.t_eval, self.t_end, self.max_steps = t_eval, t_end, max_steps
        self.hit_from, self.hit_stop = hit_from, hit_stop
        self.seconds = 0.0
        self.extra: dict[str, float] = {}
        self.message = ""

    def _fail(self, si, code: int, message: str) -> None:
        from nsbench.hybrid import loop

        self.message = message
        si[abi.SI_ARC_STATUS] = code
        si[abi.SI_PHASE] = loop.P_ARC_DONE

    def arc(self, rec: Records, y, mode_arr, gk, gb, gs, sf, si, cnt, y_arc) -> None:
        from nsbench.hybrid import loop
        from nsbench.integrators.base import ArcRequest

        problem, integ = self.problem, self.integ
        n = problem.n_states
        mode = tuple(int(v) for v in mode_arr)
        guards = problem.guards(mode)
        t, t_lo = float(sf[loop.SF_T]), float(sf[loop.SF_TLO])
        y_in = y.copy()
        y_in.flags.writeable = False
        i_eval = int(si[abi.SI_IEVAL])
        request = ArcRequest(problem=problem, mode=mode, t0=t, y0=y_in, t_end=self.t_end, guards=guards,
                             sections=self.sections, t_eval=self.t_eval[i_eval:],
                             max_steps=self.max_steps - int(cnt[abi.NSTEPS]), t0_lo=t_lo)
        tic = time.perf_counter()
        try:
            res = integ.advance(request)
        except Exception as exc:  # a protocol violation by the integrator: keep what we have
            self.seconds += time.perf_counter() - tic
            sf[loop.SF_ARC_T] = t
            y_arc[:] = y
            return self._fail(si, _PY_FAILURE, f"{type(exc).__name__}: {exc}")
        self.seconds += time.perf_counter() - tic
        cnt[abi.NFEV] += int(res.nfev)
        cnt[abi.NJEV] += int(res.njev)
        cnt[abi.NSTEPS] += int(res.nsteps)
        for key, value in (res.extra or {}).items():
            self.extra[key] = self.extra.get(key, 0) + value
        t1 = float(res.t)
        y1 = np.asarray(res.y, dtype=float).reshape(-1)
        sf[loop.SF_ARC_T], sf[loop.SF_ARC_TLO] = t1, 0.0
        y_arc[:] = y1 if y1.shape == (n,) else y
        expected = int(np.searchsorted(request.t_eval, t1, side="right"))
        y_eval = np.asarray(res.y_eval, dtype=float)
        if y_eval.size == 0:
            y_eval = np.empty((n, 0))
        if y_eval.ndim != 2 or y_eval.shape[0] != n:
            return self._fail(si, _PY_FAILURE, (
                f"{integ.name} returned y_eval of shape {y_eval.shape}; the protocol wants "
                f"(n_states, n_points) = ({n}, {expected})"))
        if res.status.ok and y_eval.shape[1] != expected:
            return self._fail(si, _PY_FAILURE, (
                f"{integ.name} returned {y_eval.shape[1]} dense states for {expected} requested times"))
        k = min(y_eval.shape[1], expected)
        rec.y_eval[i_eval:i_eval + k] = y_eval[:, :k].T
        si[abi.SI_IEVAL] = i_eval + k
        stop_hit = None
        for hit in res.section_hits:
            if hit.t < self.hit_from:
                continue
            j = int(si[abi.SI_NHITS])
            if j >= rec.ht.shape[0]:
                rec.grow_hits(j)
            rec.hk[j], rec.ht[j], rec.hy[j] = hit.index, float(hit.t), np.asarray(hit.y, dtype=float)
            si[abi.SI_NHITS] = j + 1
            if 0 <= self.hit_stop <= j + 1:
                stop_hit = hit
                break
        if not res.status.ok:
            if res.status is Status.BUDGET_EXHAUSTED:
                self.message = res.message
                si[abi.SI_ARC_STATUS] = abi.K_BUDGET
                si[abi.SI_PHASE] = loop.P_ARC_DONE
                return None
            return self._fail(si, _PY_FAILURE, res.message or res.status.value)
        if stop_hit is not None:
            sf[loop.SF_ARC_T] = float(stop_hit.t)
            y_arc[:] = np.asarray(stop_hit.y, dtype=float)
            si[abi.SI_IEVAL] = i_eval + int(np.searchsorted(request.t_eval, float(stop_hit.t), side="right"))
            si[abi.SI_ARC_STATUS] = abi.K_HIT_STOP
            si[abi.SI_PHASE] = loop.P_ARC_DONE
            return None
        if not (math.isfinite(t1) and y1.shape == (n,) and np.all(np.isfinite(y1))):
            self.message = f"non-finite state at t = {t1}"
            si[abi.SI_ARC_STATUS] = abi.K_NONFINITE
            si[abi.SI_PHASE] = loop.P_ARC_DONE
            return None
        if t1 < t or t1 > self.t_end:
            return self._fail(si, _PY_FAILURE, (
                f"{integ.name} stopped at t = {t1!r} outside the arc [{t!r}, {self.t_end!r}]"))
        if res.fired is None and t1 < self.t_end:
            return self._fail(si, _PY_FAILURE, f"{integ.name} stopped at t = {t1!r} < t_end without an event")
        if res.fired is not None and not 0 <= int(res.fired) < len(guards):
            return self._fail(si, _PY_FAILURE, f"{integ.name} reported guard {res.fired!r} of {len(guards)}")
        sf[loop.SF_ARC_TLO] = low_part(t1, res.t_lo)
        si[abi.SI_ARC_STATUS] = abi.K_OK
        si[abi.SI_DETAIL] = -1 if res.fired is None else int(res.fired)
        si[abi.SI_PHASE] = loop.P_ARC_DONE
        return None


def kernel_advance(integ: "Integrator", request) -> Any:
    """``Integrator.advance`` of an integrator with a compiled kernel: one arc through :func:`loop.arc`."""
    from nsbench.hybrid import loop, rules
    from nsbench.integrators.base import ArcResult, SectionHit

    problem = request.problem
    kernel = integ.compiled_kernel(problem)
    n, nb = problem.n_states, problem.n_blocks
    mode = np.asarray(request.mode, dtype=np.int64)
    gk, gb, gs = (np.empty(2 * nb, np.int64) for _ in range(3))
    ng = rules.guards_of(mode, gk, gb, gs)
    codes = {"velocity": rules.VELOCITY, "upper": rules.UPPER, "lower": rules.LOWER}
    given = [(codes[g.kind], g.block - 1, g.expected_sign) for g in request.guards]
    if not given:
        ng = 0  # a free arc of the mode: no guard stops it
    elif given != [(int(gk[q]), int(gb[q]), int(gs[q])) for q in range(ng)]:
        from nsbench.errors import ConfigError

        raise ConfigError(f"{integ.name}: a compiled kernel takes all the guards of the mode in the order of "
                          f"problem.guards(mode) (or none), not {list(request.guards)}")
    sc, sl, sd = section_arrays(request.sections, n)
    t_eval = np.ascontiguousarray(request.t_eval, dtype=float)
    rec = Records(n, nb, t_eval.size, events=1, hits=16)
    y0 = np.array(request.y0, dtype=float)
    y_out = np.empty(n)
    kd = _kd(kernel.method, kernel.data_for(len(request.sections)))
    while True:
        si = np.zeros(abi.N_SI, np.int64)
        cnt = np.zeros(abi.N_COUNTERS, np.int64)
        status, t, t_lo, fired = loop.arc(
            kernel.method, kd, kernel.options, problem.packed, mode, gk, gb, gs, ng, float(request.t0),
            float(request.t0_lo), y0, float(request.t_end), int(min(request.max_steps, 2**62)), sc, sl, sd,
            -math.inf, -1, rec.hk, rec.ht, rec.hy, si, t_eval, rec.y_eval, y_out, cnt)
        if status == abi.K_HIT_FULL:
            rec.grow_hits(0)
        elif status == abi.K_NEED_MODE:
            kd = _kd(kernel.method, kernel.prepare_mode(mode.copy()))
        else:
            break
    message, code = "", Status.SUCCESS
    if status == abi.K_BUDGET:
        code, message = Status.BUDGET_EXHAUSTED, f"step budget exhausted at t = {t:.6g}"
    elif status == abi.K_NONFINITE:
        code, message = Status.INTEGRATOR_FAILURE, f"non-finite state after t = {t:.6g}"
    elif status >= abi.K_FAIL:
        code = Status.INTEGRATOR_FAILURE
        message = kernel.failure(int(status), t) if kernel.failure else f"failure code {status}"
    hits = [SectionHit(int(rec.hk[j]), float(rec.ht[j]), rec.hy[j].copy()) for j in range(int(si[abi.SI_NHITS]))]
    extra = {name: int(cnt[abi.X0 + k]) for k, name in enumerate(kernel.counters)}
    return ArcResult(t=float(t), y=y_out.copy(), fired=None if fired < 0 else int(fired),
                     y_eval=rec.y_eval[: int(si[abi.SI_IEVAL])].T.copy(), section_hits=hits,
                     nfev=int(cnt[abi.NFEV]), njev=int(cnt[abi.NJEV]), nsteps=int(cnt[abi.NSTEPS]), extra=extra,
                     status=code, message=message, t_lo=float(t_lo))


_WARM: set[int] = set()


def warm_up(problem: "FrictionOscillator", integ: "Integrator") -> None:
    """Load (or compile, on a machine's first use) the compiled loop and the kernel's arc, untimed.

    A run that ends where it starts goes through the loop without an arc; one
    arc through :meth:`Integrator.advance` loads the kernel dispatcher as well.
    """
    kernel = integ.compiled_kernel(problem) if getattr(integ, "_kernel_problem", None) is problem else None
    key = -1 if kernel is None else kernel.method
    if key in _WARM:
        return
    run_hybrid(problem, integ, 0.0)
    if kernel is not None and integ.kernel(problem) is not None:
        from nsbench.integrators.base import ArcRequest

        mode = problem.initial_mode(0.0, problem.initial_state())
        kernel_advance(integ, ArcRequest(problem, mode, 0.0, problem.initial_state(), 1e-3,
                                         problem.guards(mode)))
    _WARM.add(key)
