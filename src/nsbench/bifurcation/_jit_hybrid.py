"""The whole hybrid loop of the engine, compiled: arcs, transitions, records and budgets.

:func:`hybrid_run` is :func:`nsbench.engine.simulate` without Python in the
loop: it advances arcs with a compiled method (``EXACT``: closed form,
``RK4``: RK4 + Henon), applies the transition map and every guard that must
fire at once (the engine's ``settle``), detects event storms, and records one
kind of section point after ``t_rec`` until ``n_rec`` are stored: peaks (a
state section), stroboscopic states (given times), stick events or slip events
(mapping points). It starts from a given mode or from the mode of the state.
"""

from __future__ import annotations

import numpy as np

from nsbench.bifurcation._jit_exact import exact_arc
from nsbench.bifurcation._jit_model import (
    KIND_SLIP,
    KIND_STICK,
    guards_of,
    initial_mode,
    pending_guard,
    transition,
)
from nsbench.integrators import _henon_kernel as henon
from nsbench.problems.kernels import jit

EXACT, RK4 = 0, 1
SEC_STATE, SEC_TIME, SEC_STICK, SEC_SLIP = 0, 1, 2, 3
OK, BUDGET, STORM, FAILURE = 0, 1, 2, 3
# counter slots
C_NFEV, C_NSTEPS, C_ROOTS, C_BISECT, C_EVENTS = 0, 1, 2, 3, 4
C_STICK1, C_STICK2, C_SLIP1, C_SLIP2, C_REV1, C_REV2 = 5, 6, 7, 8, 9, 10
N_COUNTERS = 11


@jit
def _rk4_arc(p, mode, t0, y0, t_end, h, max_steps, sc, sl, sd, t_eval, i_eval, y_eval,
             hit_t, hit_y, hit_k, max_hits, t_rec, y_out, cnt):
    """One arc of ``henon-rk4`` (the compiled kernel of :mod:`nsbench.integrators._henon_kernel`).

    Adapts the kernel to :func:`_arc`'s conventions: section hits before ``t_rec``
    are dropped, the arc stops once ``max_hits`` are kept (``fired = -2``, at the
    last kept hit), ``fired`` is -3 on an exhausted budget and -4 on a
    non-finite state; ``y_eval`` rows are states.
    """
    n = y0.shape[0]
    gk = np.empty(4, np.int64)
    gb = np.empty(4, np.int64)
    gs = np.empty(4, np.int64)
    ng = guards_of(mode, gk, gb, gs)
    ns = sc.shape[0]
    n_total = max(1, int(np.ceil((t_end - t0) / h - 1e-9)))
    buf_k = np.empty(max_hits + ns, np.int64)
    buf_t = np.empty(max_hits + ns)
    buf_y = np.empty((max_hits + ns, n))
    counters = np.zeros(6, np.int64)
    y = y0.copy()
    y_stop = np.empty(n)
    y_cols = y_eval.T
    t = t0
    step = 0
    used = 0
    kept = 0
    while True:
        cap = max_hits - kept + ns - 1 if ns > 0 else 0  # the kernel stops once `need` hits are stored
        status, t, fired, step = henon.henon_arc(
            p, mode, t0, step, t, y, t_end, h, n_total, gk[:ng], gb[:ng], gs[:ng], sc, sl, sd,
            t_eval, i_eval, max_steps - used, y_cols, buf_k[:cap], buf_t[:cap], buf_y[:cap], y_stop,
            counters)
        used += counters[0]
        cnt[C_NSTEPS] += counters[0]
        cnt[C_NFEV] += counters[1]
        cnt[C_ROOTS] += counters[2]
        cnt[C_BISECT] += counters[3]
        i_eval = counters[4]
        for j in range(counters[5]):
            if buf_t[j] >= t_rec and kept < max_hits:
                hit_t[kept] = buf_t[j]
                hit_k[kept] = buf_k[j]
                hit_y[kept, :] = buf_y[j]
                kept += 1
        y[:] = y_stop
        if status == henon.BUDGET:
            y_out[:] = y
            return t, -3, i_eval, kept
        if status == henon.FAILURE:
            y_out[:] = y
            return t, -4, i_eval, kept
        if ns > 0 and kept >= max_hits and fired < 0:
            y_out[:] = hit_y[kept - 1]
            return hit_t[kept - 1], -2, i_eval, kept
        if status != henon.BUFFER_FULL:
            y_out[:] = y
            return t, fired, i_eval, kept


@jit
def _arc(method, p, ft, opts, mode, t, y, t_end, max_steps, sc, sl, sd, t_eval, i_eval, y_eval,
         hit_t, hit_y, hit_k, max_hits, t_rec, y_out, cnt):
    if method == EXACT:
        return exact_arc(p, ft, mode, t, y, t_end, opts[0], opts[1], sc, sl, sd, t_eval, i_eval, y_eval,
                         hit_t, hit_y, hit_k, max_hits, t_rec, y_out, cnt)
    return _rk4_arc(p, mode, t, y, t_end, opts[0], max_steps, sc, sl, sd, t_eval, i_eval, y_eval,
                    hit_t, hit_y, hit_k, max_hits, t_rec, y_out, cnt)


