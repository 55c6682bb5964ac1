"""Double-double refinement of ``exact``'s mode tables and of every event it locates.

Why: on a periodic orbit every cycle repeats the same arithmetic, so the
rounding of the eigen-decomposition (a relative ``1e-16`` on an eigenvalue is a
phase error on every slip arc) does not average out: event times drift linearly,
2e-13 by ``tau = 300`` on the unforced 2-DOF case. The scan and the root are
found in double; then the root is polished by one Newton step whose residual,
the guard at the double root, is evaluated in double-double from
double-double eigen-data (refined once per mode here), and the state at the
event is evaluated there in double-double and rounded once. The matrix of a mode
holds doubles, taken as exact: they are the problem.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from nsbench.integrators import _double_double as dd
from nsbench.integrators._exact_layout import (
    C_C0,
    C_RES,
    N_V,
    STACK,
    V_DH,
    V_DL,
    V_P0,
    V_P0L,
    V_RH,
    V_RL,
    V_SCR,
    V_YH,
    V_YL,
    c_offsets,
    f_offsets,
    i_slip,
    i_stuck,
)
from nsbench.model.compile import hot, jit

#: Modes whose slipping sub-system is larger are not polished (their tables stay double).
MAX_POLISH = 24


@jit
def product_dd(a, x, scale):
    """``scale * (a @ x)`` of doubles in double-double, as ``(hi, lo)`` arrays (``scale`` a power of 2)."""
    rows = a.shape[0]
    hi = np.zeros(rows)
    lo = np.zeros(rows)
    for r in range(rows):
        sh, sl = 0.0, 0.0
        for c in range(x.shape[0]):
            ph, pl = dd.two_prod(a[r, c], x[c])
            sh, sl = dd.add(sh, sl, ph, pl)
        hi[r], lo[r] = scale * sh, scale * sl
    return hi, lo


@jit
def refine_eigenpairs(a, lam, vec, lam_lo, vec_lo):
    """One Newton step on each eigenpair of ``a`` with the residual ``a v - lam v`` in double-double.

    The component of largest modulus of each eigenvector is kept fixed. After the
    step ``lam + lam_lo`` and ``vec + vec_lo`` are eigenpairs to double-double
    accuracy (for a well-conditioned eigen-decomposition).
    """
    n = a.shape[0]
    for k in range(n):
        v = vec[:, k].copy()
        lk = lam[k]
        m = 0
        for i in range(n):
            if abs(v[i]) > abs(v[m]):
                m = i
        r = np.empty(n, np.complex128)
        for i in range(n):
            rh, rl, ih, il = 0.0, 0.0, 0.0, 0.0
            for j in range(n):
                ph, pl = dd.two_prod(a[i, j], v[j].real)
                rh, rl = dd.add(rh, rl, ph, pl)
                ph, pl = dd.two_prod(a[i, j], v[j].imag)
                ih, il = dd.add(ih, il, ph, pl)
            # minus lam v_i (complex product, each part exact in double-double)
            p1h, p1l = dd.two_prod(lk.real, v[i].real)
            p2h, p2l = dd.two_prod(lk.imag, v[i].imag)
            rh, rl = dd.add(rh, rl, -p1h, -p1l)
            rh, rl = dd.add(rh, rl, p2h, p2l)
            p1h, p1l = dd.two_prod(lk.real, v[i].imag)
            p2h, p2l = dd.two_prod(lk.imag, v[i].real)
            ih, il = dd.add(ih, il, -p1h, -p1l)
            ih, il = dd.add(ih, il, -p2h, -p2l)
            r[i] = complex(rh + rl, ih + il)
        mat = np.empty((n, n), np.complex128)
        for i in range(n):
            for j in range(n):
                mat[i, j] = a[i, j] - (lk if i == j else 0.0)
            mat[i, m] = -v[i]
        x = np.linalg.solve(mat, -r)
        lam_lo[k] = x[m]
        for i in range(n):
            vec_lo[i, k] = 0.0 if i == m else x[i]


@jit
def refine_linear(a, ainv, b_hi, b_lo, x, x_lo, r):
    """``x + x_lo`` solving ``a x = b`` (``b = b_hi + b_lo``) to double-double: one refinement step of ``x``.

    ``r`` is scratch of the size of ``x``.
    """
    n = x.shape[0]
    for i in range(n):
        sh, sl = dd.add(b_hi[i], b_lo[i], 0.0, 0.0)
        for j in range(n):
            ph, pl = dd.two_prod(a[i, j], x[j])
            sh, sl = dd.add(sh, sl, -ph, -pl)
        r[i] = sh + sl
    for i in range(n):
        acc = 0.0
        for j in range(n):
            acc += ainv[i, j] * r[j]
        x_lo[i] = acc


@jit
def refine_harmonic(a, w, z, b, z_lo):
    """``z + z_lo`` solving ``(i w I - a) z = b`` to double-double (one refinement step of ``z``)."""
    n = z.shape[0]
    r = np.empty(n, np.complex128)
    for i in range(n):
        rh, rl, ih, il = b[i].real, 0.0, b[i].imag, 0.0
        # - i w z_i = w z_i.imag - i w z_i.real
        ph, pl = dd.two_prod(w, z[i].imag)
        rh, rl = dd.add(rh, rl, ph, pl)
        ph, pl = dd.two_prod(w, z[i].real)
        ih, il = dd.add(ih, il, -ph, -pl)
        for j in range(n):
            ph, pl = dd.two_prod(a[i, j], z[j].real)
            rh, rl = dd.add(rh, rl, ph, pl)
            ph, pl = dd.two_prod(a[i, j], z[j].imag)
            ih, il = dd.add(ih, il, ph, pl)
        r[i] = complex(rh + rl, ih + il)
    mat = 1j * w * np.eye(n) - a.astype(np.complex128)
    dz = np.linalg.solve(mat, r)
    for i in range(n):
        z_lo[i] = dz[i]


class ArcMode(NamedTuple):
    """What the polish reads of an arc: the mode tables ``ti, tf, tc`` (row ``mi``), the arc's scratch ``wv,
    wc`` (complex vectors from row ``nqr``), the sizes (``ns`` slipping and ``nst`` stuck states, ``n``
    states, modes of size ``m``, at most ``g_max`` guards) and the forcing."""

    ti: np.ndarray
    tf: np.ndarray
    tc: np.ndarray
    wv: np.ndarray
    wc: np.ndarray
    nqr: int
    mi: int
    ns: int
    nst: int
    n: int
    m: int
    g_max: int
    forced: bool
    w: float


@hot
def polish_event(arc_mode, t0, t0_lo, y0, s0, fired, rate, y_out):
    """Polish the event of guard ``fired`` at offset ``s0`` of the arc from ``(t0 + t0_lo, y0)``.

    ``arc_mode`` (:class:`ArcMode`) holds the mode tables and the arc's scratch and sizes.

    ``ti, tf, tc`` are the mode tables (layout: :mod:`._exact_layout`), ``mi`` the
    mode's row (``n`` states, modes of size ``m``, at most ``g_max`` guards), ``wv, wc``
    the arc's scratch and ``rate`` the guard's (double) time derivative at ``s0``. Returns the Newton correction of ``s0``; the state at
    ``s0`` in double-double is left in rows ``V_YH`` (high) and ``V_YL`` (low) of
    ``wv``, and its rounding in ``y_out``.
    """
    ti, tf, tc, wv, wc, nqr, mi, ns, nst, n, m, g_max, forced, w = arc_mode
    n3 = n + 3
    f_cw, f_ainv, f_ask, f_ass, f_b0s, f_p1, f_p1lo, f_b0k, f_rate, f_q, f_aug, f_end = f_offsets(n, g_max)
    c_lam, c_lamlo, c_z, c_zlo, c_vec, c_veclo, c_vinv, c_end = c_offsets(n)
    o_slip, o_stuck = i_slip(m), i_stuck(m, n)
    q = f_q + fired * n3
    yh, yl, rh, rl, p0, p0_lo, dh, dl, scr = (
        wv[V_YH],
        wv[V_YL],
        wv[V_RH],
        wv[V_RL],
        wv[V_P0],
        wv[V_P0L],
        wv[V_DH],
        wv[V_DL],
        wv[V_SCR],
    )
    wp = wv[N_V + STACK :]
    c0, res = wc[nqr + C_C0], wc[nqr + C_RES]
    # the stuck states move at their constant rate (a block with the belt): y0 + b s, exactly in double-double
    for r in range(nst):
        ix = ti[mi, o_stuck + r]
        sh, sl = dd.two_prod(tf[mi, f_b0k + r], s0)
        yh[ix], yl[ix] = dd.add_d(sh, sl, y0[ix])
    # the forcing phase of the arc start, and the harmonic factor at s0
    r0, r1, r2, r3 = 1.0, 0.0, 0.0, 0.0
    e0, e1, e2, e3 = 1.0, 0.0, 0.0, 0.0
    if forced:
        ph, pl = dd.two_prod(w, t0)
        ph, pl = dd.add_d(ph, pl, w * t0_lo)
        wh, wl = dd.two_prod(w, s0)
        r0, r1, r2, r3, e0, e1, e2, e3 = dd.cos_sin2(ph, pl, wh, wl)  # in lockstep: the same doubles, sooner
    if ns > 0:
        # P0 = A_ss^-1 (P1 - A_sk y_k0 - b0_s) in double-double: the double solution, then one refinement
        for r in range(ns):
            ah, al = dd.add_d(tf[mi, f_p1 + r], tf[mi, f_p1lo + r], -tf[mi, f_b0s + r])
            for c in range(nst):
                ph, pl = dd.two_prod(tf[mi, f_ask + r * n + c], y0[ti[mi, o_stuck + c]])
                ah, al = dd.add(ah, al, -ph, -pl)
            rh[r], rl[r] = ah, al
        for r in range(ns):
            acc = 0.0
            for c in range(ns):
                acc += tf[mi, f_ainv + r * n + c] * (rh[c] + rl[c])
            p0[r] = acc
        for r in range(ns):  # the residual of A_ss P0 = rhs, in double-double
            ah, al = rh[r], rl[r]
            for c in range(ns):
                ph, pl = dd.two_prod(tf[mi, f_ass + r * n + c], p0[c])
                ah, al = dd.add(ah, al, -ph, -pl)
            scr[r] = ah + al
        for r in range(ns):
            acc = 0.0
            for c in range(ns):
                acc += tf[mi, f_ainv + r * n + c] * scr[c]
            p0_lo[r] = acc
        # harmonic part at the arc start: Zr = z rot; d = y0 - P0 - Re(Zr), in double-double
        for r in range(ns):
            ah, al = dd.add_d(-p0[r], -p0_lo[r], y0[ti[mi, o_slip + r]])
            wp[r, 0], wp[r, 1], wp[r, 2], wp[r, 3] = 0.0, 0.0, 0.0, 0.0
            if forced:
                zz, zl = tc[mi, c_z + r], tc[mi, c_zlo + r]
                a0, a1 = dd.add_d(zz.real, 0.0, zl.real)
                a2, a3 = dd.add_d(zz.imag, 0.0, zl.imag)
                wp[r, 0], wp[r, 1], wp[r, 2], wp[r, 3] = dd.cmul(a0, a1, a2, a3, r0, r1, r2, r3)
                ah, al = dd.add(ah, al, -wp[r, 0], -wp[r, 1])
            dh[r], dl[r] = ah, al
        # modal coefficients c = V^-1 d, refined once against V + V_lo
        for k in range(ns):
            acc = 0j
            for r in range(ns):
                acc += tc[mi, c_vinv + k * n + r] * (dh[r] + dl[r])
            c0[k] = acc
        for r in range(ns):
            xh, xl, ih, il = dh[r], dl[r], 0.0, 0.0
            for k in range(ns):
                v, vlo = tc[mi, c_vec + r * n + k], tc[mi, c_veclo + r * n + k]
                vh0, vl0 = dd.add_d(v.real, 0.0, vlo.real)
                vh1, vl1 = dd.add_d(v.imag, 0.0, vlo.imag)
                pr0, pr1, pr2, pr3 = dd.cmul(vh0, vl0, vh1, vl1, c0[k].real, 0.0, c0[k].imag, 0.0)
                xh, xl = dd.add(xh, xl, -pr0, -pr1)
                ih, il = dd.add(ih, il, -pr2, -pr3)
            res[r] = complex(xh + xl, ih + il)
        for k in range(ns):
            if tf[mi, f_cw + k] == 0.0:
                continue
            acc = 0j
            for r in range(ns):
                acc += tc[mi, c_vinv + k * n + r] * res[r]
            wp[k, 4], wp[k, 5] = dd.add_d(c0[k].real, 0.0, acc.real)
            wp[k, 6], wp[k, 7] = dd.add_d(c0[k].imag, 0.0, acc.imag)
            # lambda_k s0 in double-double (its exponential below)
            lk, lklo = tc[mi, c_lam + k], tc[mi, c_lamlo + k]
            lrh, lrl = dd.add_d(lk.real, 0.0, lklo.real)
            lih, lil = dd.add_d(lk.imag, 0.0, lklo.imag)
            wp[k, 8], wp[k, 9] = dd.mul_d(lrh, lrl, s0)
            wp[k, 10], wp[k, 11] = dd.mul_d(lih, lil, s0)
        # exp(lambda_k s0) in double-double, two at a time in lockstep (the same doubles as one by one)
        prev = -1
        for k in range(ns):
            if tf[mi, f_cw + k] == 0.0:
                continue
            if prev < 0:
                prev = k
                continue
            (
                wp[prev, 8],
                wp[prev, 9],
                wp[prev, 10],
                wp[prev, 11],
                wp[k, 8],
                wp[k, 9],
                wp[k, 10],
                wp[k, 11],
            ) = dd.cexp2(wp[prev, 8], wp[prev, 9], wp[prev, 10], wp[prev, 11], wp[k, 8], wp[k, 9], wp[k, 10], wp[k, 11])
            prev = -1
        if prev >= 0:
            wp[prev, 8], wp[prev, 9], wp[prev, 10], wp[prev, 11] = dd.cexp(
                wp[prev, 8], wp[prev, 9], wp[prev, 10], wp[prev, 11]
            )
        for r in range(ns):
            mh, ml = dd.mul_d(tf[mi, f_p1 + r], tf[mi, f_p1lo + r], s0)
            ah, al = dd.add(p0[r], p0_lo[r], mh, ml)
            if forced:
                h0, h1, h2, h3 = dd.cmul(wp[r, 0], wp[r, 1], wp[r, 2], wp[r, 3], e0, e1, e2, e3)
                ah, al = dd.add(ah, al, h0, h1)
            for k in range(ns):
                cwk = tf[mi, f_cw + k]
                if cwk != 0.0:
                    v, vlo = tc[mi, c_vec + r * n + k], tc[mi, c_veclo + r * n + k]
                    vh0, vl0 = dd.add_d(v.real, 0.0, vlo.real)
                    vh1, vl1 = dd.add_d(v.imag, 0.0, vlo.imag)
                    b0, b1, b2, b3 = dd.cmul(vh0, vl0, vh1, vl1, wp[k, 4], wp[k, 5], wp[k, 6], wp[k, 7])
                    f0, f1, f2, f3 = dd.cmul(b0, b1, b2, b3, wp[k, 8], wp[k, 9], wp[k, 10], wp[k, 11])
                    ah, al = dd.add(ah, al, cwk * f0, cwk * f1)
            i = ti[mi, o_slip + r]
            yh[i], yl[i] = ah, al
    # the guard in double-double, and its Newton correction
    gh, gl = tf[mi, q + n], 0.0
    for i in range(n):
        ph, pl = dd.mul_d(yh[i], yl[i], tf[mi, q + i])
        gh, gl = dd.add(gh, gl, ph, pl)
    qc, qs = tf[mi, q + n + 1], tf[mi, q + n + 2]
    if forced and (qc != 0.0 or qs != 0.0):
        c0h, c0l, s0h, s0l = dd.cmul(r0, r1, r2, r3, e0, e1, e2, e3)
        ph, pl = dd.mul_d(c0h, c0l, qc)
        gh, gl = dd.add(gh, gl, ph, pl)
        ph, pl = dd.mul_d(s0h, s0l, qs)
        gh, gl = dd.add(gh, gl, ph, pl)
    elif qc != 0.0:
        gh, gl = dd.add_d(gh, gl, qc)  # a constant force (w = 0): cos 0 = 1
    for i in range(n):
        y_out[i] = yh[i] + yl[i]
    return -(gh + gl) / rate if rate != 0.0 else 0.0
