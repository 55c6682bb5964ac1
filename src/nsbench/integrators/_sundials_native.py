"""CVODE and IDA running the whole hybrid run natively: the solvers, and the compiled event loop that drives them.

:class:`NativeSolver` owns one SUNDIALS solver (its ``SUNContext``, vectors, dense
matrix, dense linear solver and memory, created through
:mod:`~nsbench.integrators._sundials_capi` with the options of the per-arc adapters
of :mod:`nsbench.integrators.sundials`) whose callbacks are the compiled functions of
:mod:`~nsbench.integrators._sundials_callbacks`. :func:`native_loop` runs the whole
run (the whole-run protocol of :class:`nsbench.integrators.base.Integrator`, rules
11-15): it calls ``CVode``/``IDASolve`` one internal step at a time through their C
addresses, and at each guard's root hands the state to the core's compiled step
:func:`nsbench.model.native.event` (the missed-crossing check on the arc's requested
states, the transition through :func:`nsbench.model.rules.settle`: the same
transitions, storms, accumulations, event budget and stop rule as the core's loop),
reinitialises the solver from the new state and goes on; sections go through
:func:`~nsbench.model.native.hit`, the end through :func:`~nsbench.model.native.arrive`
or :func:`~nsbench.model.native.fail`. So the run fills the run's own bundles
(:class:`~nsbench.model.abi.RunState`, the record buffers) as the core's loop would.

The checks the core makes per arc are also made on the solver's own steps:

- *missed crossings*: after every internal step each guard is evaluated (the
  formulation's root function, what the solver's root finding sees) at the middle
  of the step, read from the solver's interpolant, and, once a guard has been seen
  on its wrong side, at the step's end; a guard seen on its wrong side and later back
  on its own side within the arc is a crossing the solver stepped over
  (:data:`~nsbench.model.abi.RUN_MISSED`, at the time of the first wrong-side sighting);
- the step budget before every step, non-finite states at every step end, steps that
  do not advance (``t + h == t``, :data:`MAX_STALLS` in a row), the end time (the
  solver's stop time).
"""

from __future__ import annotations

import ctypes
import math
import time
from typing import Any, NamedTuple

import numpy as np

from nsbench.integrators import _sundials_callbacks as cb
from nsbench.integrators import _sundials_capi as capi
from nsbench.integrators._sundials_capi import SLOT, c_function
from nsbench.model.abi import (
    K_BUDGET,
    K_FAIL,
    K_HIT_FULL,
    K_HIT_STOP,
    K_NONFINITE,
    K_OK,
    NFEV,
    NJEV,
    NSTEPS,
    RUN_FAILURE,
    RUN_MISSED,
    RUN_NONFINITE,
    RUN_STEP_BUDGET,
    SF_ARC_T,
    SF_T,
    SF_TLO,
    SI_DETAIL,
    SI_IEVAL,
    SI_NG,
    SI_NHITS,
    SI_PHASE,
    SI_RECORDED,
    SI_STATUS,
)
from nsbench.model import native
from nsbench.model.clock import AVAILABLE as CLOCK
from nsbench.model.clock import monotonic_ns
from nsbench.model.compile import hot
from nsbench.model.records import copy_into
from nsbench.problems import friction_law as k

#: Solver kinds (slot ``H_KIND`` of the handles).
CVODE, IDA = 0, 1
#: Slots of the handles (int64): the solver's C objects and sizes.
H_KIND, H_MEM, H_Y, H_YP, H_DKY, H_ID, H_NEQ, H_SLOTS, H_NROOTS = range(9)
N_H = 9
#: Counter slots of the native run (the core's method-specific ones).
COUNTERS = ("root_returns", "midpoint_checks")

#: The arc stepped over a guard's crossing (this loop's own code; the core's kernels have none).
K_MISSED = 6
#: A failure of this loop's own (beyond any SUNDIALS flag, ``K_FAIL - flag``): steps that did not advance.
K_STALLED = K_FAIL + 1000
#: Consecutive steps without progress (shorter than 16 ulps of the step's time: ``t + h == t`` or about) after
#: which the run fails (CVODE's own count of warnings about ``t + h == t`` before it stops warning).
MAX_STALLS = 10
#: Where :func:`native_loop` resumes: the next arc (the core's ``P_TOP``, where ``native.begin`` leaves
#: a run), or the event of the last arc, waiting for room in the event buffers.
P_TOP, P_EVENT = 1, 7
R_DONE, R_GROW_EVENTS, R_GROW_HITS = 0, 1, 2
#: Slots of :attr:`Solver.clock`: nanoseconds inside the arcs, root returns, midpoint checks.
C_NS, C_ROOTS, C_MIDPOINTS = 0, 1, 2
_EPS = np.finfo(np.float64).eps

