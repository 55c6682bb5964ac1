"""Compiled fixed-step RK4 arc with Henon's trick on every surface (``henon-rk4`` in numba).

The algorithm of :class:`nsbench.integrators.henon_rk4.HenonRK4`, step for
step: the grid ``t0 + k h`` from the arc start, a guard crossed at a step end
is located by one RK4 step in ``sigma = guard`` back to the surface (old mode's
field, ``t`` carried as a state), a dip between step ends is caught from the
cubic Hermite interpolant of the guard, and bisection on RK4 sub-steps is the
fallback. Sections use the same Henon step; dense output is cubic Hermite.
"""

from __future__ import annotations

import math

import numpy as np

from nsbench.bifurcation._jit_exact import crossed
from nsbench.bifurcation._jit_model import guards_of
from nsbench.problems.kernels import (
    guard_rate,
    guard_value,
    jit,
    linear_section_rate,
    linear_section_value,
    rhs,
)

NFEV, NSTEPS, HENON, BISECT = 0, 1, 2, 3


@jit
def rk4_step(p, mode, t, y, h, fy, out, k2, k3, k4, tmp, cnt):
    """One classical RK4 step from ``(t, y)`` with ``fy`` known, into ``out`` (3 evaluations)."""
    n = y.shape[0]
    for j in range(n):
        tmp[j] = y[j] + 0.5 * h * fy[j]
    rhs(p, mode, t + 0.5 * h, tmp, k2)
    for j in range(n):
        tmp[j] = y[j] + 0.5 * h * k2[j]
    rhs(p, mode, t + 0.5 * h, tmp, k3)
    for j in range(n):
        tmp[j] = y[j] + h * k3[j]
    rhs(p, mode, t + h, tmp, k4)
    cnt[NFEV] += 3
    for j in range(n):
        out[j] = y[j] + (h / 6.0) * (fy[j] + 2.0 * k2[j] + 2.0 * k3[j] + k4[j])


@jit
def surf_value(p, sc, sl, typ, a, b, t, y):
    """Raw value of a surface: a guard ``(kind a, block b)`` if ``typ == 0``, else section ``a``."""
    if typ == 0:
        return guard_value(p, a, b, t, y)
    return linear_section_value(sc[a], sl[a], y)


@jit
def surf_rate(p, sc, typ, a, b, t, y, dy):
    if typ == 0:
        return guard_rate(p, a, b, t, y, dy)
    return linear_section_rate(sc[a], dy)


@jit
def hermite_dips(p0, p1, d0, d1, skip_start):
    """Whether the cubic with ends ``p0, p1`` and slopes ``d0, d1`` (per unit step) dips to <= 0."""
    a = 2.0 * p0 - 2.0 * p1 + d0 + d1
    b = -3.0 * p0 + 3.0 * p1 - 2.0 * d0 - d1
    roots = np.empty(2)
    nr = 0
    if a != 0.0:
        disc = 4.0 * b * b - 12.0 * a * d0
        if disc >= 0.0:
            sq = math.sqrt(disc)
            roots[0] = (-2.0 * b - sq) / (6.0 * a)
            roots[1] = (-2.0 * b + sq) / (6.0 * a)
            nr = 2
    elif b != 0.0:
        roots[0] = -d0 / (2.0 * b)
        nr = 1
    for j in range(nr):
        s = roots[j]
        if 0.0 < s < 1.0 and 6.0 * a * s + 2.0 * b > 0.0:
            if skip_start and s < 1e-6:
                continue
            if ((a * s + b) * s + d0) * s + p0 <= 0.0:
                return True
    return False


