"""The Python side of the hybrid core: run a problem with an integrator through the compiled loop.

:func:`run_hybrid` is what :func:`nsbench.simulate` (and through it the bench,
sweeps, Lyapunov exponents, periodic orbits and the conformance kit) calls. It
prepares the run's bundles (:mod:`nsbench.model.abi`), calls
:func:`nsbench.model.loop.hybrid_loop` and does what the loop hands back: grows
buffers, builds a kernel's data for a newly visited mode, or, for an integrator
without a compiled kernel, runs its ``advance`` for one arc (:class:`_PythonArcs`),
checking the result against the protocol. It imports no problem and no
integrator: both come in as objects.
"""

from __future__ import annotations

import bisect
import contextlib
import dataclasses
import math
import time
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Sequence

import numpy as np

from nsbench.model import abi, callback
from nsbench.model.callback import ARC_STORED, ARC_STORED_REENTER
from nsbench.model.records import HITS_AT_START, Records
from nsbench.results import Counters
from nsbench.status import Status

if TYPE_CHECKING:  # pragma: no cover
    from nsbench.integrators.base import Integrator
    from nsbench.problems.base import HybridProblem
    from nsbench.sections import StateSection

_PY_FAILURE = abi.K_FAIL + 100  # an arc computed in Python failed (its message is kept in Python)

#: The status of each outcome code of the compiled loop.
RUN_STATUS = {
    abi.RUN_SUCCESS: Status.SUCCESS,
    abi.RUN_STEP_BUDGET: Status.BUDGET_EXHAUSTED,
    abi.RUN_EVENT_BUDGET: Status.BUDGET_EXHAUSTED,
    abi.RUN_STORM: Status.EVENT_STORM,
    abi.RUN_NONFINITE: Status.INTEGRATOR_FAILURE,
    abi.RUN_FAILURE: Status.INTEGRATOR_FAILURE,
    abi.RUN_MISSED: Status.EVENT_MISSED,
}


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
    prepare_time: float = 0.0  # seconds building data of newly visited modes (first use, not the run)
    loop: str = "per-arc"  # who ran the event loop (nsbench.integrators.base.LOOP_PATHS)
    loop_note: str = ""  # why an integrator with a loop of its own ran per arc ('' if it did not)
    internal: Any = None  # a whole-system method's own states by step (a DataFrame), SimulationResult.internal
    #: a whole-system method's own time of each event (``SystemResult.switch_times``), NaN where it located
    #: none; ``None``: it locates none (the event log then has no ``t_located`` column)
    located_t: np.ndarray | None = None
    #: the SIMD lanes of the batch the run went through (:func:`run_hybrid_batch`); 0: it ran alone
    batch: int = 0


_NO_KERNEL: dict[str, Any] = {}


def _no_kernel() -> tuple[np.ndarray, abi.KernelData, np.ndarray]:
    """The kernel arguments of a run whose arcs run in Python."""
    if not _NO_KERNEL:
        _NO_KERNEL["k"] = (np.zeros(0, np.int64), abi.kernel_data(), np.zeros(1))
    return _NO_KERNEL["k"]


#: The most section hits a run's buffer is sized for ahead of the run (beyond that it grows as needed).
MAX_HITS_AHEAD = 1 << 16