_cv_solve = c_function("i32(p, f64, p, p, i32)")  # CVode(mem, tout, yout, &tret, itask)
_cv_reinit = c_function("i32(p, f64, p)")  # CVodeReInit(mem, t0, y0)
_ida_solve = c_function("i32(p, f64, p, p, p, i32)")  # IDASolve(mem, tout, &tret, yy, yp, itask)
_ida_reinit = c_function("i32(p, f64, p, p)")  # IDAReInit(mem, t0, yy0, yp0)
_set_stop = c_function("i32(p, f64)")  # *SetStopTime(mem, tstop)
_root_info = c_function("i32(p, p)")  # *GetRootInfo(mem, int *rootsfound)
_get_dky = c_function("i32(p, f64, i32, p)")  # *GetDky(mem, t, k, dky)
_get_long = c_function("i32(p, p)")  # *GetNum...(mem, long *)
_set_id = c_function("i32(p, p)")  # IDASetId(mem, id)
#: Slots of the address table, as constants for compiled code.
_CVode = SLOT["CVode"]
_CVodeGetDky = SLOT["CVodeGetDky"]
_CVodeGetNumJacEvals = SLOT["CVodeGetNumJacEvals"]
_CVodeGetNumRhsEvals = SLOT["CVodeGetNumRhsEvals"]
_CVodeGetRootInfo = SLOT["CVodeGetRootInfo"]
_CVodeReInit = SLOT["CVodeReInit"]
_CVodeSetStopTime = SLOT["CVodeSetStopTime"]
_IDAGetDky = SLOT["IDAGetDky"]
_IDAGetNumJacEvals = SLOT["IDAGetNumJacEvals"]
_IDAGetNumResEvals = SLOT["IDAGetNumResEvals"]
_IDAGetRootInfo = SLOT["IDAGetRootInfo"]
_IDAReInit = SLOT["IDAReInit"]
_IDASetId = SLOT["IDASetId"]
_IDASetStopTime = SLOT["IDASetStopTime"]
_IDASolve = SLOT["IDASolve"]
_N_VGetArrayPointer = SLOT["N_VGetArrayPointer"]


class Solver(NamedTuple):
    """What the compiled loop needs of a :class:`NativeSolver` (arrays only)."""

    calls: np.ndarray  # int64 addresses of capi.CALLS
    h: np.ndarray  # int64 handles H_*
    ud: np.ndarray  # int64 user data of the callbacks (cb.UD_*)
    p: np.ndarray  # float64 parameters the callbacks read (CVODE: F = 0)
    fw: np.ndarray  # float64 [F, w]
    y: np.ndarray  # float64 view of the solver's state vector
    yp: np.ndarray  # float64 view of its derivative (IDA; CVODE: empty)
    dky: np.ndarray  # float64 view of the interpolation vector
    ident: np.ndarray  # float64 view of IDA's differential/algebraic vector (CVODE: empty)
    found: np.ndarray  # int32 root information (H_NROOTS)
    roots: np.ndarray  # float64 root values (H_NROOTS)
    tret: np.ndarray  # float64, 1
    counter: np.ndarray  # int64, 1 (a counter read from the solver)
    wrong: np.ndarray  # float64, slots + 1: each guard's first wrong-side time at a solver point; how many
    clock: np.ndarray  # int64, C_*: the run's time inside the arcs and its method counters


# ---------------------------------------------------------------------- compiled: one arc
@hot
def _consistent(p, mode, t, y, yy, yp, ident):
    """IDA's consistent start at a switch (:func:`nsbench.integrators._sundials_kernels.consistent_start`,
    compiled), and its differential (1) / algebraic (0) components."""
    nb = mode.shape[0]
    n = 2 * nb
    for i in range(n):
        yy[i] = y[i]
    for i in range(nb):
        yy[n + i] = 0.0
    k.rhs(p, mode, t, yy, yp)
    for i in range(nb):
        yp[n + i] = 0.0
    for i in range(nb):
        if mode[i] == 0:
            yy[n + i] = k.restoring(p, t, yy, i)
            yp[n + i] = k.restoring_rate(p, t, yy, yp, i)
        else:
            yy[n + i] = k.slip_force(p, i, mode[i], yy[2 * i + 1])
        ident[2 * i] = 1.0
        ident[2 * i + 1] = 0.0 if mode[i] == 0 else 1.0
        ident[n + i] = 0.0


