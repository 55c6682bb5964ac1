"""Compiled arc of ``henon-rk4``: fixed-step RK4, Henon steps, grazing checks, sections, dense output.

The same algorithm as the generic Python loop in :mod:`nsbench.integrators.henon_rk4`,
on the numba kernels of the friction oscillator. One call advances one frozen
mode until a guard fires, ``t_end``, the step budget, or the section buffer is
full (the caller then resumes from the returned state on the same step grid).
"""

from __future__ import annotations

import numpy as np

from nsbench.problems.kernels import (
    guard_rate,
    guard_value,
    jit,
    linear_section_rate,
    linear_section_value,
    rhs,
    section_crossed,
)

SUCCESS, BUDGET, FAILURE, BUFFER_FULL = 0, 1, 2, 3


@jit
def _value(p, fn, idx, kinds, blocks, sec_c, sec_l, t, y):
    if fn == 0:
        return guard_value(p, kinds[idx], blocks[idx], t, y)
    return linear_section_value(sec_c[idx], sec_l[idx], y)


@jit
def _rate(p, fn, idx, kinds, blocks, sec_c, t, y, dy):
    if fn == 0:
        return guard_rate(p, kinds[idx], blocks[idx], t, y, dy)
    return linear_section_rate(sec_c[idx], dy)


@jit
def _rk4(p, mode, t, y, h, fy, out, work):
    """One RK4 step into ``out``; ``fy = f(t, y)`` known. Three new evaluations."""
    n = y.shape[0]
    k2, k3, k4, tmp = work[0], work[1], work[2], work[3]
    for j in range(n):
        tmp[j] = y[j] + 0.5 * h * fy[j]
    rhs(p, mode, t + 0.5 * h, tmp, k2)
    for j in range(n):
        tmp[j] = y[j] + 0.5 * h * k2[j]
    rhs(p, mode, t + 0.5 * h, tmp, k3)
    for j in range(n):
        tmp[j] = y[j] + h * k3[j]
    rhs(p, mode, t + h, tmp, k4)
    for j in range(n):
        out[j] = y[j] + (h / 6.0) * (fy[j] + 2.0 * k2[j] + 2.0 * k3[j] + k4[j])


@jit
def _henon(p, mode, fn, idx, kinds, blocks, sec_c, sec_l, ta, tb, t1, y1, out, work):
    """RK4 step in sigma = fn from (t1, y1) to fn = 0. Returns (ok, t_star); state into out."""
    n = y1.shape[0]
    f, tmp, acc = work[4], work[5], work[6]
    ds = -_value(p, fn, idx, kinds, blocks, sec_c, sec_l, t1, y1)
    t_acc = 0.0
    t_s = t1
    for j in range(n):
        tmp[j] = y1[j]
        acc[j] = 0.0
    weights = (1.0, 2.0, 2.0, 1.0)
    fractions = (0.5, 0.5, 1.0, 0.0)
    for stage in range(4):
        rhs(p, mode, t_s, tmp, f)
        r = _rate(p, fn, idx, kinds, blocks, sec_c, t_s, tmp, f)
        if r == 0.0 or not np.isfinite(r):
            return False, 0.0
        kt = 1.0 / r
        t_acc += weights[stage] * kt
        for j in range(n):
            ky = f[j] * kt
            acc[j] += weights[stage] * ky
            tmp[j] = y1[j] + fractions[stage] * ds * ky
        t_s = t1 + fractions[stage] * ds * kt
    t_star = t1 + ds / 6.0 * t_acc
    for j in range(n):
        out[j] = y1[j] + ds / 6.0 * acc[j]
        if not np.isfinite(out[j]):
            return False, 0.0
    if not (ta < t_star <= tb):
        return False, 0.0
    return True, t_star


