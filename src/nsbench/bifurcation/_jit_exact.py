"""Compiled closed-form arc of a linear mode: the ``exact`` integrator's algorithm in numba.

The flow is evaluated directly at any offset ``s`` from the arc start (never
chained), guards are bracketed by a scan at ``scan / fastest rate`` with the
derivative's sign change catching tangential touches (the logic of
:func:`nsbench.integrators._roots.first_zero`), and roots are refined by
Brent's method to a few ulps. Objectives are numbered: ``0 .. ng-1`` are the
mode's guards (signed by their expected sign), ``ng + k`` the state sections.
"""

from __future__ import annotations

import numba
import numpy as np

from nsbench.bifurcation._jit_model import guards_of, mode_index
from nsbench.problems.kernels import (
    guard_rate,
    guard_value,
    jit,
    linear_section_rate,
    linear_section_value,
    rhs,
    section_crossed,
)

_EPS = np.finfo(np.float64).eps
# hot helpers are inlined into their callers: a call boundary costs a reference
# count update per array of the flow table, more than the arithmetic itself
hot = numba.njit(cache=True, nogil=True, inline="always")
NFEV, NSTEPS, ROOTS = 0, 1, 2
FULL = -2  # arc stopped early: the section-hit buffer is full


@jit
def flow_start(ft, mi, t0, y0, p0, coef):
    """Particular-solution offset ``p0`` and modal coefficients ``coef`` of an arc from ``(t0, y0)``."""
    ns, nst = ft.ns[mi], ft.nst[mi]
    c0 = np.empty(4)
    for r in range(ns):
        acc = ft.b0s[mi, r]
        for c in range(nst):
            acc += ft.ask[mi, r, c] * y0[ft.stuck[mi, c]]
        c0[r] = ft.p1[mi, r] - acc
    for r in range(ns):
        acc = 0.0
        for c in range(ns):
            acc += ft.ainv[mi, r, c] * c0[c]
        p0[r] = acc
    forced = ft.scal[0] != 0.0
    rot = np.exp(1j * ft.scal[1] * t0) if forced else 0j
    d = np.empty(4)
    for r in range(ns):
        up0 = p0[r]
        if forced:
            up0 += (ft.z[mi, r] * rot).real
        d[r] = y0[ft.slip[mi, r]] - up0
    for r in range(ns):
        acc = 0j
        for c in range(ns):
            acc += ft.vinv[mi, r, c] * d[c]
        coef[r] = acc


@hot
def flow_state(ft, mi, t0, y0, p0, coef, wc, s, out):
    """State at offset ``s`` from the arc start into ``out``."""
    v0 = ft.scal[2]
    for a in range(0, ft.nst[mi], 2):
        ix = ft.stuck[mi, a]
        out[ix] = y0[ix] + v0 * s
        out[ix + 1] = v0
    ns = ft.ns[mi]
    if ns == 0:
        return
    for c in range(ns):
        if ft.cw[mi, c] != 0.0:
            lam = ft.lam[mi, c]
            # exp of a complex number through real exp, cos, sin: faster than complex exp
            mag = ft.cw[mi, c] * np.exp(lam.real * s)
            ang = lam.imag * s
            wc[c] = coef[c] * complex(mag * np.cos(ang), mag * np.sin(ang))
    forced = ft.scal[0] != 0.0
    if forced:
        wt = ft.scal[1] * (t0 + s)
        rot_re, rot_im = np.cos(wt), np.sin(wt)
    for r in range(ns):
        u = p0[r] + ft.p1[mi, r] * s
        if forced:
            zr = ft.z[mi, r]
            u += zr.real * rot_re - zr.imag * rot_im
        acc = 0.0
        for c in range(ns):
            if ft.cw[mi, c] != 0.0:
                v = ft.vec[mi, r, c]
                w = wc[c]
                acc += v.real * w.real - v.imag * w.imag
        out[ft.slip[mi, r]] = u + acc


@jit
def objective(cx, obj, deriv, s, cnt):
    """Signed guard (``obj < ng``) or section value at offset ``s``; its time derivative if ``deriv``."""
    p, ft, mi, mode, t0, y0, p0, coef, wc, gk, gb, gs, ng, sc, sl, ys, dys = cx
    flow_state(ft, mi, t0, y0, p0, coef, wc, s, ys)
    cnt[NFEV] += 1
    t = t0 + s
    if deriv:
        rhs(p, mode, t, ys, dys)
        if obj < ng:
            return gs[obj] * guard_rate(p, gk[obj], gb[obj], t, ys, dys)
        return linear_section_rate(sc[obj - ng], dys)
    if obj < ng:
        return gs[obj] * guard_value(p, gk[obj], gb[obj], t, ys)
    return linear_section_value(sc[obj - ng], sl[obj - ng], ys)