def run_hybrid(
    problem: "HybridProblem",
    integ: "Integrator",
    t_end: float,
    *,
    t0: float = 0.0,
    t0_lo: float = 0.0,
    y0: np.ndarray | None = None,
    mode: Sequence[int] | None = None,
    sections: Sequence["StateSection"] = (),
    t_eval: np.ndarray | None = None,
    hit_from: float = -math.inf,
    hit_stop: int = -1,
    record_from: float = -math.inf,
    stop_kind: str | None = None,
    stop_count: int = 0,
    max_steps: int = 5_000_000,
    max_events: int = 1_000_000,
    zeno_events: int = 64,
    zeno_span: float = 1e-9,
    accumulation: float = 1e-14,
) -> RawRun:
    """Run ``problem`` with the (set-up) integrator ``integ`` from ``t0`` to ``t_end`` through every event.

    Parameters
    ----------
    t0, t0_lo, y0, mode
        Start time (compensated: ``t0 + t0_lo``), state (default: the problem's start
        state) and mode (default: the mode of the state, then the start rule).
    sections, t_eval
        Linear state sections to record, and sorted times for states.
    hit_from, hit_stop
        Section hits at ``t >= hit_from`` are kept; the run stops at the ``hit_stop``-th.
    record_from, stop_kind, stop_count
        Events at ``t >= record_from`` are kept; the run stops after ``stop_count`` of
        kind ``stop_kind`` (one of ``problem.event_kinds``) among them.
    max_steps, max_events, zeno_events, zeno_span
        Budgets; more than ``zeno_events`` consecutive events within ``zeno_span`` are a storm.
    accumulation
        Tolerance of an extrapolated accumulation (Zeno) time, relative to ``max(1, |t|)``
        (:func:`nsbench.model.rules.accumulation_time` says when the rule extrapolates and
        applies the problem's limit behaviour; 0: never).
    """
    from nsbench.integrators.base import require_event_driven
    from nsbench.model import loop

    require_event_driven(integ)
    p = _prepare(
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
    )
    kernel, y, mode_arr, grid, sec, rec, st, lim = p.kernel, p.y, p.mode, p.grid, p.sec, p.rec, p.st, p.lim
    prob, start_mode = problem.data, p.start_mode
    if kernel is not None:
        table, kd, fo = kernel.table, kernel.data_for(len(sections)), kernel.options
    else:
        table, kd, fo = _no_kernel()
    prepare_time = 0.0
    path, note = choose_loop(problem, integ, kernel)
    if path == "native":
        return _native_raw(p, _run_native(problem, integ, sections, lim, sec, rec, st))
    py = _PythonArcs(
        problem, integ, sections, grid, float(t_end), int(max_steps), float(hit_from), int(hit_stop), rec, st
    )
    with callback.running(py) if kernel is None else contextlib.nullcontext():
        while True:
            code = loop.hybrid_loop(table, kd, fo, prob, lim, sec, rec.hits, rec.dense, rec.events, st)
            if code == loop.R_DONE:
                break
            if code == loop.R_GROW_EVENTS:
                rec.grow_events(int(st.si[abi.SI_RECORDED]))
            elif code == loop.R_GROW_HITS:
                rec.grow_hits(int(st.si[abi.SI_NHITS]))
            elif code == loop.R_NEED_MODE:
                tic = time.perf_counter()
                kd = kernel.prepare_mode(mode_arr.copy())
                prepare_time += time.perf_counter() - tic
            # R_RESUME: an arc run in Python grew a buffer; the loop resumes with the new one
    if kernel is None:
        py.counters_into(st.cnt)
    status, message = _outcome(problem, st, py.message, kernel, max_steps, max_events, zeno_events, rec)
    cnt, si = st.cnt, st.si
    counters = Counters(
        nfev=int(cnt[abi.NFEV]), njev=int(cnt[abi.NJEV]), nsteps=int(cnt[abi.NSTEPS]), n_events=int(si[abi.SI_EVENTS])
    )
    if kernel is not None:
        for k, name in enumerate(kernel.counters):
            counters.extra[name] = int(cnt[abi.X0 + k])
        from nsbench.model.clock import AVAILABLE

        integ_time = si[abi.SI_CLOCK] * 1e-9 if AVAILABLE else math.nan
    else:
        counters.extra.update(py.extra)
        integ_time = py.seconds
    return _raw(status, message, st, y, mode_arr, rec, counters, integ_time, t0, start_mode, prepare_time, path, note)


@dataclass
class _Prepared:
    """A run's bundles before its loop, and what its outcome is read with."""

    problem: Any
    kernel: Any
    y: np.ndarray
    mode: np.ndarray
    grid: np.ndarray
    sec: abi.Sections
    rec: Records
    st: abi.RunState
    lim: abi.RunLimits
    start_mode: tuple[int, ...]
    t0: float
    budgets: tuple[int, int, int]  # max_steps, max_events, zeno_events


def _prepare(
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
) -> _Prepared:
    """The bundles of a run of :func:`run_hybrid` (its arguments, in its order), before any loop."""

    n = problem.n_states
    kernel = integ.kernel(problem)
    y = problem.initial_state() if y0 is None else np.array(y0, dtype=float)
    y = np.ascontiguousarray(y, dtype=float)
    mode_arr = np.zeros(problem.mode_size, np.int64)
    if mode is None:
        problem.law.initial_mode(problem.data.p, float(t0), y, mode_arr)
    else:
        mode_arr[:] = np.asarray(mode, dtype=np.int64)
    grid = np.ascontiguousarray(np.empty(0) if t_eval is None else t_eval, dtype=float)
    sec = section_bundle(sections, n, hit_from, hit_stop)
    # a run that stops at its hit_stop-th hit never holds more: sized for them, the loop is not left
    # to grow the buffer (a sweep value's 100 peaks overran the 64 rows it starts with: one re-entry per value)
    rec = Records(n, problem.mode_size, grid, hits=min(max(int(hit_stop), HITS_AT_START), MAX_HITS_AHEAD))
    st = _run_state(problem, y, mode_arr, zeno_events)
    st.sf[abi.SF_T], st.sf[abi.SF_TLO] = float(t0), float(t0_lo)
    if stop_kind is not None and stop_kind not in problem.event_kinds:
        from nsbench.errors import ConfigError

        raise ConfigError(
            f"stop_kind {stop_kind!r}: {problem.name} has no such events; its event kinds: "
            f"{', '.join(problem.event_kinds)}"
        )
    kind_code = -1 if stop_kind is None else problem.event_kinds.index(stop_kind)
    lim = abi.RunLimits(
        float(t_end),
        int(max_steps),
        int(max_events),
        float(zeno_span),
        float(record_from),
        int(kind_code),
        int(stop_count),
        float(accumulation),
    )
    start_mode = tuple(int(v) for v in mode_arr)
    budgets = (int(max_steps), int(max_events), int(zeno_events))
    return _Prepared(problem, kernel, y, mode_arr, grid, sec, rec, st, lim, start_mode, float(t0), budgets)