@jit
def _bisect(p, mode, fn, idx, sign, kinds, blocks, sec_c, sec_l, t, y, fy, t1, start, out, work):
    """First zero of sign*fn in (t, t1] from RK4 sub-steps of (t, y).

    Returns ``(found, t_hit, n_substeps)``; the state at ``t_hit`` goes into ``out``.
    """
    ys = work[7]
    lo = t
    hi = -1.0
    positive_seen = not start
    n_sub = 0
    for k in range(1, 9):
        tau = t + (t1 - t) * k / 8.0
        _rk4(p, mode, t, y, tau - t, fy, ys, work)
        n_sub += 1
        v = sign * _value(p, fn, idx, kinds, blocks, sec_c, sec_l, tau, ys)
        if v > 0.0:
            positive_seen = True
            lo = tau
        elif positive_seen:
            hi = tau
            out[:] = ys
            break
    if hi < 0.0:
        return False, 0.0, n_sub
    for _ in range(80):
        mid = 0.5 * (lo + hi)
        if mid <= lo or mid >= hi:
            break
        _rk4(p, mode, t, y, mid - t, fy, ys, work)
        n_sub += 1
        v = sign * _value(p, fn, idx, kinds, blocks, sec_c, sec_l, mid, ys)
        if v > 0.0:
            lo = mid
        else:
            hi = mid
            out[:] = ys
    return True, hi, n_sub


@jit
def _dips(p0, p1, d0, d1, skip_start):
    """Whether the cubic Hermite with positive ends p0, p1 and end slopes d0, d1 dips to <= 0."""
    a = 2.0 * p0 - 2.0 * p1 + d0 + d1
    b = -3.0 * p0 + 3.0 * p1 - 2.0 * d0 - d1
    # critical points: 3a s^2 + 2b s + d0 = 0
    qa, qb, qc = 3.0 * a, 2.0 * b, d0
    roots = np.empty(2)
    nroots = 0
    if qa == 0.0:
        if qb != 0.0:
            roots[0] = -qc / qb
            nroots = 1
    else:
        disc = qb * qb - 4.0 * qa * qc
        if disc >= 0.0:
            sq = np.sqrt(disc)
            roots[0] = (-qb - sq) / (2.0 * qa)
            roots[1] = (-qb + sq) / (2.0 * qa)
            nroots = 2
    for k in range(nroots):
        s = roots[k]
        if 0.0 < s < 1.0 and 6.0 * a * s + 2.0 * b > 0.0:
            if skip_start and s < 1e-6:
                continue
            if ((a * s + b) * s + d0) * s + p0 <= 0.0:
                return True
    return False


@jit
def _hermite_into(ta, ya, fa, tb, yb, fb, t, out, col):
    h = tb - ta
    th = (t - ta) / h
    h00 = (1.0 + 2.0 * th) * (1.0 - th) ** 2
    h10 = th * (1.0 - th) ** 2
    h01 = th * th * (3.0 - 2.0 * th)
    h11 = th * th * (th - 1.0)
    for j in range(ya.shape[0]):
        out[j, col] = h00 * ya[j] + h * h10 * fa[j] + h01 * yb[j] + h * h11 * fb[j]