@jit
def henon(p, mode, sc, sl, typ, a, b, ta, tb, y1, t1, out, ws, cnt):
    """One RK4 step in ``sigma = surface`` from ``(t1, y1)`` back to the surface; its time or NaN."""
    n = y1.shape[0]
    cnt[HENON] += 1
    ky = ws[0:4]
    kt = np.empty(4)
    f = ws[4]
    tmp = ws[5]
    ds = -surf_value(p, sc, sl, typ, a, b, t1, y1)
    for stage in range(4):
        c = 0.0 if stage == 0 else (0.5 if stage < 3 else 1.0)
        if stage == 0:
            ts = t1
            for j in range(n):
                tmp[j] = y1[j]
        else:
            ts = t1 + c * ds * kt[stage - 1]
            for j in range(n):
                tmp[j] = y1[j] + c * ds * ky[stage - 1, j]
        rhs(p, mode, ts, tmp, f)
        cnt[NFEV] += 1
        rate = surf_rate(p, sc, typ, a, b, ts, tmp, f)
        if rate == 0.0 or not math.isfinite(rate):
            return np.nan
        for j in range(n):
            ky[stage, j] = f[j] / rate
        kt[stage] = 1.0 / rate
    t_star = t1 + ds / 6.0 * (kt[0] + 2.0 * kt[1] + 2.0 * kt[2] + kt[3])
    for j in range(n):
        out[j] = y1[j] + ds / 6.0 * (ky[0, j] + 2.0 * ky[1, j] + 2.0 * ky[2, j] + ky[3, j])
        if not math.isfinite(out[j]):
            return np.nan
    if not (ta < t_star <= tb):
        return np.nan
    return t_star


@jit
def bisect(p, mode, sc, sl, typ, a, b, sign, t, y, fy, t1, start, out, ws, cnt):
    """First zero of ``sign * surface`` in ``(t, t1]`` from RK4 sub-steps of ``(t, y)``; time or NaN."""
    cnt[BISECT] += 1
    ys = ws[5]
    k2, k3, k4, tmp = ws[0], ws[1], ws[2], ws[3]
    lo = t
    hi = np.nan
    positive_seen = not start
    for j in range(1, 9):
        tau = t + (t1 - t) * j / 8.0 if j < 8 else t1
        rk4_step(p, mode, t, y, tau - t, fy, ys, k2, k3, k4, tmp, cnt)
        value = sign * surf_value(p, sc, sl, typ, a, b, tau, ys)
        if value > 0.0:
            positive_seen = True
            lo = tau
        elif positive_seen:
            hi = tau
            out[:] = ys
            break
    if np.isnan(hi):
        return np.nan
    for _ in range(80):
        mid = 0.5 * (lo + hi)
        if mid <= lo or mid >= hi:
            break
        rk4_step(p, mode, t, y, mid - t, fy, ys, k2, k3, k4, tmp, cnt)
        if sign * surf_value(p, sc, sl, typ, a, b, mid, ys) > 0.0:
            lo = mid
        else:
            hi = mid
            out[:] = ys
    return hi


@jit
def hermite_into(ta, ya, fa, tb, yb, fb, t, out):
    """Cubic Hermite interpolant of a step at time ``t``."""
    h = tb - ta
    th = (t - ta) / h
    h00 = (1 + 2 * th) * (1 - th) ** 2
    h10 = th * (1 - th) ** 2
    h01 = th * th * (3 - 2 * th)
    h11 = th * th * (th - 1)
    for j in range(ya.shape[0]):
        out[j] = ya[j] * h00 + h * fa[j] * h10 + yb[j] * h01 + h * fb[j] * h11