def _run_state(problem, y: np.ndarray, mode_arr: np.ndarray, zeno_events: int) -> abi.RunState:
    """A fresh :class:`~nsbench.model.abi.RunState` of a run from ``y`` in ``mode_arr``."""
    from nsbench.model.rules import STREAK_TIMES

    n, g = problem.n_states, max(problem.max_guards, 1)
    return abi.RunState(
        y=y,
        mode=mode_arr,
        fresh=np.zeros(max(problem.n_elements, 1), np.bool_),
        gk=np.zeros(g, np.int64),
        gi=np.zeros(g, np.int64),
        gs=np.zeros(g, np.int64),
        ring=np.full(max(int(zeno_events), 1), -np.inf),
        acc=np.zeros(STREAK_TIMES),
        sf=np.zeros(abi.N_SF),
        si=np.zeros(abi.N_SI, np.int64),
        cnt=np.zeros(abi.N_COUNTERS, np.int64),
        y_arc=np.empty(n),
        dy=np.empty(n),
        iw=np.zeros(abi.N_COUNTERS + 2, np.int64),
    )


def _native_raw(p: _Prepared, report) -> RawRun:
    """The :class:`RawRun` of a native run (the integrator's own loop) from its report."""
    st, rec = p.st, p.rec
    status, message = _outcome(p.problem, st, report.message, None, *p.budgets, rec)
    cnt, si = st.cnt, st.si
    counters = Counters(
        nfev=int(cnt[abi.NFEV]),
        njev=int(cnt[abi.NJEV]),
        nsteps=int(cnt[abi.NSTEPS]),
        n_events=int(si[abi.SI_EVENTS]),
        extra=dict(report.extra),
    )
    args = (status, message, st, p.y, p.mode, rec, counters, report.integrator_time, p.t0, p.start_mode)
    return _raw(*args, report.prepare_time, "native")


#: The arguments of :func:`run_hybrid` after ``t_end``, in the order :func:`_prepare` takes them.
_RUN_ARGS = (
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
)


def batch_refusal(problems: Sequence["HybridProblem"], integ: "Integrator", runs: Sequence[dict]) -> str:
    """Why the runs ``run_hybrid(problems[i], integ, **runs[i])`` do not go through ``integ``'s batch mode
    together (:func:`run_hybrid_batch`); ``''`` if they do: the integrator has one, each run takes its
    native path (:func:`choose_loop`), the runs share their sections' structure, and the integrator
    accepts the problems together (its ``batch_refusal``)."""
    refuse = getattr(integ, "batch_refusal", None)
    if refuse is None or not callable(getattr(integ, "run_batch", None)):
        return f"{integ.name} has no batch mode"
    if len(problems) != len(runs) or not problems:
        return "one set of run arguments per problem is needed"
    for problem in problems:
        if integ.kernel(problem) is not None:
            return f"{integ.name} runs {problem.name} with a compiled arc kernel"
        path, note = choose_loop(problem, integ)
        if path != "native":
            return note or f"{integ.name} runs {problem.name} per arc"
    shapes = {tuple((len(s.coeffs), int(s.direction)) for s in r.get("sections", ())) for r in runs}
    if len(shapes) > 1:
        return "the runs' sections differ in number or direction"
    return str(refuse(problems, tuple(runs[0].get("sections", ()))))