@hot
def _point_ud(sv, st, sec):
    """Point the callbacks' user data at this run's mode, guards and sections."""
    ud = sv.ud
    ud[cb.UD_MODE] = st.mode.ctypes.data
    ud[cb.UD_GK] = st.gk.ctypes.data
    ud[cb.UD_GI] = st.gi.ctypes.data
    ud[cb.UD_GS] = st.gs.ctypes.data
    ud[cb.UD_NG] = st.si[SI_NG]
    ud[cb.UD_NSEC] = sec.levels.shape[0]
    ud[cb.UD_SEC_C] = sec.coeffs.ctypes.data
    ud[cb.UD_SEC_L] = sec.levels.ctypes.data


@hot
def _start(sv, prob, st, t0, t_end):
    """Reinitialise the solver at ``(t0, st.y)`` in ``st.mode``; SUNDIALS' flag."""
    h, calls = sv.h, sv.calls
    mem = h[H_MEM]
    n = st.y.shape[0]
    if h[H_KIND] == CVODE:
        for i in range(n):
            sv.y[i] = st.y[i]
        if h[H_NEQ] > n:  # the forcing's cos and sin as states
            w = sv.fw[1]
            sv.y[n] = math.cos(w * t0)
            sv.y[n + 1] = math.sin(w * t0)
        flag = _cv_reinit(calls[_CVodeReInit], (mem, t0, h[H_Y]))
        if flag < 0:
            return flag
        return _set_stop(calls[_CVodeSetStopTime], (mem, t_end))
    _consistent(sv.p, st.mode, t0, st.y, sv.y, sv.yp, sv.ident)
    flag = _set_id(calls[_IDASetId], (mem, h[H_ID]))
    if flag < 0:
        return flag
    flag = _ida_reinit(calls[_IDAReInit], (mem, t0, h[H_Y], h[H_YP]))
    if flag < 0:
        return flag
    return _set_stop(calls[_IDASetStopTime], (mem, t_end))


@hot
def _step(sv, t_end):
    """One internal step towards ``t_end`` (or the next root in the step); SUNDIALS' flag, time in ``sv.tret``."""
    h, calls = sv.h, sv.calls
    if h[H_KIND] == CVODE:
        return _cv_solve(calls[_CVode], (h[H_MEM], t_end, h[H_Y], sv.tret.ctypes.data, capi.CV_ONE_STEP))
    return _ida_solve(calls[_IDASolve], (h[H_MEM], t_end, sv.tret.ctypes.data, h[H_Y], h[H_YP], capi.IDA_ONE_STEP))


@hot
def _interpolate(sv, t):
    """The solver's interpolant at ``t`` (inside its last step) into ``sv.dky``; SUNDIALS' flag."""
    h = sv.h
    slot = _CVodeGetDky if h[H_KIND] == CVODE else _IDAGetDky
    return _get_dky(sv.calls[slot], (h[H_MEM], t, 0, h[H_DKY]))


@hot
def _counter(sv, name_cv, name_ida):
    h = sv.h
    sv.counter[0] = 0  # a C long may be narrower than the int64 it is read into
    _get_long(sv.calls[name_cv if h[H_KIND] == CVODE else name_ida], (h[H_MEM], sv.counter.ctypes.data))
    return sv.counter[0]


@hot
def _root_values(sv, y):
    """The formulation's guards at the solver state ``y`` into ``sv.roots`` (their slots; no sections)."""
    if sv.h[H_KIND] == CVODE:
        cb.cvode_root_values(sv.ud, y, sv.roots, False)
    else:
        cb.ida_root_values(sv.ud, y, sv.roots, False)


@hot
def _scale(y):
    ymax = 1.0
    for j in range(y.shape[0]):
        ymax = max(ymax, abs(y[j]))
    return 64.0 * _EPS * ymax


@hot
def _watch_solver(sv, ng, t, y):
    """Feed a solver point to the missed-crossing rule (formulation's guards); the first wrong-side time of a
    guard now back on its own side, or -1."""
    _root_values(sv, y)
    tol = _scale(y)
    wrong = sv.wrong
    for q in range(ng):
        g = sv.roots[q]
        if g < -tol:
            if wrong[q] < 0.0:
                wrong[q] = t
                wrong[wrong.shape[0] - 1] += 1.0  # sightings still open
        elif g > tol and wrong[q] >= 0.0:
            return wrong[q]
    return -1.0