@jit
def rk4_arc(p, mode, t0, y0, t_end, h, max_steps, sc, sl, sd, t_eval, i_eval, y_eval,
            hit_t, hit_y, hit_k, max_hits, t_rec, y_out, cnt):
    """Integrate one frozen mode by RK4 + Henon; same returns as :func:`exact_arc`.

    ``fired`` is also -3 on an exhausted step budget and -4 on a non-finite state.
    """
    n = y0.shape[0]
    gk = np.empty(4, np.int64)
    gb = np.empty(4, np.int64)
    gs = np.empty(4, np.int64)
    ng = guards_of(mode, gk, gb, gs)
    nsec = sc.shape[0]
    ws = np.empty((6, n))
    y = y0.copy()
    fy = np.empty(n)
    y1 = np.empty(n)
    f1 = np.empty(n)
    ystar = np.empty(n)
    ycand = np.empty(n)
    k2, k3, k4, tmp = np.empty(n), np.empty(n), np.empty(n), np.empty(n)
    rhs(p, mode, t0, y, fy)
    cnt[NFEV] += 1
    phi = np.empty(ng)
    psi = np.empty(ng)
    phi1 = np.empty(ng)
    psi1 = np.empty(ng)
    for q in range(ng):
        phi[q] = gs[q] * guard_value(p, gk[q], gb[q], t0, y)
        psi[q] = gs[q] * guard_rate(p, gk[q], gb[q], t0, y, fy)
    sec_val = np.empty(nsec)
    for k in range(nsec):
        sec_val[k] = linear_section_value(sc[k], sl[k], y)
    t = t0
    steps = 0
    fired = -1
    n_hits = 0
    n_left = max(1, math.ceil((t_end - t0) / h - 1e-9))
    while t < t_end:
        if steps >= max_steps:
            fired = -3
            break
        last = n_left <= 1
        t1 = t_end if last else t0 + (steps + 1) * h
        hk = t1 - t
        rk4_step(p, mode, t, y, hk, fy, y1, k2, k3, k4, tmp, cnt)
        rhs(p, mode, t1, y1, f1)
        cnt[NFEV] += 1
        steps += 1
        cnt[NSTEPS] += 1
        n_left -= 1
        finite = True
        for j in range(n):
            finite = finite and math.isfinite(y1[j])
        if not finite:
            fired = -4
            break
        start = t == t0
        best = np.inf
        bq = -1
        for q in range(ng):
            p1 = gs[q] * guard_value(p, gk[q], gb[q], t1, y1)
            d1 = gs[q] * guard_rate(p, gk[q], gb[q], t1, y1, f1)
            phi1[q] = p1
            psi1[q] = d1
            hit = p1 <= 0.0 or ((phi[q] > 0.0 or start)
                                and hermite_dips(phi[q], p1, hk * psi[q], hk * d1, start))
            if hit:
                ts = np.nan
                if p1 <= 0.0:
                    ts = henon(p, mode, sc, sl, 0, gk[q], gb[q], t, t1, y1, t1, ycand, ws, cnt)
                if np.isnan(ts):
                    ts = bisect(p, mode, sc, sl, 0, gk[q], gb[q], gs[q], t, y, fy, t1, start, ycand, ws, cnt)
                if not np.isnan(ts) and ts < best:
                    best, bq = ts, q
                    ystar[:] = ycand
        if bq >= 0:
            t_b = best
            y1[:] = ystar
            rhs(p, mode, t_b, y1, f1)
            cnt[NFEV] += 1
        else:
            t_b = t1
        # sections between (t, y) and (t_b, y1)
        for k in range(nsec):
            vb = linear_section_value(sc[k], sl[k], y1)
            if crossed(sd[k], sec_val[k], vb):
                if vb == 0.0:
                    ts = t_b
                    ycand[:] = y1
                else:
                    ts = henon(p, mode, sc, sl, 1, k, 0, t, t_b, y1, t_b, ycand, ws, cnt)
                    if np.isnan(ts):
                        sgn = 1.0 if sec_val[k] > 0 else -1.0
                        ts = bisect(p, mode, sc, sl, 1, k, 0, sgn, t, y, fy, t_b, False, ycand, ws, cnt)
                if not np.isnan(ts) and ts >= t_rec and n_hits < max_hits:
                    hit_t[n_hits] = ts
                    hit_k[n_hits] = k
                    hit_y[n_hits, :] = ycand
                    n_hits += 1
            sec_val[k] = vb
        while i_eval < t_eval.shape[0] and t_eval[i_eval] <= t_b:
            hermite_into(t, y, fy, t_b, y1, f1, t_eval[i_eval], y_eval[i_eval])
            i_eval += 1
        if nsec > 0 and n_hits >= max_hits and bq < 0:
            t = hit_t[n_hits - 1]
            y[:] = hit_y[n_hits - 1]
            fired = -2
            break
        t = t_b
        y[:] = y1
        fy[:] = f1
        if bq >= 0:
            fired = bq
            break
        for q in range(ng):
            phi[q] = phi1[q]
            psi[q] = psi1[q]
    y_out[:] = y
    return t, fired, i_eval, n_hits