@jit
def hybrid_run(method, p, ft, opts, t0, y0, mode, use_mode, t_end, sec_kind, sc, sl, sd, t_eval,
               t_rec, n_rec, rec_t, rec_y, rec_kind, rec_block, max_steps, max_events,
               zeno_events, zeno_span, cnt):
    """Run the hybrid system from ``(t0, y0)``; record section points; return the outcome.

    Parameters
    ----------
    method
        ``EXACT`` or ``RK4``; ``opts`` is ``[scan, max_scan]`` or ``[h]``.
    mode, use_mode
        Start mode (int64 phases, updated in place to the final mode); if
        ``use_mode`` is false it is set from the state, as the engine does.
    sec_kind
        ``SEC_STATE`` (sections ``sc, sl, sd``), ``SEC_TIME`` (states at
        ``t_eval``), ``SEC_STICK`` or ``SEC_SLIP`` (events after transition).
    t_rec, n_rec
        Record points at ``t >= t_rec``; stop when ``n_rec`` are stored.
    rec_t, rec_y, rec_kind, rec_block
        Output buffers of length ``n_rec``.
    cnt
        Counters (``N_COUNTERS`` int64 slots), accumulated; event counts by
        kind and block are those at ``t >= t_rec``.

    Returns
    -------
    (status, t_final, y_final, n_recorded)
    """
    n = y0.shape[0]
    nb = n // 2
    v0 = p[3 + 6 * nb]
    y = y0.copy()
    y_new = np.empty(n)
    dy = np.empty(n)
    gk = np.empty(4, np.int64)
    gb = np.empty(4, np.int64)
    gs = np.empty(4, np.int64)
    ring = np.empty(zeno_events + 1)
    n_ring = 0
    if not use_mode:
        initial_mode(p, t0, y, mode)
    t = t0
    n_recd = 0
    status = OK
    # the engine's start rule: a slipping block exactly at v0 is fresh
    fresh = 0
    for i in range(nb):
        if mode[i] != 0 and y[2 * i + 1] == v0:
            fresh |= 1 << i
    q = pending_guard(p, mode, t, y, fresh, gk, gb, gs, dy)
    kind_q, block_q = (gk[q], gb[q]) if q >= 0 else (0, 0)
    empty_sc = sc[:0]
    while True:
        # settle: apply the fired guard and every guard that must follow at once
        while q >= 0:
            ev = transition(p, mode, kind_q, block_q, t, y)
            cnt[C_EVENTS] += 1
            if t >= t_rec:
                if ev == KIND_STICK:
                    cnt[C_STICK1 + block_q] += 1
                elif ev == KIND_SLIP:
                    cnt[C_SLIP1 + block_q] += 1
                else:
                    cnt[C_REV1 + block_q] += 1
                if (sec_kind == SEC_STICK and ev == KIND_STICK) or (sec_kind == SEC_SLIP and ev == KIND_SLIP):
                    if n_recd < n_rec:
                        rec_t[n_recd] = t
                        rec_y[n_recd, :] = y
                        rec_kind[n_recd] = ev
                        rec_block[n_recd] = block_q + 1
                        n_recd += 1
            ring[n_ring % (zeno_events + 1)] = t
            n_ring += 1
            if cnt[C_EVENTS] >= max_events:
                return BUDGET, t, y, n_recd
            if n_ring > zeno_events and t - ring[n_ring % (zeno_events + 1)] <= zeno_span:
                return STORM, t, y, n_recd
            if mode[block_q] != 0:
                fresh |= 1 << block_q
            else:
                fresh &= ~(1 << block_q)
            q = pending_guard(p, mode, t, y, fresh, gk, gb, gs, dy)
            if q >= 0:
                kind_q, block_q = gk[q], gb[q]
        if n_recd >= n_rec or t >= t_end:
            return status, t, y, n_recd
        # one arc
        if sec_kind == SEC_STATE:
            a_t, fired, _, nh = _arc(method, p, ft, opts, mode, t, y, t_end, max_steps - cnt[C_NSTEPS],
                                     sc, sl, sd, t_eval[:0], 0, rec_y, rec_t[n_recd:], rec_y[n_recd:],
                                     rec_kind[n_recd:], n_rec - n_recd, t_rec, y_new, cnt)
            for j in range(n_recd, n_recd + nh):
                rec_block[j] = 1
                rec_kind[j] = -1
            n_recd += nh
        elif sec_kind == SEC_TIME:
            a_t, fired, i_ev, _ = _arc(method, p, ft, opts, mode, t, y, t_end, max_steps - cnt[C_NSTEPS],
                                       empty_sc, sl[:0], sd[:0], t_eval, n_recd, rec_y, rec_t, rec_y,
                                       rec_kind, 0, t_rec, y_new, cnt)
            for j in range(n_recd, i_ev):
                rec_t[j] = t_eval[j]
                rec_kind[j] = -1
                rec_block[j] = 0
            n_recd = i_ev
        else:
            a_t, fired, _, _ = _arc(method, p, ft, opts, mode, t, y, t_end, max_steps - cnt[C_NSTEPS],
                                    empty_sc, sl[:0], sd[:0], t_eval[:0], 0, rec_y, rec_t, rec_y,
                                    rec_kind, 0, t_rec, y_new, cnt)
        if fired == -3:
            return BUDGET, a_t, y_new, n_recd
        if fired == -4:
            return FAILURE, t, y, n_recd
        t = a_t
        y[:] = y_new
        if fired == -2 or fired == -1:
            return status, t, y, n_recd
        if cnt[C_NSTEPS] >= max_steps:
            return BUDGET, t, y, n_recd
        guards_of(mode, gk, gb, gs)
        kind_q, block_q = gk[fired], gb[fired]
        q = fired
        fresh = 0