def run_hybrid_batch(problems: Sequence["HybridProblem"], integ: "Integrator", runs: Sequence[dict]) -> list[RawRun]:
    """``[run_hybrid(p, integ, **r) for p, r in zip(problems, runs)]``, the runs that get past their start
    made together in ``integ``'s batch mode (``integ.run_batch``, groups of ``integ.batch_size()``), where
    :func:`batch_refusal` accepts them; one by one otherwise. ``runs[i]`` holds ``t_end`` and the keyword
    arguments of :func:`run_hybrid`. A batch's exception ends each of its runs as an integrator failure."""
    if batch_refusal(problems, integ, runs):
        return [run_hybrid(p, integ, **r) for p, r in zip(problems, runs)]
    from nsbench.integrators.base import RunReport, RunRequest
    from nsbench.model import native

    defaults = dict(run_hybrid.__kwdefaults__ or {})
    prepared = [
        _prepare(p, integ, r["t_end"], *[r.get(a, defaults[a]) for a in _RUN_ARGS]) for p, r in zip(problems, runs)
    ]
    reports: list[Any] = [RunReport(integrator_time=0.0) for _ in prepared]
    live = []
    for k, p in enumerate(prepared):
        while True:
            code = native.begin(p.problem.data, p.lim, p.rec.dense, p.rec.events, p.st)
            if code != native.NEED_EVENTS:
                break
            p.rec.grow_events(int(p.st.si[abi.SI_RECORDED]))
        if code == native.GO_ON:  # else the start alone ended the run
            live.append(k)
    size = max(1, int(getattr(integ, "batch_size")()))
    batched: set[int] = set()
    for g in range(0, len(live), size):
        group = live[g : g + size]
        sections = [tuple(runs[k].get("sections", ())) for k in group]
        requests = [
            RunRequest(
                prepared[k].problem, sections[j], prepared[k].lim, prepared[k].sec, prepared[k].rec, prepared[k].st
            )
            for j, k in enumerate(group)
        ]
        try:
            got = getattr(integ, "run_batch")(requests)
        except Exception as exc:  # noqa: BLE001 - the runs' outcome, never lost runs
            for k in group:
                prepared[k].st.si[abi.SI_STATUS], prepared[k].st.si[abi.SI_DETAIL] = abi.RUN_FAILURE, _PY_FAILURE
                reports[k] = RunReport(message=f"{type(exc).__name__}: {exc}")
            continue
        for k, report in zip(group, got):
            reports[k] = report
            batched.add(k)
    out = []
    for k, (p, report) in enumerate(zip(prepared, reports)):
        raw = _native_raw(p, report)
        raw.batch = size if k in batched else 0
        out.append(raw)
    return out


def _raw(
    status, message, st, y, mode_arr, rec, counters, integ_time, t0, start_mode, prepare_time, loop, note=""
) -> RawRun:
    """The :class:`RawRun` of a run whose outcome is in ``st`` and the records."""
    si = st.si
    return RawRun(
        status=status,
        message=message,
        t=float(st.sf[abi.SF_T]),
        t_lo=float(st.sf[abi.SF_TLO]),
        y=y.copy(),
        mode=tuple(int(v) for v in mode_arr),
        records=rec,
        n_events=int(si[abi.SI_RECORDED]),
        n_hits=int(si[abi.SI_NHITS]),
        n_dense=int(si[abi.SI_IEVAL]),
        n_events_total=int(si[abi.SI_EVENTS]),
        counters=counters,
        integrator_time=float(integ_time),
        stopped=bool(si[abi.SI_STOPPED]),
        t0=float(t0),
        start_mode=start_mode,
        prepare_time=prepare_time,
        loop=loop,
        loop_note=note,
    )


def choose_loop(problem: "HybridProblem", integ: "Integrator", kernel: Any = None) -> tuple[str, str]:
    """Who runs the event loop of ``problem`` with the set-up ``integ``: ``(path, note)``.

    ``path`` is one of :data:`~nsbench.integrators.base.LOOP_PATHS`: ``'kernel'`` for an integrator with
    a compiled arc kernel (``kernel``: :meth:`Integrator.kernel`'s), ``'native'`` where the integrator
    runs the loop itself (whole-run protocol) and its ``loop`` option allows, else ``'per-arc'``;
    ``note`` says why an integrator with a loop of its own runs per arc (its refusal, or the option).

    Raises
    ------
    ConfigError
        ``loop = 'native'`` for a configuration that cannot run ``problem`` natively.
    """
    if kernel is not None:
        return "kernel", ""
    if "loop" not in getattr(integ, "options", {}):
        return "per-arc", ""
    setting = integ.settings.get("loop", "auto")
    if setting == "per-arc":
        return "per-arc", "loop = 'per-arc'"
    forced = setting == "native"
    try:
        refusal = integ.native_refusal(problem, forced=forced)
    except Exception as exc:  # noqa: BLE001 - a binding that does not load: one line, and the per-arc path
        first = (str(exc).strip().splitlines() or [""])[0]
        refusal = f"its own event loop is unavailable ({type(exc).__name__}: {first})"
    if not refusal:
        return "native", ""
    if forced:
        from nsbench.errors import ConfigError

        raise ConfigError(f"{integ.name}: loop = 'native' cannot run {problem.name}: {refusal}")
    return "per-arc", refusal