@jit
def henon_arc(p, mode, grid_t0, step0, t_start, y_start, t_end, h, n_steps_total, kinds, blocks, signs,
              sec_c, sec_l, sec_dir, t_eval, n_eval_done, max_steps,
              y_eval, hit_idx, hit_t, hit_y, y_stop, counters):
    """Advance one frozen mode from ``(t_start, y_start)``; see the module docstring.

    The step grid is ``grid_t0 + k h`` for ``k = step0 + 1 ..``, the last point
    being ``t_end`` (``n_steps_total`` steps from ``grid_t0``). ``counters`` receives
    ``[nsteps, nfev, henon_steps, bisections, n_eval_done, n_hits]``.

    Returns ``(status, t_stop, fired, steps_done)``; ``y_stop`` receives the state.
    """
    n = y_start.shape[0]
    ng = kinds.shape[0]
    ns = sec_l.shape[0]
    work = np.empty((8, n))
    y = y_start.copy()
    fy = np.empty(n)
    y1 = np.empty(n)
    f1 = np.empty(n)
    ystar = np.empty(n)
    ybest = np.empty(n)
    phi = np.empty(ng)
    psi = np.empty(ng)
    phi1 = np.empty(ng)
    psi1 = np.empty(ng)
    sec_v = np.empty(ns)
    dummy_l = np.zeros(1)
    t = t_start
    rhs(p, mode, t, y, fy)
    nfev = 1
    for q in range(ng):
        phi[q] = signs[q] * guard_value(p, kinds[q], blocks[q], t, y)
        psi[q] = signs[q] * guard_rate(p, kinds[q], blocks[q], t, y, fy)
    for k in range(ns):
        sec_v[k] = linear_section_value(sec_c[k], sec_l[k], y)
    n_done = n_eval_done
    n_hits = 0
    steps = 0
    henon_steps = 0
    bisections = 0
    status = SUCCESS
    fired = -1
    step = step0
    cap = hit_t.shape[0]
    while t < t_end:
        if steps >= max_steps:
            status = BUDGET
            break
        if n_hits + ns > cap:
            status = BUFFER_FULL
            break
        step += 1
        t1 = t_end if step >= n_steps_total else grid_t0 + step * h
        hk = t1 - t
        _rk4(p, mode, t, y, hk, fy, y1, work)
        rhs(p, mode, t1, y1, f1)
        nfev += 4
        steps += 1
        finite = True
        for j in range(n):
            if not np.isfinite(y1[j]):
                finite = False
        if not finite:
            status = FAILURE
            break
        start = step == 1  # the arc's first step starts on the surface of its phase
        best_t = np.inf
        for q in range(ng):
            p1 = signs[q] * guard_value(p, kinds[q], blocks[q], t1, y1)
            d1 = signs[q] * guard_rate(p, kinds[q], blocks[q], t1, y1, f1)
            phi1[q] = p1
            psi1[q] = d1
            end_crossed = p1 <= 0.0
            crossed = end_crossed or ((phi[q] > 0.0 or start)
                                      and _dips(phi[q], p1, hk * psi[q], hk * d1, start))
            if not crossed:
                continue
            ok = False
            t_hit = 0.0
            if end_crossed:
                henon_steps += 1
                nfev += 4
                ok, t_hit = _henon(p, mode, 0, q, kinds, blocks, sec_c, dummy_l, t, t1, t1, y1, ystar, work)
            if not ok:
                bisections += 1
                ok, t_hit, n_sub = _bisect(p, mode, 0, q, signs[q], kinds, blocks, sec_c, dummy_l,
                                           t, y, fy, t1, start, ystar, work)
                nfev += 3 * n_sub
            if ok and t_hit < best_t:
                best_t = t_hit
                fired = q
                ybest[:] = ystar
        tb = t1
        if fired >= 0:
            tb = best_t
            y1[:] = ybest
            rhs(p, mode, tb, y1, f1)
            nfev += 1
        # sections between t and tb
        for k in range(ns):
            vb = linear_section_value(sec_c[k], sec_l[k], y1)
            if section_crossed(sec_dir[k], sec_v[k], vb):
                if vb == 0.0:
                    hit_idx[n_hits] = k
                    hit_t[n_hits] = tb
                    hit_y[n_hits, :] = y1
                    n_hits += 1
                else:
                    henon_steps += 1
                    nfev += 4
                    ok, t_hit = _henon(p, mode, 1, k, kinds, blocks, sec_c, sec_l, t, tb, tb, y1, ystar, work)
                    if not ok:
                        bisections += 1
                        sgn = 1.0 if sec_v[k] > 0.0 else -1.0
                        ok, t_hit, n_sub = _bisect(p, mode, 1, k, sgn, kinds, blocks, sec_c, sec_l,
                                                   t, y, fy, tb, False, ystar, work)
                        nfev += 3 * n_sub
                    if ok:
                        hit_idx[n_hits] = k
                        hit_t[n_hits] = t_hit
                        hit_y[n_hits, :] = ystar
                        n_hits += 1
            sec_v[k] = vb
        # dense output on (t, tb]
        while n_done < t_eval.shape[0] and t_eval[n_done] <= tb:
            _hermite_into(t, y, fy, tb, y1, f1, t_eval[n_done], y_eval, n_done)
            n_done += 1
        t = tb
        y[:] = y1
        fy[:] = f1
        for q in range(ng):
            phi[q] = phi1[q]
            psi[q] = psi1[q]
        if fired >= 0:
            break
    y_stop[:] = y
    counters[0] = steps
    counters[1] = nfev
    counters[2] = henon_steps
    counters[3] = bisections
    counters[4] = n_done
    counters[5] = n_hits
    return status, t, fired, step
