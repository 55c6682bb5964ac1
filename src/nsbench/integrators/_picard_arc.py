"""Compiled arc kernel of ``ofapi``/``mcpi``: the loop over the collocation segments of one frozen-mode arc.

:func:`picard_arc` is the whole hot path of ``ofapi``/``mcpi``: segment-length
control, the iteration (:mod:`._picard_iteration`), guard location, section
crossings and dense output on the converged interpolant
(:mod:`._picard_location`). Times inside the arc are offsets from ``t0`` and the
start state of each segment is carried with compensated summation, so neither
rounding accumulates over the segments of an arc.
"""

from __future__ import annotations

import numpy as np

from nsbench.integrators._chebyshev import barycentric
from nsbench.integrators._picard_iteration import CONVERGED, Iteration, Nodal, picard_iterations
from nsbench.integrators._picard_location import SECTION, Segment, Target, first_zero, root, state_at
from nsbench.model.abi import (
    K_BUDGET,
    K_FAIL,
    K_HIT_FULL,
    K_HIT_STOP,
    K_OK,
    NFEV,
    NJEV,
    NSTEPS,
    SI_IEVAL,
    SI_NHITS,
    X0,
    X1,
    X2,
    X3,
)
from nsbench.model.compile import hot
from nsbench.model.law import guard_rate, guard_value, rhs
from nsbench.model.records import copy_into, linear_section_value, record_hit, section_crossed, sort_hits

#: The options vector ``fo``, by name (the integrator packs it in this order).
OPTIONS = ("h", "h_max", "h_min", "tol", "coef_tol", "max_iter", "order", "jac_node", "adaptive")
O_H, O_H_MAX, O_H_MIN, O_TOL, O_COEF_TOL, O_MAX_ITER, O_ORDER, O_JAC_NODE, O_ADAPTIVE = range(len(OPTIONS))
#: Failure codes of :func:`picard_arc` (beyond the common ones of the ABI).
NOT_CONVERGED, INACCURATE = K_FAIL, K_FAIL + 1
#: Counter slots of this kernel.
ITERATIONS, SEGMENTS, HALVINGS, REJECTIONS = X0, X1, X2, X3
GROWTH = 1.5  # largest factor between consecutive adaptive segment lengths
SAFETY = 0.9


@hot
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