@hot
def _fill_states(sv, dense, st, t_upto, n):
    """The states at the requested times up to ``t_upto`` (inside the last step), from the interpolant."""
    si = st.si
    i = si[SI_IEVAL]
    while i < dense.t.shape[0] and dense.t[i] <= t_upto:
        if _interpolate(sv, dense.t[i]) < 0:  # outside the last step (cannot happen): the step's end state
            for j in range(n):
                sv.dky[j] = sv.y[j]
        row = dense.y[i]
        for j in range(n):
            row[j] = sv.dky[j]
        i += 1
    si[SI_IEVAL] = i


@hot
def _finite(y, n):
    for j in range(n):
        if not np.isfinite(y[j]):
            return False
    return True


@hot
def _watch_step(sv, ng, t_prev, t, end):
    """The missed-crossing rule on the step ``(t_prev, t]``: its middle (the interpolant), and its end ``sv.y``
    if ``end`` and a guard has been seen on its wrong side; a first wrong-side time now resolved, or -1."""
    wrong_at = -1.0
    t_mid = 0.5 * (t_prev + t)
    if t_mid > t_prev and _interpolate(sv, t_mid) >= 0:
        sv.clock[C_MIDPOINTS] += 1
        wrong_at = _watch_solver(sv, ng, t_mid, sv.dky)
    if end and wrong_at < 0.0 and sv.wrong[sv.wrong.shape[0] - 1] > 0.0:
        # the step's end only to see a guard back on its own side: the solver's root finding has
        # compared the guards at both ends of the step, so a guard cannot newly be on its wrong side
        # there without a root (no guard was heading there at the arc's start: the core's settle rule)
        wrong_at = _watch_solver(sv, ng, t, sv.y)
    return wrong_at


@hot
def _arc(sv, prob, sec, hits, dense, st, t_end, budget):
    """One arc from ``(sf[SF_T], st.y)`` in ``st.mode`` to its first guard's root, ``t_end`` or a stop;
    ``(status, t_stop, fired)`` with the codes of an arc kernel (and :data:`K_MISSED`), the state where
    it stopped in ``st.y_arc``. A section's hit that ends the run (``hit_stop``) is applied here
    (:func:`nsbench.model.native.hit`): :data:`K_HIT_STOP`, the run's outcome set."""
    si, cnt = st.si, st.cnt
    n = st.y.shape[0]
    t0 = st.sf[SF_T]
    ng = si[SI_NG]
    slots = sv.h[H_SLOTS]
    n_sec = sec.levels.shape[0]
    _point_ud(sv, st, sec)
    for q in range(slots):
        sv.wrong[q] = -1.0
    sv.wrong[slots] = 0.0
    flag = _start(sv, prob, st, t0, t_end)
    copy_into(st.y_arc, st.y)
    if flag < 0:
        return K_FAIL - flag, t0, -1
    steps, stalls, t_prev, t = 0, 0, t0, t0
    status, fired, t_stop = K_OK, -1, t_end
    while True:
        if steps >= budget:
            status, t_stop = K_BUDGET, t
            break
        flag = _step(sv, t_end)
        if flag < 0:
            for j in range(n):
                st.y_arc[j] = sv.y[j]
            status, t_stop = K_FAIL - flag, sv.tret[0]
            break
        t = sv.tret[0]
        if flag == capi.ROOT_RETURN:
            sv.clock[C_ROOTS] += 1
            slot = _CVodeGetRootInfo if sv.h[H_KIND] == CVODE else _IDAGetRootInfo
            _root_info(sv.calls[slot], (sv.h[H_MEM], sv.found.ctypes.data))
            for q in range(ng):
                if sv.found[q] != 0:
                    fired = q
                    break
            if fired >= 0:  # the part of the step before the root, checked as a step
                wrong_at = _watch_step(sv, ng, t_prev, t, False)
                if wrong_at >= 0.0:
                    status, t_stop, fired = K_MISSED, wrong_at, -1
                    break
            for j in range(n_sec):
                if sv.found[slots + j] != 0:
                    _fill_states(sv, dense, st, t, n)
                    code = native.hit(sec, hits, dense, st, j, t, sv.y[:n])
                    if code == native.NEED_HITS:
                        return K_HIT_FULL, t, -1
                    if code != native.GO_ON:
                        return K_HIT_STOP, t, -1
            if fired < 0:
                continue  # a section's root inside the step: the step goes on
            _fill_states(sv, dense, st, t, n)
            for j in range(n):
                st.y_arc[j] = sv.y[j]
            t_stop = t
            break
        steps += 1
        if not _finite(sv.y, sv.h[H_NEQ]):
            status, t_stop = K_NONFINITE, t
            break
        # a step that underflowed (t + h == t, or within 16 ulps of t): CVODE goes on "anyway", without progress.
        # Measured at the step's own time, not the span's end: IDA at atol = 1e-15 starts with steps of 1e-14
        # near t = 0, which are real progress (ulps of 300 would have called ten of them a stall).
        if t - t_prev <= 16.0 * _EPS * max(abs(t), abs(t_prev)):
            stalls += 1
            if stalls >= MAX_STALLS:
                status, t_stop = K_STALLED, t
                break
            continue
        stalls = 0
        wrong_at = _watch_step(sv, ng, t_prev, t, True)
        if wrong_at >= 0.0:
            status, t_stop = K_MISSED, wrong_at
            break
        _fill_states(sv, dense, st, t, n)
        t_prev = t
        if flag == capi.TSTOP_RETURN or t >= t_end:
            for j in range(n):
                st.y_arc[j] = sv.y[j]
            _fill_states(sv, dense, st, t_end, n)
            t_stop = t_end
            break
    cnt[NSTEPS] += steps
    cnt[NFEV] += _counter(sv, _CVodeGetNumRhsEvals, _IDAGetNumResEvals)
    cnt[NJEV] += _counter(sv, _CVodeGetNumJacEvals, _IDAGetNumJacEvals)
    return status, t_stop, fired