def _run_native(problem, integ, sections, lim, sec, rec: Records, st):
    """Settle the start as the compiled loop does, then hand the run to the integrator's own loop.

    An exception from the integrator (a protocol violation, a bug) ends the run as an integrator
    failure with its message, as an arc's does on the per-arc path.
    """
    from nsbench.integrators.base import RunReport, RunRequest
    from nsbench.model import native

    while True:
        code = native.begin(problem.data, lim, rec.dense, rec.events, st)
        if code != native.NEED_EVENTS:
            break
        rec.grow_events(int(st.si[abi.SI_RECORDED]))
    if code != native.GO_ON:  # the start alone ended the run (t_end reached, a storm at the start, ...)
        return RunReport(integrator_time=0.0)
    request = RunRequest(problem, tuple(sections), lim, sec, rec, st)
    try:
        report = integ.run(request)
    except Exception as exc:  # noqa: BLE001 - the run's outcome, never a lost run
        st.si[abi.SI_STATUS], st.si[abi.SI_DETAIL] = abi.RUN_FAILURE, _PY_FAILURE
        return RunReport(message=f"{type(exc).__name__}: {exc}")
    if not isinstance(report, RunReport):
        st.si[abi.SI_STATUS], st.si[abi.SI_DETAIL] = abi.RUN_FAILURE, _PY_FAILURE
        return RunReport(message=f"{integ.name}.run returned {type(report).__name__}, not a RunReport")
    return report


def section_bundle(sections, n: int, hit_from: float = -math.inf, hit_stop: int = -1) -> abi.Sections:
    """The sections of a run as the compiled code reads them."""
    from nsbench.model.kernel import section_bundle as bundle

    return bundle(sections, n, hit_from, hit_stop)


def _storm_detail(problem, rec: Records, si, span: float, zeno_events: int) -> str:
    """Which guards chattered in a storm, and whether time passed between the events.

    Events that all happen at one instant are a cycle of the settle rules at a
    degenerate point (a guard on its surface with a rate zero to rounding): a
    numerical storm, never physics. Events spread over a positive span may be a
    genuine accumulation (Zeno behaviour of the model) and are worth comparing
    with the reference.
    """
    k = int(si[abi.SI_RECORDED])
    m = min(k, zeno_events + 1)
    if m == 0:
        return ""
    counts: dict[tuple[int, int], int] = {}
    for b, kind in zip(rec.events.index[k - m : k], rec.events.kind[k - m : k]):
        counts[(int(b) + 1, int(kind))] = counts.get((int(b) + 1, int(kind)), 0) + 1
    top = sorted(counts.items(), key=lambda item: -item[1])[:4]
    chatter = ", ".join(f"{n} {problem.event_kinds[kind]} of block {b}" for (b, kind), n in top)
    where = (
        "all at one instant: a numerical storm (the rules cycle at a degenerate point)"
        if span == 0.0
        else "spread over time: an accumulation of events, possibly genuine (compare with the reference)"
    )
    return f"; chattering: {chatter}; {where}"


def _outcome(problem, st, py_message, kernel, max_steps, max_events, zeno_events, rec: Records) -> tuple[Status, str]:
    si, sf = st.si, st.sf
    run_status, detail = int(si[abi.SI_STATUS]), int(si[abi.SI_DETAIL])
    t = float(sf[abi.SF_T])
    status = RUN_STATUS[run_status]
    mode = problem.mode_name(tuple(int(v) for v in st.mode))
    if run_status == abi.RUN_SUCCESS:
        return status, ""
    if run_status == abi.RUN_STEP_BUDGET:
        return status, py_message or f"{max_steps} steps used by t = {t:.6g}"
    if run_status == abi.RUN_EVENT_BUDGET:
        return status, f"event budget of {max_events} events reached at t = {t:.17g}"
    if run_status == abi.RUN_STORM:
        span = t - float(np.min(st.ring))
        return status, (
            f"{zeno_events + 1} events within {span:.3g} time units ending at t = {t:.17g} "
            f"(mode {mode})" + _storm_detail(problem, rec, si, span, zeno_events)
        )
    if run_status == abi.RUN_MISSED:
        return status, (
            f"a guard of mode {mode} was on its wrong side at t = {t:.17g} and back on its own side "
            "later in the same arc: the integrator stepped over a crossing (tighten its tolerance "
            "or step)"
        )
    if run_status == abi.RUN_NONFINITE:
        return status, py_message or f"non-finite state after t = {t:.6g}"
    if detail == _PY_FAILURE or kernel is None or kernel.failure is None:
        return status, py_message or f"integrator failure (code {detail}) at t = {t:.6g}"
    return status, kernel.failure(detail, t)


