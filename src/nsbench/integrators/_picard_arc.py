"""Compiled (numba) loop over the collocation segments of one frozen-mode arc.

:func:`advance_arc` is the whole hot path of ``ofapi``/``mcpi``: segment-length
control, the iteration (:mod:`._picard_iteration`), guard location, section
crossings and dense output on the converged interpolant
(:mod:`._picard_location`). Times inside the arc are offsets from ``t0`` and the
start state of each segment is carried with compensated summation, so neither
rounding accumulates over the segments of an arc.
"""

from __future__ import annotations

import numpy as np

from nsbench.integrators._chebyshev import barycentric
from nsbench.integrators._picard_iteration import CONVERGED, picard_iterations
from nsbench.integrators._picard_location import SECTION, first_zero, root, state_at
from nsbench.problems.kernels import guard_rate, guard_value, jit, linear_section_value, rhs, section_crossed

#: Status codes of :func:`advance_arc`.
SUCCESS, BUDGET_EXHAUSTED, NOT_CONVERGED, INACCURATE = 0, 1, 2, 3
#: Slots of the counter array returned by :func:`advance_arc`.
NFEV, NJEV, NSTEPS, SEGMENTS, ITERATIONS, HALVINGS, REJECTIONS = range(7)
N_COUNTERS = 7
GROWTH = 1.5  # largest factor between consecutive adaptive segment lengths
SAFETY = 0.9


@jit
def _store_hit(hit_index, hit_t, hit_y, n_hits, index, t, y):
    """Append a section hit, doubling the buffers when full; returns the buffers."""
    if n_hits == hit_t.shape[0]:
        cap = 2 * hit_t.shape[0]
        new_index = np.empty(cap, np.int64)
        new_t = np.empty(cap)
        new_y = np.empty((cap, hit_y.shape[1]))
        new_index[:n_hits] = hit_index[:n_hits]
        new_t[:n_hits] = hit_t[:n_hits]
        new_y[:n_hits] = hit_y[:n_hits]
        hit_index, hit_t, hit_y = new_index, new_t, new_y
    hit_index[n_hits] = index
    hit_t[n_hits] = t
    hit_y[n_hits, :] = y
    return hit_index, hit_t, hit_y


@jit
def _trailing(A, D, scale):
    """Largest of the two trailing Chebyshev coefficients of the increments, relative to ``scale``."""
    m, n = D.shape
    out = 0.0
    for i in range(n):
        c1 = 0.0
        c2 = 0.0
        for j in range(m):
            c1 += A[m - 2, j] * D[j, i]
            c2 += A[m - 1, j] * D[j, i]
        out = max(out, abs(c1), abs(c2))
    return out / scale