# ---------------------------------------------------------------------- compiled: the run
@hot
def native_loop(sv, prob, lim, sec, hits, dense, ev, st):
    """Run with the solver ``sv`` (:class:`Solver`) from where the core's :func:`nsbench.model.native.begin`
    left the run, through every event, to its outcome (``st.si[SI_STATUS]``).

    Between arcs it calls the core's steps (:mod:`nsbench.model.native`: ``event``, ``arrive``,
    ``fail``), so the transitions, storms, event budget, Zeno rule, stop rule and the core's own
    missed-crossing check on the requested states are the core's. Returns :data:`R_DONE`,
    :data:`R_GROW_EVENTS` or :data:`R_GROW_HITS` (grow that buffer and call again: an event waiting
    for room is applied then; an arc whose hit buffer was full runs again from its start).
    """
    si, sf, cnt = st.si, st.sf, st.cnt
    saved = st.iw[: cnt.shape[0]]
    clock = st.iw[cnt.shape[0] :]
    while True:
        if si[SI_PHASE] != P_EVENT:
            copy_into(saved, cnt)
            n_hits, i_eval = si[SI_NHITS], si[SI_IEVAL]
            tic = monotonic_ns(clock)
            status, t1, fired = _arc(sv, prob, sec, hits, dense, st, lim.t_end, lim.max_steps - cnt[NSTEPS])
            sv.clock[C_NS] += monotonic_ns(clock) - tic
            if status == K_HIT_FULL:
                copy_into(cnt, saved)  # the arc runs again from its start once the buffer is grown
                si[SI_NHITS], si[SI_IEVAL] = n_hits, i_eval
                return R_GROW_HITS
            if status == K_HIT_STOP:
                return R_DONE
            if status == K_MISSED:
                sf[SF_T], sf[SF_TLO] = t1, 0.0
                si[SI_STATUS] = RUN_MISSED
                return R_DONE
            if status == K_NONFINITE:
                native.fail(st, RUN_NONFINITE, t1, st.y_arc, 0)
                return R_DONE
            if status == K_BUDGET:
                native.fail(st, RUN_STEP_BUDGET, t1, st.y_arc, 0)
                return R_DONE
            if status >= K_FAIL:
                native.fail(st, RUN_FAILURE, t1, st.y_arc, status)
                return R_DONE
            if fired < 0:
                native.arrive(prob, dense, st, t1, 0.0, st.y_arc)
                return R_DONE
            sf[SF_ARC_T], si[SI_DETAIL] = t1, fired
            si[SI_PHASE] = P_EVENT
        code = native.event(prob, lim, dense, ev, st, si[SI_DETAIL], sf[SF_ARC_T], 0.0, st.y_arc)
        if code == native.NEED_EVENTS:
            return R_GROW_EVENTS
        si[SI_PHASE] = P_TOP
        if code != native.GO_ON:
            return R_DONE


# ---------------------------------------------------------------------- Python: owning a solver
def _vector_view(binding: capi.Binding, vector: int, size: int) -> np.ndarray:
    get = binding.fn("core", "N_VGetArrayPointer", ctypes.c_void_p, ctypes.c_void_p)
    return np.ctypeslib.as_array((ctypes.c_double * size).from_address(get(vector)))