def low_part(t: float, t_lo: float) -> float:
    """An integrator's low-order time part, or 0 if it is not a valid correction of ``t`` (at most an ulp)."""
    t_lo = float(t_lo)
    return t_lo if math.isfinite(t_lo) and abs(t_lo) <= math.ulp(t) else 0.0


class _PythonArcs:
    """Runs one arc of an integrator without a compiled kernel and stores its outcome for the loop.

    The compiled loop calls it back (:mod:`nsbench.model.callback`) once per arc. What
    it costs beyond the integrator's ``advance`` is nsbench's share of such a run
    (docs/core.md), so the common arc takes a short path: the request's fields are set
    directly, the counters are kept as Python integers, and the result, checked with a
    few scalar comparisons, is written into the run's arrays (the loop checks that the
    state is finite); its section hits are stored as they come. Any other result (a
    failure, a shape or a time outside the protocol) goes through :meth:`_checked`,
    which names what is wrong.
    """

    def __init__(self, problem, integ, sections, t_eval, t_end, max_steps, hit_from, hit_stop, rec, st) -> None:
        from nsbench.integrators.base import ArcRequest

        from nsbench.model import loop

        self._request = ArcRequest  # imported once per run, not once per arc
        self._new = object.__new__
        self._arc_done = loop.P_ARC_DONE
        self._no_states = np.empty((problem.n_states, 0))
        self.problem, self.integ, self.rec, self.st = problem, integ, rec, st
        self._advance = integ.advance
        self._n = problem.n_states
        self._shape = (problem.n_states,)
        self.sections = tuple(sections)
        self.t_eval, self.t_end, self.max_steps = t_eval, t_end, max_steps
        self._times = t_eval.tolist()  # searched with bisect per arc: a tenth of numpy's searchsorted call
        self.hit_from, self.hit_stop = hit_from, hit_stop
        self.seconds = 0.0
        self.nfev = self.njev = self.nsteps = 0
        self.extra: dict[str, float] = {}
        self.message = ""
        self._by_mode: dict[bytes, tuple[tuple[int, ...], tuple]] = {}  # per mode: its tuple and its guards
        self._ok = Status.SUCCESS
        # the fields of every request of the run; the others are set per arc (_make_request)
        self._fixed = {"problem": problem, "t_end": t_end, "sections": self.sections, "sections_from": hit_from}
        names = {f.name for f in dataclasses.fields(ArcRequest)}
        known = names == set(self._fixed) | {"mode", "t0", "y0", "guards", "t_eval", "max_steps", "t0_lo"}
        self._build = self._make_request if known else self._construct  # a field this glue does not know

    def _fail(self, si, code: int, message: str) -> int:
        self.message = message
        return self._done(si, code)

    def _done(self, si, code: int) -> int:
        si[abi.SI_ARC_STATUS] = code
        si[abi.SI_PHASE] = self._arc_done
        return ARC_STORED

    def _make_request(self, mode, t, y_in, guards, t_eval, max_steps, t_lo):
        """An :class:`ArcRequest`, its fields set directly (a frozen dataclass's ``__init__`` sets
        each through ``object.__setattr__``: a few us per arc; this sets the same fields)."""
        request = self._new(self._request)
        fields = request.__dict__
        fields.update(self._fixed)
        fields["mode"], fields["t0"], fields["y0"], fields["guards"] = mode, t, y_in, guards
        fields["t_eval"], fields["max_steps"], fields["t0_lo"] = t_eval, max_steps, t_lo
        return request

    def _construct(self, mode, t, y_in, guards, t_eval, max_steps, t_lo):
        return self._request(
            problem=self.problem,
            mode=mode,
            t0=t,
            y0=y_in,
            t_end=self.t_end,
            guards=guards,
            sections=self.sections,
            sections_from=self.hit_from,
            t_eval=t_eval,
            max_steps=max_steps,
            t0_lo=t_lo,
        )

    def _mode(self, key: bytes) -> tuple[tuple[int, ...], tuple]:
        mode = tuple(self.st.mode.tolist())
        entry = self._by_mode[key] = (mode, self.problem.guards(mode))
        return entry

    def counters_into(self, cnt: np.ndarray) -> None:
        """Add the run's evaluation counters to the loop's (steps are kept there arc by arc)."""
        cnt[abi.NFEV] += self.nfev
        cnt[abi.NJEV] += self.njev

    def __call__(self) -> int:
        """Run the current arc (called from the compiled loop); :data:`ARC_STORED` or, when a record
        buffer was replaced, :data:`ARC_STORED_REENTER`."""
        st = self.st
        key = st.mode.tobytes()
        entry = self._by_mode.get(key)
        mode, guards = self._mode(key) if entry is None else entry
        sf, si = st.sf, st.si
        times = sf.tolist()
        t, t_lo = times[abi.SF_T], times[abi.SF_TLO]
        i_eval = int(si[abi.SI_IEVAL])
        t_eval = self.t_eval[i_eval:] if i_eval else self.t_eval
        y_in = np.frombuffer(st.y.tobytes())  # a read-only copy
        request = self._build(mode, t, y_in, guards, t_eval, self.max_steps - self.nsteps, t_lo)
        tic = time.perf_counter()
        try:
            res = self._advance(request)
        except Exception as exc:  # a protocol violation by the integrator: keep what we have
            self.seconds += time.perf_counter() - tic
            sf[abi.SF_ARC_T] = t
            st.y_arc[:] = st.y
            return self._fail(si, _PY_FAILURE, f"{type(exc).__name__}: {exc}")
        self.seconds += time.perf_counter() - tic
        try:
            self.nfev += res.nfev
            self.njev += res.njev
            self.nsteps = steps = self.nsteps + res.nsteps
            st.cnt[abi.NSTEPS] = steps
        except (TypeError, ValueError, OverflowError):
            return self._fail(
                si,
                _PY_FAILURE,
                f"{self.integ.name} returned counters that are not integers: {res.nfev!r}, {res.njev!r}, {res.nsteps!r}",
            )
        if res.extra:
            extra = self.extra
            for name, value in res.extra.items():
                extra[name] = extra.get(name, 0) + value
        # The common arc: it ended at an event or at t_end, with its dense states and nothing else.
        t1, y1, y_eval, fired = res.t, res.y, res.y_eval, res.fired
        if (
            res.status is self._ok
            and type(y1) is np.ndarray
            and y1.shape == self._shape
            and type(y_eval) is np.ndarray
            and t <= t1 <= self.t_end
            and (t1 == self.t_end if fired is None else 0 <= fired < len(guards))
        ):
            # searchsorted(t_eval, t1, "right"), t1 being a finite number here
            expected = bisect.bisect_right(self._times, t1, i_eval) - i_eval
            if expected:
                if y_eval.shape != (self._n, expected):
                    return self._checked(res, t, t_eval, i_eval, guards)
                self.rec.dense.y[i_eval : i_eval + expected] = y_eval.T
                si[abi.SI_IEVAL] = i_eval + expected
            elif y_eval.size:
                return self._checked(res, t, t_eval, i_eval, guards)
            sf[abi.SF_ARC_T] = t1
            sf[abi.SF_ARC_TLO] = low_part(t1, res.t_lo) if res.t_lo else 0.0
            st.y_arc[:] = y1
            si[abi.SI_ARC_STATUS] = abi.K_OK
            si[abi.SI_DETAIL] = -1 if fired is None else fired
            if not res.section_hits:
                return ARC_STORED
            stop_hit, reenter = self._hits(res.section_hits)
            code = ARC_STORED if stop_hit is None else self._hit_stop(stop_hit, t_eval, i_eval)
            if reenter:  # the loop returns and resumes with the grown buffer
                si[abi.SI_PHASE] = self._arc_done
                return ARC_STORED_REENTER
            return code
        return self._checked(res, t, t_eval, i_eval, guards)

    def _hits(self, hits) -> tuple[Any, bool]:
        """Store the section hits at ``t >= hit_from``; the hit that ends the run (or None), and whether
        the buffer was grown (the loop must then be entered again to see it)."""
        rec, si, reenter = self.rec, self.st.si, False
        for hit in hits:
            if hit.t < self.hit_from:
                continue
            j = int(si[abi.SI_NHITS])
            if j >= rec.hits.t.shape[0]:
                rec.grow_hits(j)
                reenter = True
            rec.hits.index[j], rec.hits.t[j], rec.hits.y[j] = hit.index, float(hit.t), np.asarray(hit.y, dtype=float)
            si[abi.SI_NHITS] = j + 1
            if 0 <= self.hit_stop <= j + 1:
                return hit, reenter
        return None, reenter

    def _hit_stop(self, hit, t_eval: np.ndarray, i_eval: int) -> int:
        """The arc ends at the section hit that ends the run."""
        st = self.st
        st.sf[abi.SF_ARC_T], st.sf[abi.SF_ARC_TLO] = float(hit.t), 0.0
        st.y_arc[:] = np.asarray(hit.y, dtype=float)
        st.si[abi.SI_IEVAL] = i_eval + int(np.searchsorted(t_eval, float(hit.t), side="right"))
        return self._done(st.si, abi.K_HIT_STOP)

    def _checked(self, res, t: float, t_eval: np.ndarray, i_eval: int, guards: tuple) -> int:
        """Store an arc's result after checking it field by field against the protocol."""
        st, rec, integ, n = self.st, self.rec, self.integ, self._n
        y, sf, si, y_arc = st.y, st.sf, st.si, st.y_arc
        t1 = float(res.t)
        y1 = res.y
        if not (type(y1) is np.ndarray and y1.dtype == np.float64 and y1.ndim == 1):
            y1 = np.asarray(y1, dtype=float).reshape(-1)
        sf[abi.SF_ARC_T], sf[abi.SF_ARC_TLO] = t1, 0.0
        shaped = y1.shape[0] == n
        y_arc[:] = y1 if shaped else y
        if res.status.ok and (t1 < t or t1 > self.t_end):  # before the dense states, which it would miscount
            return self._fail(
                si, _PY_FAILURE, (f"{integ.name} stopped at t = {t1!r} outside the arc [{t!r}, {self.t_end!r}]")
            )
        expected = int(np.searchsorted(t_eval, t1, side="right")) if t_eval.size else 0
        y_eval = res.y_eval
        if expected or not (type(y_eval) is np.ndarray and y_eval.size == 0):
            y_eval = np.asarray(y_eval, dtype=float)
            if y_eval.size == 0:
                y_eval = self._no_states
            if y_eval.ndim != 2 or y_eval.shape[0] != n:
                return self._fail(
                    si,
                    _PY_FAILURE,
                    (
                        f"{integ.name} returned y_eval of shape {y_eval.shape}; the protocol wants "
                        f"(n_states, n_points) = ({n}, {expected})"
                    ),
                )
            if res.status.ok and y_eval.shape[1] != expected:
                return self._fail(
                    si,
                    _PY_FAILURE,
                    (f"{integ.name} returned {y_eval.shape[1]} dense states for {expected} requested times"),
                )
            k = min(y_eval.shape[1], expected)
            if k:
                rec.dense.y[i_eval : i_eval + k] = y_eval[:, :k].T
                si[abi.SI_IEVAL] = i_eval + k
        stop_hit, reenter = self._hits(res.section_hits)
        code = self._store(res, t, t1, y1, shaped, t_eval, i_eval, guards, stop_hit)
        return ARC_STORED_REENTER if reenter else code

    def _store(self, res, t, t1, y1, shaped, t_eval, i_eval, guards, stop_hit) -> int:
        st, integ = self.st, self.integ
        sf, si = st.sf, st.si
        status = res.status
        if status is not self._ok and not status.ok:
            if status is Status.BUDGET_EXHAUSTED:
                self.message = res.message
                return self._done(si, abi.K_BUDGET)
            return self._fail(si, _PY_FAILURE, res.message or status.value)
        if stop_hit is not None:
            return self._hit_stop(stop_hit, t_eval, i_eval)
        if not shaped:
            return self._fail(
                si, _PY_FAILURE, f"{integ.name} returned y of shape {y1.shape}; the protocol wants ({self._n},)"
            )
        if not (math.isfinite(t1) and all(map(math.isfinite, y1.tolist()))):
            self.message = f"non-finite state at t = {t1}"
            return self._done(si, abi.K_NONFINITE)
        if t1 < t or t1 > self.t_end:
            return self._fail(
                si, _PY_FAILURE, (f"{integ.name} stopped at t = {t1!r} outside the arc [{t!r}, {self.t_end!r}]")
            )
        fired = res.fired
        if fired is None:
            if t1 < self.t_end:
                return self._fail(si, _PY_FAILURE, f"{integ.name} stopped at t = {t1!r} < t_end without an event")
        elif not 0 <= int(fired) < len(guards):
            return self._fail(si, _PY_FAILURE, f"{integ.name} reported guard {fired!r} of {len(guards)}")
        sf[abi.SF_ARC_TLO] = low_part(t1, res.t_lo)
        si[abi.SI_DETAIL] = -1 if fired is None else int(fired)
        return self._done(si, abi.K_OK)


_WARM: set[str] = set()


def warm_up(problem: "HybridProblem", integ: "Integrator") -> None:
    """Load (or compile, on a machine's first use) the compiled loop with this kernel, untimed: a run that
    ends where it starts goes through the loop without an arc."""
    kernel = integ.kernel(problem)
    key = f"{problem.law.source}:{'python' if kernel is None else kernel.name}"
    if key in _WARM:
        return
    run_hybrid(problem, integ, 0.0)
    _WARM.add(key)