@jit
def brent(cx, obj, deriv, a, b, cnt):
    """Root of the objective in ``[a, b]`` where it changes sign (Brent's method, a few ulps)."""
    fa = objective(cx, obj, deriv, a, cnt)
    fb = objective(cx, obj, deriv, b, cnt)
    if fa == 0.0:
        return a
    if fb == 0.0:
        return b
    c, fc = a, fa
    d = e = b - a
    for _ in range(200):
        if (fb > 0.0) == (fc > 0.0):
            c, fc = a, fa
            d = e = b - a
        if abs(fc) < abs(fb):
            a, fa = b, fb
            b, fb = c, fc
            c, fc = a, fa
        tol = 4.0 * _EPS * abs(b) + 1e-300
        m = 0.5 * (c - b)
        if abs(m) <= tol or fb == 0.0:
            return b
        if abs(e) >= tol and abs(fa) > abs(fb):
            r3 = fb / fa
            if a == c:
                pp = 2.0 * m * r3
                qq = 1.0 - r3
            else:
                q1 = fa / fc
                r1 = fb / fc
                pp = r3 * (2.0 * m * q1 * (q1 - r1) - (b - a) * (r1 - 1.0))
                qq = (q1 - 1.0) * (r1 - 1.0) * (r3 - 1.0)
            if pp > 0.0:
                qq = -qq
            else:
                pp = -pp
            if 2.0 * pp < min(3.0 * m * qq - abs(tol * qq), abs(e * qq)):
                e = d
                d = pp / qq
            else:
                d = m
                e = m
        else:
            d = m
            e = m
        a, fa = b, fb
        b = b + (d if abs(d) > tol else (tol if m > 0.0 else -tol))
        fb = objective(cx, obj, deriv, b, cnt)
    return b


@jit
def first_zero_inside(cx, obj, a, b, phi_a, phi_b, psi_a, psi_b, cnt):
    """First zero of the signed objective in ``(a, b]`` (``phi_a > 0``), or NaN; touches included."""
    if phi_a <= 0.0:
        return a
    if phi_b <= 0.0:
        return brent(cx, obj, False, a, b, cnt)
    if psi_a < 0.0 < psi_b:
        s_min = brent(cx, obj, True, a, b, cnt)
        phi_min = objective(cx, obj, False, s_min, cnt)
        if phi_min <= 0.0:
            return s_min if phi_min == 0.0 else brent(cx, obj, False, a, s_min, cnt)
    return np.nan


@jit
def first_zero(cx, obj, a, b, phi_a, phi_b, psi_a, psi_b, start, cnt):
    """:func:`nsbench.integrators._roots.first_zero` compiled (NaN for ``None``)."""
    if phi_a > 0.0 or not start:
        return first_zero_inside(cx, obj, a, b, phi_a, phi_b, psi_a, psi_b, cnt)
    if psi_a > 0.0 and psi_b < 0.0:
        s_max = brent(cx, obj, True, a, b, cnt)
        if objective(cx, obj, False, s_max, cnt) > 0.0:
            return brent(cx, obj, False, s_max, b, cnt) if phi_b <= 0.0 else np.nan
    elif psi_a > 0.0 and phi_b > 0.0:
        return np.nan
    # ambiguous start interval: sample 16 sub-intervals
    n = 16
    prev_s, prev_v, prev_r = a, 0.0, 0.0
    positive = False
    for j in range(n + 1):
        sj = a + (b - a) * j / n
        vj = objective(cx, obj, False, sj, cnt)
        rj = objective(cx, obj, True, sj, cnt)
        if positive:
            hit = first_zero_inside(cx, obj, prev_s, sj, prev_v, vj, prev_r, rj, cnt)
            if not np.isnan(hit):
                return hit
        elif vj > 0.0:
            positive = True
        prev_s, prev_v, prev_r = sj, vj, rj
    return a if not positive else np.nan