class NativeSolver:
    """One CVODE or IDA solver for a problem, with the options of the per-arc adapter, owned here.

    Parameters
    ----------
    kind
        :data:`CVODE` or :data:`IDA`.
    problem
        A friction-family problem (``n_states``, ``packed``, ``coefficients``, ``max_guards``).
    method
        CVODE's ``'Adams'`` or ``'BDF'`` (IDA: ignored).
    rtol, atol, max_step
        As the adapters' options (``max_step`` 0: none).
    n_sections, directions
        The sections' count and crossing directions (-1, 0, +1).
    """

    def __init__(
        self,
        kind: int,
        problem: Any,
        method: str,
        rtol: float,
        atol: float,
        max_step: float,
        n_sections: int,
    ) -> None:
        from nsbench.problems.friction_spec import LAYOUT

        b = self.binding = capi.load()
        self.kind = kind
        self.n_sections = int(n_sections)
        n, nb = int(problem.n_states), int(problem.n_blocks)
        p = np.array(problem.packed, dtype=float)
        c = problem.coefficients
        F, w = float(c.F), float(c.w)
        if kind == CVODE:
            p[LAYOUT.offset("F", nb)] = 0.0  # the force enters through the cos state
            neq = n + (2 if F != 0.0 else 0)
        else:
            neq = n + nb
        slots = int(problem.max_guards)
        self.n_roots = n_roots = slots + self.n_sections
        self.own = own = capi.Owned()
        vp, ci, cd = ctypes.c_void_p, ctypes.c_int, ctypes.c_double
        idx = b.index
        lib = "cvode" if kind == CVODE else "ida"
        P = "CVode" if kind == CVODE else "IDA"

        def call(name: str, *args: Any, restype: Any = ci, argtypes: tuple = ()) -> Any:
            f = getattr(b.libs[lib], name)
            f.restype = restype
            if argtypes:
                f.argtypes = list(argtypes)
            return f(*args)

        def check(flag: int, what: str) -> None:
            if flag < 0:
                self.close()
                raise capi.BindingUnavailable(f"{what} failed ({b.flag_name(lib, flag)})")

        core = b.libs["core"]
        core.SUNContext_Create.argtypes = [ci, ctypes.POINTER(vp)]
        core.SUNContext_Free.argtypes = [ctypes.POINTER(vp)]
        core.SUNContext_ClearErrHandlers.argtypes = [vp]
        ctx = vp()
        check(core.SUNContext_Create(0, ctypes.byref(ctx)), "SUNContext_Create")  # 0: SUN_COMM_NULL
        own.add(ctx.value, lambda ptr: core.SUNContext_Free(ctypes.byref(vp(ptr))), "SUNContext")
        # no error handler, no warnings: SUNDIALS would print each failure and warning to stderr; the
        # run's status and message say what failed (its return flag's name, or a stalled step)
        core.SUNContext_ClearErrHandlers(ctx)
        logger = vp()
        core.SUNContext_GetLogger.argtypes = [vp, ctypes.POINTER(vp)]
        core.SUNLogger_SetWarningFilename.argtypes = [vp, ctypes.c_char_p]
        if core.SUNContext_GetLogger(ctx, ctypes.byref(logger)) == 0 and logger.value:
            core.SUNLogger_SetWarningFilename(logger, b"")  # SUNDIALS: an empty name turns the output off
        destroy = b.fn("core", "N_VDestroy", None, vp)

        def vector(what: str) -> int:
            return own.add(call("N_VNew_Serial", idx(neq), ctx, restype=vp, argtypes=(idx, vp)), destroy, what)

        y, yp, dky = vector("state vector"), vector("derivative vector"), vector("interpolation vector")
        ident = vector("id vector") if kind == IDA else 0
        mat_destroy = b.fn("core", "SUNMatDestroy", None, vp)
        ls_free = b.fn("core", "SUNLinSolFree", ci, vp)
        A = own.add(
            call("SUNDenseMatrix", idx(neq), idx(neq), ctx, restype=vp, argtypes=(idx, idx, vp)),
            mat_destroy,
            "dense matrix",
        )
        LS = own.add(
            call("SUNLinSol_Dense", vp(y), vp(A), ctx, restype=vp, argtypes=(vp, vp, vp)),
            ls_free,
            "dense linear solver",
        )
        addresses = cb.addresses()
        free_mem = b.fn(lib, f"{P}Free", None, ctypes.POINTER(vp))
        if kind == CVODE:
            mem = call("CVodeCreate", CVODE_METHODS[method], ctx, restype=vp, argtypes=(ci, vp))
        else:
            mem = call("IDACreate", ctx, restype=vp, argtypes=(vp,))
        mem = own.add(mem, lambda ptr: free_mem(ctypes.byref(vp(ptr))), f"{P} memory")
        self.views = {
            "y": _vector_view(b, y, neq),
            "yp": _vector_view(b, yp, neq),
            "dky": _vector_view(b, dky, neq),
            "ident": _vector_view(b, ident, neq) if ident else np.zeros(0),
        }
        self.views["y"][:] = 0.0
        self.views["yp"][:] = 0.0
        if kind == IDA:
            self.views["ident"][:] = 1.0
        fn = ctypes.c_void_p
        if kind == CVODE:
            check(call("CVodeInit", vp(mem), fn(addresses["cvode_rhs"]), cd(0.0), vp(y)), "CVodeInit")
        else:
            check(call("IDAInit", vp(mem), fn(addresses["ida_res"]), cd(0.0), vp(y), vp(yp)), "IDAInit")
        check(call(f"{P}SStolerances", vp(mem), cd(rtol), cd(atol)), f"{P}SStolerances")
        check(call(f"{P}SetLinearSolver", vp(mem), vp(LS), vp(A)), f"{P}SetLinearSolver")
        check(call(f"{P}SetJacFn", vp(mem), fn(addresses["cvode_jac" if kind == CVODE else "ida_jac"])), f"{P}SetJacFn")
        # scikit-sundae's settings, which the per-arc adapters run with (its defaults and theirs)
        check(call(f"{P}SetMaxNonlinIters", vp(mem), ci(3 if kind == CVODE else 4)), f"{P}SetMaxNonlinIters")
        check(call(f"{P}SetMaxConvFails", vp(mem), ci(10)), f"{P}SetMaxConvFails")
        check(call(f"{P}SetInitStep", vp(mem), cd(0.0)), f"{P}SetInitStep")
        check(call(f"{P}SetMinStep", vp(mem), cd(0.0)), f"{P}SetMinStep")
        check(call(f"{P}SetMaxStep", vp(mem), cd(max_step)), f"{P}SetMaxStep")
        max_order = 12 if (kind == CVODE and method == "Adams") else 5
        check(call(f"{P}SetMaxOrd", vp(mem), ci(max_order)), f"{P}SetMaxOrd")
        check(call(f"{P}SetMaxNumSteps", vp(mem), ctypes.c_long(10**9)), f"{P}SetMaxNumSteps")
        root = addresses["cvode_root" if kind == CVODE else "ida_root"]
        check(call(f"{P}RootInit", vp(mem), ci(n_roots), fn(root)), f"{P}RootInit")
        check(call(f"{P}SetNoInactiveRootWarn", vp(mem)), f"{P}SetNoInactiveRootWarn")
        if kind == CVODE:
            check(call("CVodeSetMaxHnilWarns", vp(mem), ci(-1)), "CVodeSetMaxHnilWarns")  # the stall check says it
        if kind == IDA:
            check(call("IDASetId", vp(mem), vp(ident)), "IDASetId")
        # the callbacks' data
        self.p = p
        self.fw = np.array([F, w])
        self.scratch = np.zeros((n, n))
        self.slip_all = np.full(nb, -1, dtype=np.int64)
        self.no_sections = (np.zeros((1, n)), np.zeros(1))
        ud = self.ud = cb.user_data()
        ud[cb.UD_NVGET] = b.table[_N_VGetArrayPointer]
        ud[cb.UD_MATDATA] = ctypes.cast(getattr(b.libs[lib], "SUNDenseMatrix_Data"), vp).value
        ud[cb.UD_P], ud[cb.UD_NP] = p.ctypes.data, p.size
        ud[cb.UD_NB], ud[cb.UD_SLOTS], ud[cb.UD_N], ud[cb.UD_NEQ] = nb, slots, n, neq
        ud[cb.UD_FW] = self.fw.ctypes.data
        ud[cb.UD_SCRATCH] = self.scratch.ctypes.data
        ud[cb.UD_SLIP] = self.slip_all.ctypes.data
        ud[cb.UD_SEC_C], ud[cb.UD_SEC_L] = self.no_sections[0].ctypes.data, self.no_sections[1].ctypes.data
        check(call(f"{P}SetUserData", vp(mem), vp(ud.ctypes.data)), f"{P}SetUserData")
        self.directions = np.full(n_roots, -1, dtype=np.int32)  # guards: expected_sign * guard decreasing
        self._set_directions = lambda d: check(
            call(f"{P}SetRootDirection", vp(mem), d.ctypes.data_as(ctypes.POINTER(ci))), f"{P}SetRootDirection"
        )
        self._set_directions(self.directions)
        h = np.zeros(N_H, np.int64)
        h[H_KIND], h[H_MEM], h[H_Y], h[H_YP], h[H_DKY], h[H_ID] = kind, mem, y, yp, dky, ident
        h[H_NEQ], h[H_SLOTS], h[H_NROOTS] = neq, slots, n_roots
        self.bundle = Solver(
            calls=b.table,
            h=h,
            ud=ud,
            p=p,
            fw=self.fw,
            y=self.views["y"],
            yp=self.views["yp"] if kind == IDA else np.zeros(0),
            dky=self.views["dky"],
            ident=self.views["ident"],
            found=np.zeros(n_roots, np.int32),
            roots=np.zeros(n_roots),
            tret=np.zeros(1),
            counter=np.zeros(1, np.int64),
            wrong=np.zeros(slots + 1),
            clock=np.zeros(3, np.int64),
        )
        self.solver_name = "cvode" if kind == CVODE else "ida"

    def prepare(self, directions: np.ndarray) -> Solver:
        """The bundle for a run whose sections cross in ``directions``."""
        if self.own.alive == 0:
            raise RuntimeError("this SUNDIALS solver has been freed")
        d = np.asarray(directions, dtype=np.int32)
        if d.size != self.n_sections:
            raise ValueError(f"{d.size} section directions for a solver built for {self.n_sections}")
        if not np.array_equal(self.directions[self.n_roots - self.n_sections :], d):
            self.directions[self.n_roots - self.n_sections :] = d
            self._set_directions(self.directions)
        return self.bundle

    def failure(self, detail: int, t: float) -> str:
        """The message of a run that ended on SUNDIALS' failure code ``detail`` (``K_FAIL - flag``)."""
        if int(detail) == K_STALLED:
            return f"SUNDIALS: {MAX_STALLS} steps in a row did not advance (t + h == t) at t = {t:.6g}"
        flag = -(int(detail) - K_FAIL)
        return f"SUNDIALS: {self.binding.flag_name(self.solver_name, flag)} (flag {flag}) at t = {t:.6g}"

    def close(self) -> None:
        """Free the solver's C objects (the views on its vectors go with them)."""
        self.views = {}
        self.bundle = None  # type: ignore[assignment]
        self.own.close()