@jit
def advance_arc(p, mode, kinds, blocks, signs, sec_coeffs, sec_levels, sec_dirs, t0, y0, t_end,
                t_eval, max_steps, nodes, weights, E, A, h, h_max, h_min, tol, coef_tol, max_iter,
                order, jac_node, adaptive):
    """Integrate one frozen-mode arc from ``(t0, y0)`` to the first guard zero or ``t_end``.

    Segment control: a segment whose iteration does not converge within
    ``max_iter`` is halved and redone. With ``adaptive``, a converged segment
    whose trailing Chebyshev coefficients exceed ``coef_tol`` is shrunk and
    redone, and the next segment grows by up to :data:`GROWTH` (at most
    ``h_max``) when they are smaller. Segments shorter than ``h_min`` end the
    arc with a failure status. Every attempted segment counts as a step.

    Returns
    -------
    (status, t, y, fired, y_eval, n_eval, hit_index, hit_t, hit_y, n_hits, counts)
        ``fired`` is the guard index or -1; ``y_eval[:, :n_eval]`` are the
        states at ``t_eval[:n_eval]``; the section hits come in section order;
        ``counts`` follows the slot constants of this module.
    """
    m = nodes.shape[0]
    N = m - 1
    n = y0.shape[0]
    nq = kinds.shape[0]
    ns = sec_levels.shape[0]
    D = np.empty((m, n))
    X = np.empty((m, n))
    G = np.empty((m, n))
    P = np.empty((m, n))
    Y = np.empty((m, n))
    Z = np.empty((m, n))
    J = np.empty((m, n, n))
    base = y0.copy()  # segment start state, rounded ...
    comp = np.zeros(n)  # ... and what the rounding dropped
    dstop = np.empty(n)
    ystop = np.empty(n)
    ybuf = np.empty(n)
    dybuf = np.empty(n)
    g0 = np.empty(n)
    phi = np.empty((nq, m))
    dphi = np.empty((nq, m))
    sec_prev = np.empty(ns)
    for s in range(ns):
        sec_prev[s] = linear_section_value(sec_coeffs[s], sec_levels[s], base)
    k_eval = t_eval.shape[0]
    y_eval = np.empty((n, k_eval))
    n_eval = 0
    while n_eval < k_eval and t_eval[n_eval] <= t0:
        y_eval[:, n_eval] = base
        n_eval += 1
    hit_index = np.empty(8, np.int64)
    hit_t = np.empty(8)
    hit_y = np.empty((8, n))
    n_hits = 0
    counts = np.zeros(N_COUNTERS, np.int64)
    status = SUCCESS
    fired = -1
    span = t_end - t0
    s_a = 0.0  # offset of the segment start from t0
    t_a = t0
    hseg = h
    retried = False
    rhs(p, mode, t_a, base, g0)
    counts[NFEV] += 1
    while s_a < span:
        if counts[NSTEPS] >= max_steps:
            status = BUDGET_EXHAUSTED
            break
        hs = hseg
        last = span - s_a <= 1.01 * hs  # no sliver of a segment before t_end
        if last:
            hs = span - s_a
        w = 0.5 * hs
        for j in range(m):  # linear predictor: no extra field evaluation
            for i in range(n):
                D[j, i] = w * (nodes[j] + 1.0) * g0[i]
                G[j, i] = g0[i]
        D[0, :] = 0.0
        code, its, nf, nj = picard_iterations(p, mode, t_a, base, w, nodes, E, D, X, G, J, P, Y, Z,
                                              order, jac_node, tol, max_iter)
        counts[NSTEPS] += 1
        counts[ITERATIONS] += its
        counts[NFEV] += nf
        counts[NJEV] += nj
        if code != CONVERGED:
            counts[HALVINGS] += 1
            hseg = 0.5 * hs
            retried = True
            if hseg < h_min:
                status = NOT_CONVERGED
                break
            continue
        if adaptive:
            scale = 1.0
            for j in range(m):
                for i in range(n):
                    scale = max(scale, abs(X[j, i]))
            trailing = _trailing(A, D, scale)
            if trailing > coef_tol:
                counts[REJECTIONS] += 1
                hseg = hs * max(0.2, SAFETY * (coef_tol / trailing) ** (1.0 / N))
                retried = True
                if hseg < h_min:
                    status = INACCURATE
                    break
                continue
            grow = GROWTH if trailing == 0.0 else min(GROWTH, SAFETY * (coef_tol / trailing) ** (1.0 / N))
            if retried:  # no growth right after a halving or a rejection
                grow = min(grow, 1.0)
            h_next = min(h_max, hs * grow)
        else:
            h_next = min(h, 2.0 * hs)  # back to the nominal length after a halving
        retried = False
        # signed guard values and tau-rates at the nodes (rates from the last field sweep)
        for q in range(nq):
            for j in range(m):
                t_j = t_a + w * (nodes[j] + 1.0)
                phi[q, j] = signs[q] * guard_value(p, kinds[q], blocks[q], t_j, X[j])
                dphi[q, j] = w * signs[q] * guard_rate(p, kinds[q], blocks[q], t_j, X[j], G[j])
        best_tau = np.inf
        best_q = -1
        j_stop = N
        for j in range(1, m):
            for q in range(nq):
                found, tau, nf = first_zero(p, mode, kinds[q], blocks[q], float(signs[q]), sec_coeffs,
                                            sec_levels, t_a, w, nodes, weights, D, base, comp,
                                            nodes[j - 1], nodes[j], phi[q, j - 1], phi[q, j],
                                            dphi[q, j - 1], dphi[q, j], ybuf, dybuf)
                counts[NFEV] += nf
                if found and tau < best_tau:  # earliest; the lowest index on a tie
                    best_tau = tau
                    best_q = q
            if best_q >= 0:
                j_stop = j
                break
        if best_q >= 0:
            tau_stop = best_tau
            s_stop = s_a + w * (tau_stop + 1.0)
            t_stop = t0 + s_stop
        else:
            tau_stop = 1.0
            s_stop = span if last else s_a + hs
            t_stop = t_end if last else t0 + s_stop
        state_at(nodes, weights, D, base, comp, tau_stop, ystop)
        # section crossings on [t_a, t_stop]
        for s in range(ns):
            before = sec_prev[s]
            for j in range(1, j_stop + 1):
                b = nodes[j]
                if j == j_stop:
                    b = tau_stop
                    after = linear_section_value(sec_coeffs[s], sec_levels[s], ystop)
                else:
                    after = linear_section_value(sec_coeffs[s], sec_levels[s], X[j])
                if section_crossed(sec_dirs[s], before, after):
                    tau = b
                    if after != 0.0:
                        sgn = 1.0 if before > 0.0 else -1.0
                        tau, nf = root(p, mode, SECTION, s, sgn, sec_coeffs, sec_levels, t_a, w, nodes,
                                       weights, D, base, comp, nodes[j - 1], b, sgn * before,
                                       sgn * after, ybuf, dybuf)
                        counts[NFEV] += nf
                    state_at(nodes, weights, D, base, comp, tau, ybuf)
                    hit_index, hit_t, hit_y = _store_hit(hit_index, hit_t, hit_y, n_hits, s,
                                                         t0 + (s_a + w * (tau + 1.0)), ybuf)
                    n_hits += 1
                before = after
            sec_prev[s] = before
        # dense output
        while n_eval < k_eval and t_eval[n_eval] <= t_stop:
            tau = min(max(((t_eval[n_eval] - t0) - s_a) / w - 1.0, -1.0), tau_stop)
            state_at(nodes, weights, D, base, comp, tau, ybuf)
            y_eval[:, n_eval] = ybuf
            n_eval += 1
        # next start state, compensated: base + comp += increment at tau_stop
        if tau_stop == 1.0:
            dstop[:] = D[N]
        else:
            barycentric(nodes, weights, D, tau_stop, dstop)
        for i in range(n):
            increment = dstop[i] + comp[i]
            new = base[i] + increment
            comp[i] = increment - (new - base[i])
            base[i] = new
        counts[SEGMENTS] += 1
        s_a = s_stop
        t_a = t_stop
        if best_q >= 0:
            fired = best_q
            break
        if not last:
            rhs(p, mode, t_a, base, g0)
            counts[NFEV] += 1
        hseg = h_next
    return status, t_a, base, fired, y_eval, n_eval, hit_index, hit_t, hit_y, n_hits, counts