@jit
def exact_arc(p, ft, mode, t0, y0, t_end, scan, max_scan, sc, sl, sd, t_eval, i_eval, y_eval,
              hit_t, hit_y, hit_k, max_hits, t_rec, y_out, cnt):
    """Integrate one frozen mode from ``(t0, y0)`` to its first guard crossing or ``t_end``.

    Returns ``(t_stop, fired, i_eval, n_hits)``: ``fired`` is the guard index,
    -1 if ``t_end`` was reached, or ``FULL`` if ``max_hits`` section hits at
    ``t >= t_rec`` filled the buffer (the arc then stops at the last hit).
    States at ``t_eval[i_eval:] <= t_stop`` go to ``y_eval``; the stop state to ``y_out``.
    """
    n = y0.shape[0]
    mi = mode_index(mode)
    gk = np.empty(4, np.int64)
    gb = np.empty(4, np.int64)
    gs = np.empty(4, np.int64)
    ng = guards_of(mode, gk, gb, gs)
    nsec = sc.shape[0]
    p0 = np.zeros(4)
    coef = np.zeros(4, np.complex128)
    wc = np.zeros(4, np.complex128)
    flow_start(ft, mi, t0, y0, p0, coef)
    cx = (p, ft, mi, mode, t0, y0, p0, coef, wc, gk, gb, gs, ng, sc, sl, np.empty(n), np.empty(n))
    span = t_end - t0
    ds = min(max_scan, scan / max(ft.rate[mi], 1e-300))
    ya = np.empty(n)
    dya = np.empty(n)
    phi_a = np.empty(ng)
    psi_a = np.empty(ng)
    phi_b = np.empty(ng)
    psi_b = np.empty(ng)
    sec_a = np.empty(nsec)
    sec_b = np.empty(nsec)
    flow_state(ft, mi, t0, y0, p0, coef, wc, 0.0, ya)
    rhs(p, mode, t0, ya, dya)
    cnt[NFEV] += 1
    for q in range(ng):
        phi_a[q] = gs[q] * guard_value(p, gk[q], gb[q], t0, ya)
        psi_a[q] = gs[q] * guard_rate(p, gk[q], gb[q], t0, ya, dya)
    for k in range(nsec):
        sec_a[k] = linear_section_value(sc[k], sl[k], ya)
    s_a = 0.0
    fired = -1
    s_stop = span
    n_hits = 0
    while True:
        s_b = min(s_a + ds, span)
        t_b = t0 + s_b
        flow_state(ft, mi, t0, y0, p0, coef, wc, s_b, ya)
        rhs(p, mode, t_b, ya, dya)
        cnt[NFEV] += 1
        cnt[NSTEPS] += 1
        for q in range(ng):
            phi_b[q] = gs[q] * guard_value(p, gk[q], gb[q], t_b, ya)
            psi_b[q] = gs[q] * guard_rate(p, gk[q], gb[q], t_b, ya, dya)
        for k in range(nsec):
            sec_b[k] = linear_section_value(sc[k], sl[k], ya)
        best = np.inf
        bq = -1
        for q in range(ng):
            hit = first_zero(cx, q, s_a, s_b, phi_a[q], phi_b[q], psi_a[q], psi_b[q], s_a == 0.0, cnt)
            if not np.isnan(hit):
                cnt[ROOTS] += 1
                if hit < best:
                    best, bq = hit, q
        end = best if bq >= 0 else s_b
        for k in range(nsec):
            if s_a >= end:
                break
            right = min(s_b, end)
            v_right = sec_b[k] if right == s_b else objective(cx, ng + k, False, right, cnt)
            if section_crossed(sd[k], sec_a[k], v_right):
                root = right if v_right == 0.0 else brent(cx, ng + k, False, s_a, right, cnt)
                if t0 + root >= t_rec:
                    hit_t[n_hits] = t0 + root
                    hit_k[n_hits] = k
                    flow_state(ft, mi, t0, y0, p0, coef, wc, root, hit_y[n_hits])
                    n_hits += 1
                    if n_hits >= max_hits:
                        bq = -1
                        fired = -2
                        s_stop = root
                        break
        if fired == -2:
            break
        if bq >= 0:
            fired, s_stop = bq, best
            break
        if s_b >= span:
            break
        s_a = s_b
        for q in range(ng):
            phi_a[q] = phi_b[q]
            psi_a[q] = psi_b[q]
        for k in range(nsec):
            sec_a[k] = sec_b[k]
    t_stop = t0 + s_stop if fired != -1 else t_end
    flow_state(ft, mi, t0, y0, p0, coef, wc, s_stop, y_out)
    while i_eval < t_eval.shape[0] and t_eval[i_eval] <= t_stop:
        flow_state(ft, mi, t0, y0, p0, coef, wc, t_eval[i_eval] - t0, y_eval[i_eval])
        cnt[NFEV] += 1
        i_eval += 1
    return t_stop, fired, i_eval, n_hits