CVODE_METHODS = {"Adams": capi.CV_ADAMS, "BDF": capi.CV_BDF}


def run(solver: NativeSolver, request: Any) -> Any:
    """The whole run of ``request`` (:class:`~nsbench.integrators.base.RunRequest`) with ``solver``, from where
    the core's start rule left it; its :class:`~nsbench.integrators.base.RunReport`."""
    from nsbench.integrators.base import RunReport

    rec, st, sec, lim = request.records, request.state, request.section_bundle, request.limits
    prob = request.problem.data
    sv = solver.prepare(sec.directions)
    sv.clock[:] = 0
    st.si[SI_PHASE] = P_TOP
    prepare_time = _load_loop((sv, prob, lim, sec, rec.hits, rec.dense, rec.events, st))
    while True:
        code = native_loop(sv, prob, lim, sec, rec.hits, rec.dense, rec.events, st)
        if code == R_DONE:
            break
        if code == R_GROW_EVENTS:
            rec.grow_events(int(st.si[SI_RECORDED]))
        else:
            rec.grow_hits(int(st.si[SI_NHITS]))
    message = ""
    if int(st.si[SI_STATUS]) == RUN_FAILURE:
        message = solver.failure(int(st.si[SI_DETAIL]), float(st.sf[SF_T]))
    return RunReport(
        integrator_time=float(sv.clock[C_NS]) * 1e-9 if CLOCK else math.nan,
        extra={"root_returns": int(sv.clock[C_ROOTS]), "midpoint_checks": int(sv.clock[C_MIDPOINTS])},
        message=message,
        prepare_time=prepare_time,
    )


_LOADED: set = set()


def _load_loop(args: tuple) -> float:
    """Load (or, once per install, compile) :func:`native_loop` for these argument types before the run
    calls it; the seconds that took (first use: set-up, not the run)."""
    key = type(args[1])  # the problem family's data class: every other argument type is fixed
    if key in _LOADED:
        return 0.0
    import numba

    tic = time.perf_counter()
    native_loop.compile(tuple(numba.typeof(a) for a in args))
    _LOADED.add(key)
    return time.perf_counter() - tic