def scratch(
    n_nodes: int, n_states: int, n_sections: int, n_guards: int = 0
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The kernel's scratch: node arrays, node Jacobians, vectors (``kd.f3a, f3b, f2c``)."""
    rows = max(n_states, n_sections, n_nodes, 1)
    return (
        np.zeros((6, n_nodes, n_states)),
        np.zeros((n_nodes, n_states, n_states)),
        np.zeros((8 + 2 * max(n_states, n_guards), max(rows, n_nodes))),
    )


@hot
def picard_arc(kd, fo, p, arc, sec, hits, dense, si, y_out, cnt):
    """Integrate one frozen-mode arc from ``(t0, y0)`` to the first guard zero or ``t_end``.

    ``kd``: the CGL operators of degree ``N`` (``f1a`` nodes, ``f1b`` weights, ``f2a`` E,
    ``f2b`` A) and the scratch of :func:`scratch` (``f3a`` nodal, ``f3b`` Jacobians, ``f2c``
    vectors); ``fo``: the options named in :data:`OPTIONS`. Arguments and result:
    :mod:`nsbench.model.abi` (``t0_lo`` is not used); ``p`` is the problem.

    Segment control: a segment whose iteration does not converge within
    ``max_iter`` is halved and redone. With ``adaptive``, a converged segment
    whose trailing Chebyshev coefficients exceed ``coef_tol`` is shrunk and
    redone, and the next segment grows by up to :data:`GROWTH` (at most
    ``h_max``) when they are smaller. Segments shorter than ``h_min`` end the
    arc with :data:`NOT_CONVERGED` or :data:`INACCURATE`. Every attempted
    segment counts as a step.
    """
    nodes, weights, E, A, nodal, J, vec = kd.f1a, kd.f1b, kd.f2a, kd.f2b, kd.f3a, kd.f3b, kd.f2c
    h, h_max, h_min, tol, coef_tol = fo[O_H], fo[O_H_MAX], fo[O_H_MIN], fo[O_TOL], fo[O_COEF_TOL]
    max_iter, order = int(fo[O_MAX_ITER]), int(fo[O_ORDER])
    jac_node, adaptive = fo[O_JAC_NODE] != 0.0, fo[O_ADAPTIVE] != 0.0
    mode, ng = arc.mode, arc.n_guards
    t0, y0, t_end, max_steps = arc.t0, arc.y0, arc.t_end, arc.max_steps
    sc, sl, sd, hit_from, hit_stop = sec.coeffs, sec.levels, sec.directions, sec.hit_from, sec.hit_stop
    t_eval, y_eval = dense.t, dense.y
    kinds, blocks, signs = arc.guard_kind[:ng], arc.guard_index[:ng], arc.guard_sign[:ng]
    m = nodes.shape[0]
    N = m - 1
    n = y0.shape[0]
    nq = ng
    ns = sl.shape[0]
    D, X, G, P, Y, Z = nodal[0], nodal[1], nodal[2], nodal[3], nodal[4], nodal[5]
    base, comp, dstop, ystop, ybuf, dybuf, g0 = (
        vec[0, :n],
        vec[1, :n],
        vec[2, :n],
        vec[3, :n],
        vec[4, :n],
        vec[5, :n],
        vec[6, :n],
    )
    copy_into(base, y0)  # segment start state, rounded ...
    for i in range(n):
        comp[i] = 0.0  # ... and what the rounding dropped
    phi = vec[8 : 8 + nq, :m]
    dphi = vec[8 + nq : 8 + 2 * nq, :m]
    sec_prev = vec[7, :ns]
    for s in range(ns):
        sec_prev[s] = linear_section_value(sc[s], sl[s], base)
    k_eval = t_eval.shape[0]
    n_eval = si[SI_IEVAL]
    while n_eval < k_eval and t_eval[n_eval] <= t0:
        copy_into(y_eval[n_eval], base)
        n_eval += 1
    si[SI_IEVAL] = n_eval
    status = K_OK
    fired = -1
    span = t_end - t0
    s_a = 0.0  # offset of the segment start from t0
    t_a = t0
    hseg = h
    retried = False
    steps = 0
    rhs(p, mode, t_a, base, g0)
    cnt[NFEV] += 1
    while s_a < span:
        if steps >= max_steps:
            status = K_BUDGET
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
        for i in range(n):
            D[0, i] = 0.0
        code, its, nf, nj = picard_iterations(
            p, mode, t_a, base, w, nodes, E, Nodal(D, X, G, J, P, Y, Z), Iteration(order, jac_node, tol, max_iter)
        )
        steps += 1
        cnt[NSTEPS] += 1
        cnt[ITERATIONS] += its
        cnt[NFEV] += nf
        cnt[NJEV] += nj
        if code != CONVERGED:
            cnt[HALVINGS] += 1
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
                cnt[REJECTIONS] += 1
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
                phi[q, j] = signs[q] * guard_value(p, mode, kinds[q], blocks[q], t_j, X[j])
                dphi[q, j] = w * signs[q] * guard_rate(p, mode, kinds[q], blocks[q], t_j, X[j], G[j])
        best_tau = np.inf
        best_q = -1
        j_stop = N
        seg = Segment(t_a, w, nodes, weights, D, base, comp)
        for j in range(1, m):
            for q in range(nq):
                tg = Target(kinds[q], blocks[q], float(signs[q]), sc, sl)
                found, tau, nf = first_zero(
                    p,
                    mode,
                    tg,
                    seg,
                    nodes[j - 1],
                    nodes[j],
                    phi[q, j - 1],
                    phi[q, j],
                    dphi[q, j - 1],
                    dphi[q, j],
                    ybuf,
                    dybuf,
                )
                cnt[NFEV] += nf
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
        first_new = si[SI_NHITS]
        for s in range(ns):
            before = sec_prev[s]
            for j in range(1, j_stop + 1):
                b = nodes[j]
                if j == j_stop:
                    b = tau_stop
                    after = linear_section_value(sc[s], sl[s], ystop)
                else:
                    after = linear_section_value(sc[s], sl[s], X[j])
                if section_crossed(sd[s], before, after):
                    tau = b
                    if after != 0.0:
                        sgn = 1.0 if before > 0.0 else -1.0
                        tau, nf = root(
                            p,
                            mode,
                            Target(SECTION, s, sgn, sc, sl),
                            seg,
                            nodes[j - 1],
                            b,
                            sgn * before,
                            sgn * after,
                            ybuf,
                            dybuf,
                        )
                        cnt[NFEV] += nf
                    t_hit = t0 + (s_a + w * (tau + 1.0))
                    if t_hit >= hit_from:
                        if si[SI_NHITS] >= hits.t.shape[0]:
                            return K_HIT_FULL, t0, 0.0, -1
                        state_at(nodes, weights, D, base, comp, tau, ybuf)
                        record_hit(hits, si, s, t_hit, ybuf)
                before = after
            sec_prev[s] = before
        if si[SI_NHITS] > first_new:
            sort_hits(hits, first_new, si[SI_NHITS])
            if 0 <= hit_stop <= si[SI_NHITS]:
                si[SI_NHITS] = hit_stop
                t_stop = hits.t[hit_stop - 1]
                _dense(dense, si, t0, s_a, t_stop, 1.0, seg, ybuf)
                copy_into(y_out, hits.y[hit_stop - 1])
                return K_HIT_STOP, t_stop, 0.0, -1
        _dense(dense, si, t0, s_a, t_stop, tau_stop, seg, ybuf)
        # next start state, compensated: base + comp += increment at tau_stop
        if tau_stop == 1.0:
            copy_into(dstop, D[N])
        else:
            barycentric(nodes, weights, D, tau_stop, dstop)
        for i in range(n):
            increment = dstop[i] + comp[i]
            new = base[i] + increment
            comp[i] = increment - (new - base[i])
            base[i] = new
        cnt[SEGMENTS] += 1
        s_a = s_stop
        t_a = t_stop
        if best_q >= 0:
            fired = best_q
            break
        if not last:
            rhs(p, mode, t_a, base, g0)
            cnt[NFEV] += 1
        hseg = h_next
    copy_into(y_out, base)
    return status, t_a, 0.0, fired


@hot
def _dense(dense, si, t0, s_a, t_stop, tau_max, seg, ybuf):
    """States at the requested times up to ``t_stop`` from the segment's interpolant."""
    t_eval, y_eval = dense.t, dense.y
    i = si[SI_IEVAL]
    while i < t_eval.shape[0] and t_eval[i] <= t_stop:
        tau = min(max(((t_eval[i] - t0) - s_a) / seg.w - 1.0, -1.0), tau_max)
        state_at(seg.nodes, seg.weights, seg.D, seg.base, seg.comp, tau, ybuf)
        copy_into(y_eval[i], ybuf)
        i += 1
    si[SI_IEVAL] = i
