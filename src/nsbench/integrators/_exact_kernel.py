"""Compiled arc kernel of ``exact``: the closed-form flow of one linear mode and its guard roots.

Within an arc of a mode that starts at ``(t0, y0)`` the state is, exactly,

    y(s) = a0 + a1 s + Re(A e^{i w s}) + sum_k Re(B_k e^{lambda_k s})

(stuck blocks move with the belt; the slipping ones are a particular solution,
polynomial plus harmonic, and the modes of the slipping sub-system). Every guard
and every linear section is a fixed row ``q`` applied to ``[y, 1, cos w t, sin w t]``,
so it has the same *modal form*

    g(s) = G0 + G1 s + Re(GA e^{i w s}) + sum_k Re(GB_k e^{lambda_k s}),

computed once per arc. A scan step then costs one complex exponential per
(pair of) eigenvalue(s) shared by all guards, and ``g''`` is bounded on any
interval by ``M = w^2 |GA| + sum_k |lambda_k|^2 |GB_k| max |e^{lambda_k s}|``. That
bound decides, rigorously up to rounding, that a guard cannot reach zero between
two scan points; only intervals it cannot clear are subdivided, and only at the
finest level is a tangential touch looked for through the sign change of ``g'``
(Brent on the derivative). So no crossing between samples is missed, and grazing
costs work only where it happens. Roots are found by Newton's method kept inside
the bracket, then polished in double-double (:mod:`._exact_polish`): on a
periodic orbit every cycle repeats the same rounding, so without it event times
drift linearly.

Event times are carried in compensated form (``t0 + t0_lo``); the forcing phase
of an arc is taken from that sum, since near resonance ``|A|`` exceeds the state
and a phase error of one ulp of ``t`` would cost ``|A| ulp(t)``.

A mode whose eigenvectors are ill-conditioned (defective: critical damping, a
Jordan block), whose matrix is singular (a free flight) or whose harmonic response
is singular (undamped resonance) has no usable modal form; its flow is the matrix
exponential of the augmented system ``z' = M z``, ``z = [y, 1, cos w t, sin w t]``,
evaluated directly at each offset. Its curvature bound comes from the nonnegative
majorant ``P`` of ``M`` (:func:`_majorant_exp`): ``|z|`` grows by at most
``exp(P h)`` over a step of length ``h``, so ``|g''| = |q M^2 z|`` is bounded there,
and the scan clears and halves intervals as for the modal form.

The tables of each mode (layout: :mod:`._exact_layout`) are built in Python on
the first visit of the mode (:mod:`nsbench.integrators.exact`): the kernel
returns ``K_NEED_MODE`` and the loop resumes once they exist.
"""

from __future__ import annotations

import numpy as np

from nsbench.integrators import _double_double as dd
from nsbench.integrators._exact_layout import (
    C_AW,
    C_COEF,
    C_E,
    C_EA,
    C_EB,
    I_DEFECTIVE,
    I_MODE,
    I_NS,
    I_NST,
    I_POLISH,
    I_READY,
    N_V,
    S_FORCED,
    S_G,
    S_W,
    V_A0,
    V_A1,
    V_FA,
    V_FB,
    V_LAM,
    V_MA,
    V_MB,
    V_PA,
    V_PB,
    V_RHS,
    V_SG,
    V_Y,
    V_YH,
    V_YL,
    V_Z0,
    V_ZA,
    V_ZB,
    V_ZM,
    V_ZS,
    W_MAJOR,
    W_MAJOR_EXP,
    c_offsets,
    f_offsets,
    i_slip,
    i_stuck,
)
from nsbench.integrators._exact_polish import ArcMode, polish_event
from nsbench.model.abi import (
    K_BUDGET,
    K_FAIL,
    K_HIT_FULL,
    K_HIT_STOP,
    K_NEED_MODE,
    K_NONFINITE,
    K_OK,
    NFEV,
    NSTEPS,
    SI_IEVAL,
    SI_NHITS,
    X0,
    X1,
    X2,
)
from nsbench.model.compile import hot, inline, small
from nsbench.model.law import rhs
from nsbench.model.records import copy_into, record_hit, section_crossed, sort_hits

_EPS = np.finfo(np.float64).eps
ROOTS, EXPM_ARCS, POLISHED = X0, X1, X2  # counter slots of this kernel
K_SCRATCH = K_FAIL  # the scratch arrays are too small for the run's sections (a bug: they are sized first)
#: The options vector ``fo``: the scan step as a fraction of the mode's fastest time scale, its largest value.
OPTIONS = ("scan", "max_scan")
O_SCAN, O_MAX_SCAN = range(len(OPTIONS))
V_MS = 23  # scratch magnitudes of the objective evaluations (the scan keeps V_MA, V_MB)
#: Defective modes: the most the majorant may grow ``|z|`` over one scan step (:func:`_majorant_exp`); the
#: step is halved until it does not. About ``e^2``: the bound on ``g''`` then exceeds it by a small factor.
MAJORANT_GROWTH = 8.0


# --------------------------------------------------------------------- mode lookup
@hot
def mode_hash(mode):
    """A 64-bit hash of a mode (wrapping arithmetic; collisions are resolved by comparison)."""
    h = np.uint64(1469598103934665603)
    for i in range(mode.shape[0]):
        h = (h ^ np.uint64(mode[i] + 2)) * np.uint64(1099511628211)
    return h


@hot
def find_mode(keys, slots, ti, mode):
    """Row of ``mode`` in the tables (-1 if absent)."""
    cap = keys.shape[0]
    h = mode_hash(mode)
    j = np.int64(h % np.uint64(cap))
    nb = mode.shape[0]
    for _ in range(cap):
        s = slots[j]
        if s < 0:
            return -1
        if keys[j] == h:
            same = True
            for i in range(nb):
                if ti[s, I_MODE + i] != mode[i]:
                    same = False
                    break
            if same:
                return s
        j = (j + 1) % cap
    return -1


@hot
def insert_mode(keys, slots, ti, mode, slot):
    """Enter ``mode`` at row ``slot`` (the index must have a free place)."""
    cap = keys.shape[0]
    h = mode_hash(mode)
    j = np.int64(h % np.uint64(cap))
    while slots[j] >= 0:
        j = (j + 1) % cap
    keys[j] = h
    slots[j] = slot
    for i in range(mode.shape[0]):
        ti[slot, I_MODE + i] = mode[i]


# --------------------------------------------------------------------- modal form
@inline
def _exps(tf, tc, mi, ns, w, s, E, mag):
    """``E[k] = exp(lambda_k s)`` (one of each conjugate pair), ``E[ns] = exp(i w s)``; ``mag[k] = |E[k]|``."""
    for k in range(ns):
        if tf[mi, k] != 0.0:  # the pair weight cw_k (offset 0)
            lk = tc[mi, k]
            m = np.exp(lk.real * s)
            mag[k] = m
            E[k] = complex(m * np.cos(lk.imag * s), m * np.sin(lk.imag * s))
    E[ns] = complex(np.cos(w * s), np.sin(w * s))


@inline
def _value_rate(wr, wc, tf, tc, mi, j, ns, w, s, E):
    """``g_j(s)`` and ``g_j'(s)`` from the modal form, with ``E`` the exponentials at ``s``."""
    g1 = wr[j, 1]
    gv = wr[j, 0] + g1 * s
    gr = g1
    ga = wc[j, ns] * E[ns]
    gv += ga.real
    gr -= w * ga.imag
    for k in range(ns):
        cwk = tf[mi, k]
        if cwk != 0.0:
            term = wc[j, k] * E[k]
            gv += cwk * term.real
            gr += cwk * (tc[mi, k] * term).real
    return gv, gr


@inline
def _curvature(wr, tf, mi, j, ns, n, ma, mb):
    """A bound on ``|g_j''|`` over an interval whose end magnitudes ``|exp(lambda_k s)|`` are ``ma``, ``mb``."""
    m = wr[j, 3]
    base = 4 + n + 3
    for k in range(ns):
        if tf[mi, k] != 0.0:
            m += wr[j, base + k] * max(ma[k], mb[k])
    return 1.01 * m + 1e-300


@small
def _lower_bound(fa, pa, fb, pb, h, m):
    """A lower bound of ``f`` on ``[a, a + h]`` from its end values and slopes and ``|f''| <= m``.

    ``f >= fa + pa u - m u^2 / 2`` and ``f >= fb - pb (h - u) - m (h - u)^2 / 2``;
    the larger of two concave bounds is least at an end or where they cross
    (their difference is linear in ``u``). Without a bound (``m`` infinite or NaN) there is
    none: ``-inf`` (the ends alone say nothing of the interval between them).
    """
    if not m < np.inf:
        return -np.inf
    best = min(max(fa, fb - pb * h - 0.5 * m * h * h), max(fa + pa * h - 0.5 * m * h * h, fb))
    den = pb - pa + m * h
    if den > 0.0:
        u = (fa - fb + pb * h + 0.5 * m * h * h) / den
        if 0.0 < u < h:
            best = min(best, fa + pa * u - 0.5 * m * u * u)
    return best


# --------------------------------------------------------------------- the objective
# ``cx = (wr, wc, wv, tf, tc, cnt, (mi, ns, n, nq, defective, aug_offset), w, wm)``: the arc's context.
@hot
def _objective(cx, j, s, deriv):
    """Signed guard ``j`` (or section ``j - ng``) at offset ``s``, or its derivative; one evaluation."""
    wr, wc, wv, tf, tc, cnt, ints, w, wm = cx
    mi, ns, n, nq, defective, aug_o = ints
    cnt[NFEV] += 1
    sgn = wv[V_SG, j]
    if defective:
        _augmented_state(tf, wm, mi, aug_o, n + 3, wv[V_Z0], s, wv[V_ZS])
        zs = wv[V_ZS]
        n3 = n + 3
        acc = 0.0
        for a in range(n3):
            if deriv:
                da = 0.0
                for b in range(n3):
                    da += tf[mi, aug_o + a * n3 + b] * zs[b]
                acc += wr[j, 4 + a] * da
            else:
                acc += wr[j, 4 + a] * zs[a]
        return sgn * acc
    E = wc[nq + C_E]
    _exps(tf, tc, mi, ns, w, s, E, wv[V_MS])
    gv, gr = _value_rate(wr, wc, tf, tc, mi, j, ns, w, s, E)
    return sgn * (gr if deriv else gv)


@hot
def _brent(cx, j, deriv, a, b, fa, fb):
    """Root of the objective (or of its derivative) in ``[a, b]`` where it changes sign, to a few ulps."""
    if fa == 0.0:
        return a
    if fb == 0.0:
        return b
    if (fa > 0.0) == (fb > 0.0):  # rounding noise at an end: the end closer to zero
        return a if abs(fa) <= abs(fb) else b
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
        tol = 2.0 * _EPS * abs(b) + 1e-300
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
        fb = _objective(cx, j, b, deriv)
    return b


@hot
def _root(cx, j, a, b, fa, fb):
    """Zero of the objective in ``[a, b]`` with ``fa > 0 >= fb``: Newton on the modal form, kept in the bracket."""
    wr, wc, wv, tf, tc, cnt, ints, w, wm = cx
    mi, ns, n, nq, defective, aug_o = ints
    if defective:
        return _brent(cx, j, False, a, b, fa, fb)
    if fb == 0.0:
        return b
    E = wc[nq + C_E]
    mag = wv[V_MS]
    sgn = wv[V_SG, j]
    lo, hi = a, b
    x = a + (b - a) * fa / (fa - fb)  # secant start
    for _ in range(100):
        _exps(tf, tc, mi, ns, w, x, E, mag)
        gv, gr = _value_rate(wr, wc, tf, tc, mi, j, ns, w, x, E)
        cnt[NFEV] += 1
        f, d = sgn * gv, sgn * gr
        if f == 0.0:
            return x
        if f > 0.0:
            lo = x
        else:
            hi = x
        step = f / d if d != 0.0 else np.inf
        xn = x - step
        if not (lo <= xn <= hi):
            xn = 0.5 * (lo + hi)
            if xn == lo or xn == hi:
                return hi
        elif abs(step) <= 4.0 * _EPS * abs(x):
            return xn
        x = xn
    return x


@hot
def _touch(cx, j, a, b, fa, pa, fb, pb):
    """First zero in ``(a, b]`` of a short interval with ``fa > 0``: a crossing, or a touch through ``g'``."""
    if fb <= 0.0:
        return _root(cx, j, a, b, fa, fb)
    if pa < 0.0 < pb:
        s_min = _brent(cx, j, True, a, b, pa, pb)
        f_min = _objective(cx, j, s_min, False)
        if f_min <= 0.0:
            return s_min if f_min == 0.0 else _root(cx, j, a, s_min, fa, f_min)
    return np.nan


@hot
def _first_zero(cx, j, a, b, fa, pa, fb, pb, m, tol):
    """First ``s`` in ``(a, b]`` where the signed guard ``j`` (positive at ``a``) reaches zero, or NaN.

    ``m`` bounds ``|g''|`` on ``[a, b]`` (so on every part of it): from the modal form,
    or for a defective mode from the majorant of its augmented flow (:func:`_majorant_exp`);
    ``inf`` means no bound (the majorant overflowed: the derivative test alone decides).
    Intervals the bound cannot clear are halved, leftmost first, so the zero found is
    the first one.
    """
    if not np.isfinite(m):
        return _touch(cx, j, a, b, fa, pa, fb, pb)
    wr, wc, wv, tf, tc, cnt, ints, w, wm = cx
    mi, ns, n, nq, defective, aug_o = ints
    stack = wv[N_V:]
    depth = stack.shape[0] - n  # the last n rows hold the polish's scratch
    E = wc[nq + C_E]
    sgn = wv[V_SG, j]
    min_width = (b - a) * 2.0**-26
    stack[0, 0], stack[0, 1], stack[0, 2], stack[0, 3], stack[0, 4], stack[0, 5] = a, b, fa, pa, fb, pb
    top = 1
    while top > 0:
        top -= 1
        a, b, fa, pa, fb, pb = (
            stack[top, 0],
            stack[top, 1],
            stack[top, 2],
            stack[top, 3],
            stack[top, 4],
            stack[top, 5],
        )
        h = b - a
        if fb <= 0.0 and pa + pb + m * h < 0.0:
            return _root(cx, j, a, b, fa, fb)  # g' < 0 throughout: the only zero
        if fb > 0.0 and _lower_bound(fa, pa, fb, pb, h, m) > tol:
            continue
        if h <= min_width or top + 2 > depth:
            hit = _touch(cx, j, a, b, fa, pa, fb, pb)
            if not np.isnan(hit):
                return hit
            continue
        mid = a + 0.5 * h
        if defective:
            _augmented_state(tf, wm, mi, aug_o, n + 3, wv[V_Z0], mid, wv[V_ZS])
            gv, gr = _aug_value_rate(tf, mi, aug_o, n + 3, wr, j, wv[V_ZS])
        else:
            _exps(tf, tc, mi, ns, w, mid, E, wv[V_MS])
            gv, gr = _value_rate(wr, wc, tf, tc, mi, j, ns, w, mid, E)
        cnt[NFEV] += 1
        fm, pm = sgn * gv, sgn * gr
        if fm > 0.0:  # the right half waits below the left half
            stack[top, 0], stack[top, 1], stack[top, 2], stack[top, 3], stack[top, 4], stack[top, 5] = (
                mid,
                b,
                fm,
                pm,
                fb,
                pb,
            )
            top += 1
        stack[top, 0], stack[top, 1], stack[top, 2], stack[top, 3], stack[top, 4], stack[top, 5] = (
            a,
            mid,
            fa,
            pa,
            fm,
            pm,
        )
        top += 1
    return np.nan


@hot
def _fresh_start(cx, j, b, fb, pb, pa, m, tol):
    """First zero in ``(0, b]`` of a guard that starts on its own surface (``g(0) = 0``), or NaN.

    If ``g'(0) > 0`` the guard stays positive on ``(0, u]`` with ``u = g'(0) / M``
    (Taylor with the curvature bound); from there the ordinary search applies,
    provided ``g(u)`` stands above the rounding of the guard (``tol``). Otherwise
    (a start at rounding level, e.g. kinetic friction equal to static: value and
    rate both zero in exact arithmetic) the guard's computed values near 0 are
    rounding noise of either sign, and a zero found there is none (it logged a
    spurious ``reverse`` 1e-12..1e-8 after a breakaway). So the rule of
    docs/model.md: sample the interval; the first sample that leaves the rounding
    band decides. Above it, the phase goes on and zeros are searched from there;
    below it (the wrong side by more than rounding), or never out of the band,
    the phase ends at once (zero length, left to the settle rules).
    """
    if pa > 0.0 and np.isfinite(m):
        u = pa / m
        if u >= b:
            return np.nan if fb > 0.0 else _root(cx, j, 0.5 * b, b, _objective(cx, j, 0.5 * b, False), fb)
        fu = _objective(cx, j, u, False)
        if fu > tol:
            return _first_zero(cx, j, u, b, fu, _objective(cx, j, u, True), fb, pb, m, tol)
    n = 16
    if pa > 0.0 and not np.isfinite(m):
        # A defective mode leaving its surface (g' > 0) but back across it before the first sample (a
        # short flight): look closer to the start for the guard's positive side, then bracket from there.
        first = b / n
        v1 = _objective(cx, j, first, False)
        if v1 <= 0.0:
            u = 0.5 * first
            for _ in range(60):
                fu = _objective(cx, j, u, False)
                if fu > tol:  # out of the rounding band, as below
                    return _root(cx, j, u, first, fu, v1)
                u *= 0.5
    prev_s, prev_v, prev_r = 0.0, 0.0, pa
    positive = False
    for k in range(1, n + 1):
        sk = b * k / n
        vk = _objective(cx, j, sk, False)
        rk = _objective(cx, j, sk, True)
        if positive:
            hit = _first_zero(cx, j, prev_s, sk, prev_v, prev_r, vk, rk, m, tol)
            if not np.isnan(hit):
                return hit
        elif vk > tol:
            positive = True
        elif vk < -tol:
            return 0.0
        prev_s, prev_v, prev_r = sk, vk, rk
    return 0.0 if not positive else np.nan


# --------------------------------------------------------------------- augmented flow (defective modes)
@inline
def _aug_value_rate(tf, mi, off, n3, wr, j, zs):
    """Objective row ``j`` (unsigned) and its rate at the augmented state ``zs`` of a defective mode:
    ``q . z`` and ``q . M z`` (the sums in the order of :func:`_objective`)."""
    gv = 0.0
    gr = 0.0
    for a in range(n3):
        da = 0.0
        for b in range(n3):
            da += tf[mi, off + a * n3 + b] * zs[b]
        gr += wr[j, 4 + a] * da
        gv += wr[j, 4 + a] * zs[a]
    return gv, gr


@hot
def _majorant_exp(tf, wm, mi, off, n3, h):
    """``exp(P h)`` into ``wm[W_MAJOR_EXP]``, ``P`` the nonnegative majorant of the augmented matrix ``M``.

    ``P`` has ``max(M_aa, 0)`` on its diagonal and ``|M_ab|`` off it. For every
    ``0 <= u <= h``, ``|exp(M u)| <= exp(P h)`` entrywise: with ``c >= -min M_aa``,
    ``M + c I`` has a nonnegative diagonal, so ``|(M + c I)^k| <= (P + c I)^k``
    term by term of the series, hence ``|exp(M u)| <= exp(P u)``; and ``exp(P u)``,
    a series of nonnegative matrices, grows with ``u``. So ``|z(s + u)| <= exp(P h) |z(s)|``
    over a scan step, which bounds ``g''`` there (``g'' = q M^2 z``) whatever the
    conditioning of ``M``'s eigenvectors. The series has no cancellation (every term
    is nonnegative): it is summed to 24 terms after scaling ``P h`` to norm 1/2, then squared.
    """
    mp, out = wm[W_MAJOR], wm[W_MAJOR_EXP]
    norm = 0.0
    for a in range(n3):
        row = 0.0
        for b in range(n3):
            v = tf[mi, off + a * n3 + b]
            v = max(v, 0.0) if a == b else abs(v)
            mp[a, b] = v
            row += v
        norm = max(norm, row * h)
    squarings = 0
    while norm > 0.5 and squarings < 1000:
        norm *= 0.5
        squarings += 1
    scale = h / 2.0**squarings
    term, tmp = wm[1], wm[2]
    for a in range(n3):
        for b in range(n3):
            out[a, b] = 1.0 if a == b else 0.0
            term[a, b] = out[a, b]
    for k in range(1, 24):
        for a in range(n3):
            for b in range(n3):
                acc = 0.0
                for c in range(n3):
                    acc += term[a, c] * mp[c, b]
                tmp[a, b] = acc * scale / k
        for a in range(n3):
            for b in range(n3):
                term[a, b] = tmp[a, b]
                out[a, b] += tmp[a, b]
    for _ in range(squarings):
        for a in range(n3):
            for b in range(n3):
                acc = 0.0
                for c in range(n3):
                    acc += out[a, c] * out[c, b]
                tmp[a, b] = acc
        for a in range(n3):
            for b in range(n3):
                out[a, b] = tmp[a, b]


@inline
def _growth(wm, n3, z, zm):
    """``zm = exp(P h) |z|`` (:func:`_majorant_exp`); returns ``max(zm) / max(|z|)`` (1 for ``z = 0``)."""
    e = wm[W_MAJOR_EXP]
    top, start = 0.0, 0.0
    for a in range(n3):
        acc = 0.0
        for b in range(n3):
            acc += e[a, b] * abs(z[b])
        zm[a] = acc
        top = max(top, acc)
        start = max(start, abs(z[a]))
    return top / start if start > 0.0 else 1.0


@hot
def _augmented_state(tf, wm, mi, off, n3, z0, s, out):
    """``expm(M s) @ z0`` into ``out`` with ``M`` the mode's augmented matrix (Taylor series and squaring).

    ``wm`` holds three ``(n + 3) x (n + 3)`` scratch matrices.
    """
    norm = 0.0
    for a in range(n3):
        row = 0.0
        for b in range(n3):
            row += abs(tf[mi, off + a * n3 + b])
        norm = max(norm, row * abs(s))
    squarings = 0
    while norm > 0.5:
        norm *= 0.5
        squarings += 1
    scale = s / 2.0**squarings
    e, term, tmp = wm[0], wm[1], wm[2]
    for a in range(n3):
        for b in range(n3):
            e[a, b] = 1.0 if a == b else 0.0
            term[a, b] = e[a, b]
    for k in range(1, 24):
        for a in range(n3):
            for b in range(n3):
                acc = 0.0
                for c in range(n3):
                    acc += term[a, c] * tf[mi, off + c * n3 + b]
                tmp[a, b] = acc * scale / k
        for a in range(n3):
            for b in range(n3):
                term[a, b] = tmp[a, b]
                e[a, b] += tmp[a, b]
    for _ in range(squarings):
        for a in range(n3):
            for b in range(n3):
                acc = 0.0
                for c in range(n3):
                    acc += e[a, c] * e[c, b]
                tmp[a, b] = acc
        for a in range(n3):
            for b in range(n3):
                e[a, b] = tmp[a, b]
    for a in range(n3):
        acc = 0.0
        for b in range(n3):
            acc += e[a, b] * z0[b]
        out[a] = acc


# --------------------------------------------------------------------- states
@hot
def _state(cx, y0, s, out):
    """The state at offset ``s`` into ``out`` (``y0`` itself at ``s = 0``): modal form or matrix exponential."""
    wr, wc, wv, tf, tc, cnt, ints, w, wm = cx
    mi, ns, n, nq, defective, aug_o = ints
    if s == 0.0:
        copy_into(out, y0)
        return
    if defective:
        _augmented_state(tf, wm, mi, aug_o, n + 3, wv[V_Z0], s, wv[V_ZS])
        for i in range(n):
            out[i] = wv[V_ZS, i]
        return
    E = wc[nq + C_E]
    _exps(tf, tc, mi, ns, w, s, E, wv[V_MS])
    aw = wc[nq + C_AW]
    b0 = nq + 8  # rows of B
    for i in range(n):
        v = wv[V_A0, i] + wv[V_A1, i] * s + (aw[i] * E[ns]).real
        for k in range(ns):
            cwk = tf[mi, k]
            if cwk != 0.0:
                v += cwk * (wc[b0 + i, k] * E[k]).real
        out[i] = v


@hot
def _dense(cx, y0, t_eval, y_eval, si, t0, t0_lo, t_stop, ybuf):
    """States at every requested time up to ``t_stop``."""
    i = si[SI_IEVAL]
    while i < t_eval.shape[0] and t_eval[i] <= t_stop:
        _state(cx, y0, max((t_eval[i] - t0) - t0_lo, 0.0), ybuf)
        copy_into(y_eval[i], ybuf)
        cx[5][NFEV] += 1
        i += 1
    si[SI_IEVAL] = i


# --------------------------------------------------------------------- the arc
@hot
def exact_arc(kd, fo, prob, arc, sec, hits, dense, si, y_out, cnt):
    """Integrate one linear mode from ``(t0 + t0_lo, y0)`` to its first guard zero or ``t_end``.

    Arguments and result: :mod:`nsbench.model.abi`; ``kd`` holds the mode tables
    (:func:`nsbench.integrators._exact_layout.kernel_data`). ``fo``: :data:`O_SCAN`, the
    scan step as a fraction of the mode's fastest time scale, and :data:`O_MAX_SCAN`, its
    largest value.
    """
    keys, slots, ti, tf, tc, scal, wr, wc, wv, wm = (
        kd.u1,
        kd.i1,
        kd.i2,
        kd.f2a,
        kd.c2a,
        kd.f1a,
        kd.f2b,
        kd.c2b,
        kd.f2c,
        kd.f3a,
    )
    mode, gs, ng = arc.mode, arc.guard_sign, arc.n_guards
    t0, t0_lo, y0, t_end, max_steps = arc.t0, arc.t0_lo, arc.y0, arc.t_end, arc.max_steps
    sc, sl, sd, hit_from, hit_stop = sec.coeffs, sec.levels, sec.directions, sec.hit_from, sec.hit_stop
    t_eval, y_eval = dense.t, dense.y
    mi = find_mode(keys, slots, ti, mode)
    if mi < 0 or ti[mi, I_READY] == 0:
        return K_NEED_MODE, t0, 0.0, -1
    n = y0.shape[0]
    m_size = mode.shape[0]
    n3 = n + 3
    nsec = sl.shape[0]
    nq = ng + nsec
    if nq > wr.shape[0]:  # cannot happen: the scratch is sized for the run's sections before it starts
        return K_SCRATCH, t0, 0.0, -1
    nqr = wr.shape[0]  # first complex vector row of wc
    ns, nst = ti[mi, I_NS], ti[mi, I_NST]
    defective = ti[mi, I_DEFECTIVE] != 0
    forced, w = scal[S_FORCED] != 0.0, scal[S_W]
    if not forced:
        w = 0.0
    g_max = int(scal[S_G])
    o_slip, o_stuck = i_slip(m_size), i_stuck(m_size, n)
    f_cw, f_ainv, f_ask, f_ass, f_b0s, f_p1, f_p1lo, f_b0k, f_rate, f_q, f_aug, f_end = f_offsets(n, g_max)
    c_lam, c_lamlo, c_z, c_zlo, c_vec, c_veclo, c_vinv, c_end = c_offsets(n)
    # the forcing phase at the exact start t0 + t0_lo, with the rounding of w t0 put back
    ph, ph_lo = dd.two_prod(w, t0)
    ph_lo += w * t0_lo
    c_ph = np.cos(ph) - np.sin(ph) * ph_lo
    s_ph = np.sin(ph) + np.cos(ph) * ph_lo
    rot = complex(c_ph, s_ph)
    # ---- the flow from this start: y(s) = a0 + a1 s + Re(Aw e^{iws}) + sum_k Re(B_k e^{lam_k s})
    a0, a1, sg = wv[V_A0], wv[V_A1], wv[V_SG]
    aw, coef, E = wc[nqr + C_AW], wc[nqr + C_COEF], wc[nqr + C_E]
    b0 = nqr + 8
    for i in range(n):
        a0[i] = 0.0
        a1[i] = 0.0
        aw[i] = 0j
    for r in range(nst):  # a stuck state moves at a constant rate (a block with the belt: v0, and v0 itself)
        ix = ti[mi, o_stuck + r]
        a0[ix] = y0[ix]
        a1[ix] = tf[mi, f_b0k + r]
    if ns > 0 and not defective:
        rhs0 = wv[V_RHS]
        for r in range(ns):  # P0 = A_ss^-1 (P1 - A_sk y_k0 - b0_s)
            acc = tf[mi, f_p1 + r] - tf[mi, f_b0s + r]
            for c in range(nst):
                acc -= tf[mi, f_ask + r * n + c] * y0[ti[mi, o_stuck + c]]
            rhs0[r] = acc
        for r in range(ns):
            acc = 0.0
            for c in range(ns):
                acc += tf[mi, f_ainv + r * n + c] * rhs0[c]
            sr = ti[mi, o_slip + r]
            a0[sr] = acc
            a1[sr] = tf[mi, f_p1 + r]
            zr = tc[mi, c_z + r] * rot if forced else 0j
            aw[sr] = zr
            coef[r] = y0[sr] - acc - zr.real  # the offset d; V^-1 d below
        for k in range(ns):
            acc = 0j
            for c in range(ns):
                acc += tc[mi, c_vinv + k * n + c] * coef[c]
            E[k] = acc
        for i in range(n):
            for k in range(ns):
                wc[b0 + i, k] = 0j
        for k in range(ns):
            for r in range(ns):
                wc[b0 + ti[mi, o_slip + r], k] = tc[mi, c_vec + r * n + k] * E[k]
    # ---- modal forms of the guards (rows of the mode's table) and of the sections
    q0 = 4
    cm0 = 4 + n3
    for j in range(nq):
        if j < ng:
            for a in range(n3):
                wr[j, q0 + a] = tf[mi, f_q + j * n3 + a]
            sg[j] = gs[j]
        else:
            for a in range(n):
                wr[j, q0 + a] = sc[j - ng, a]
            wr[j, q0 + n] = -sl[j - ng]
            wr[j, q0 + n + 1] = 0.0
            wr[j, q0 + n + 2] = 0.0
            sg[j] = 1.0
    if not defective:
        lam_abs = wv[V_LAM]  # |lambda_k|, once per arc rather than once per guard (a hypot each)
        for k in range(ns):
            if tf[mi, f_cw + k] != 0.0:
                lam_abs[k] = abs(tc[mi, c_lam + k])
        for j in range(nq):
            g0 = wr[j, q0 + n]
            g1 = 0.0
            ga = complex(wr[j, q0 + n + 1], -wr[j, q0 + n + 2]) * rot
            for i in range(n):
                qi = wr[j, q0 + i]
                g0 += qi * a0[i]
                g1 += qi * a1[i]
                ga += qi * aw[i]
            scale = abs(g0) + abs(ga)
            for k in range(ns):
                acc = 0j
                cwk = tf[mi, f_cw + k]
                if cwk != 0.0:
                    for i in range(n):
                        acc += wr[j, q0 + i] * wc[b0 + i, k]
                    lk = lam_abs[k]
                    a_abs = abs(acc)
                    wr[j, cm0 + k] = cwk * lk * lk * a_abs
                    scale += cwk * a_abs
                wc[j, k] = acc
            wc[j, ns] = ga
            wr[j, 0], wr[j, 1], wr[j, 2], wr[j, 3] = g0, g1, scale, w * w * abs(ga)
    else:
        cnt[EXPM_ARCS] += 1
        # g'' = q M^2 z: the row q M^2 of each guard (its entries' magnitudes, with the rounding of the
        # products added, so that |q M^2| |z| bounds the computed |g''|), the curvature weights of the scan
        qm = wv[V_ZM]
        for j in range(ng):
            for b in range(n3):
                acc = 0.0
                for a in range(n3):
                    acc += wr[j, q0 + a] * tf[mi, f_aug + a * n3 + b]
                qm[b] = acc
            for b in range(n3):
                acc = 0.0
                size = 0.0
                for a in range(n3):
                    mab = tf[mi, f_aug + a * n3 + b]
                    acc += qm[a] * mab
                    inner = 0.0
                    for c in range(n3):
                        inner += abs(wr[j, q0 + c] * tf[mi, f_aug + c * n3 + a])
                    size += inner * abs(mab)
                wr[j, cm0 + b] = abs(acc) + 4.0 * n3 * _EPS * size
    z0 = wv[V_Z0]
    for i in range(n):
        z0[i] = y0[i]
    z0[n], z0[n + 1], z0[n + 2] = 1.0, c_ph, s_ph
    cx = (wr, wc, wv, tf, tc, cnt, (mi, ns, n, nqr, defective, f_aug), w, wm)
    # ---- scan
    span = (t_end - t0) - t0_lo
    # Sections are found by sign changes between scan points, so the scan follows the fastest
    # time scale; guards alone are cleared by the curvature bound, which holds on any interval.
    scan = fo[O_SCAN] if nsec > 0 else 4.0 * fo[O_SCAN]
    ds = min(fo[O_MAX_SCAN], scan / max(tf[mi, f_rate], 1e-300))
    bounded = True  # a defective mode whose majorant is finite (else the derivative test alone decides)
    if defective:
        # The majorant bounds |z| over a step by exp(P ds) |z|: halve the step until that grows |z0|
        # by at most MAJORANT_GROWTH, so that the bound on g'' stays within a small factor of |g''|
        # (a non-normal M, whose entries exceed its eigenvalues, would otherwise need many halvings of
        # each step to clear it).
        za = wv[V_ZA]
        for i in range(n):
            za[i] = y0[i]
        za[n], za[n + 1], za[n + 2] = 1.0, c_ph, s_ph
        for _ in range(60):
            _majorant_exp(tf, wm, mi, f_aug, n3, ds)
            grow = _growth(wm, n3, za, wv[V_ZM])
            if not grow < np.inf:
                bounded = False
                break
            if grow <= MAJORANT_GROWTH:
                break
            ds *= 0.5
    fa, pa, fb, pb, ma, mb, ybuf = wv[V_FA], wv[V_PA], wv[V_FB], wv[V_PB], wv[V_MA], wv[V_MB], wv[V_Y, :n]
    Ea, Eb = wc[nqr + C_EA], wc[nqr + C_EB]
    _exps(tf, tc, mi, ns, w, 0.0, Ea, ma)
    for j in range(nq):  # at s = 0 from y0 itself: a phase starts exactly on its own surface
        acc = wr[j, q0 + n] + wr[j, q0 + n + 1] * c_ph + wr[j, q0 + n + 2] * s_ph
        for i in range(n):
            acc += wr[j, q0 + i] * y0[i]
        fa[j] = sg[j] * acc
        if defective:
            pa[j] = _objective(cx, j, 0.0, True)
        else:
            pa[j] = sg[j] * _value_rate(wr, wc, tf, tc, mi, j, ns, w, 0.0, Ea)[1]
    s_a = 0.0
    fired = -1
    s_stop = span
    status = K_OK
    steps = 0
    while s_a < span:
        if steps >= max_steps:
            status = K_BUDGET
            s_stop = s_a
            break
        s_b = min(s_a + ds, span)
        steps += 1
        if defective:
            zb = wv[V_ZB]
            _augmented_state(tf, wm, mi, f_aug, n3, z0, s_b, zb)
            cnt[NFEV] += 1
            for j in range(nq):
                gv, gr = _aug_value_rate(tf, mi, f_aug, n3, wr, j, zb)
                fb[j], pb[j] = sg[j] * gv, sg[j] * gr
            if bounded:
                grow = _growth(wm, n3, wv[V_ZA], wv[V_ZM])  # |z| <= zm over the step
                bounded = grow < np.inf
        else:
            _exps(tf, tc, mi, ns, w, s_b, Eb, mb)
            cnt[NFEV] += 1
            for j in range(nq):
                gv, gr = _value_rate(wr, wc, tf, tc, mi, j, ns, w, s_b, Eb)
                fb[j], pb[j] = sg[j] * gv, sg[j] * gr
        best = np.inf
        bq = -1
        for j in range(ng):
            if defective:
                # the rounding of the guard near the step's start (its terms there): a guard that starts on
                # its surface is judged at that scale, not at the step's far end (a short flight of a ball)
                m, size = 0.0, 0.0
                for a in range(n3):
                    m += wr[j, cm0 + a] * wv[V_ZM, a]
                    size += abs(wr[j, q0 + a] * wv[V_ZA, a])
                m = 1.01 * m + 1e-300 if bounded else np.inf
                tol = 16.0 * _EPS * size
            else:
                m = _curvature(wr, tf, mi, j, ns, n, ma, mb)
                tol = 16.0 * _EPS * (wr[j, 2] + abs(wr[j, 1]) * s_b)
            if s_a == 0.0 and abs(fa[j]) <= max(tol, 64.0 * _EPS):
                hit = _fresh_start(cx, j, s_b, fb[j], pb[j], pa[j], m, tol)
            elif fa[j] <= 0.0:
                hit = s_a
            elif fb[j] > 0.0 and _lower_bound(fa[j], pa[j], fb[j], pb[j], s_b - s_a, m) > tol:
                continue  # the common case, decided here without a call
            else:
                hit = _first_zero(cx, j, s_a, s_b, fa[j], pa[j], fb[j], pb[j], m, tol)
            if not np.isnan(hit):
                cnt[ROOTS] += 1
                if hit < best:  # earliest; the lowest index on a tie
                    best, bq = hit, j
        end = best if bq >= 0 else s_b
        # sections: sign changes on (s_a, end]
        first_new = si[SI_NHITS]
        for k in range(nsec):
            j = ng + k
            right_v = fb[j] if end == s_b else _objective(cx, j, end, False)
            if section_crossed(sd[k], fa[j], right_v):
                if right_v == 0.0:
                    root = end
                elif fa[j] > 0.0:
                    root = _root(cx, j, s_a, end, fa[j], right_v)
                else:  # a section's objective is unsigned: bracket it the other way round
                    sg[j] = -1.0
                    root = _root(cx, j, s_a, end, -fa[j], -right_v)
                    sg[j] = 1.0
                t_hit = t0 + (t0_lo + root)
                if t_hit >= hit_from:
                    if si[SI_NHITS] >= hits.t.shape[0]:
                        return K_HIT_FULL, t0, 0.0, -1
                    _state(cx, y0, root, ybuf)
                    record_hit(hits, si, k, t_hit, ybuf)
        if si[SI_NHITS] > first_new:
            sort_hits(hits, first_new, si[SI_NHITS])
            if 0 <= hit_stop <= si[SI_NHITS]:
                si[SI_NHITS] = hit_stop
                t_stop = hits.t[hit_stop - 1]
                copy_into(y_out, hits.y[hit_stop - 1])
                _dense(cx, y0, t_eval, y_eval, si, t0, t0_lo, t_stop, ybuf)
                cnt[NSTEPS] += steps
                return K_HIT_STOP, t_stop, 0.0, -1
        if bq >= 0:
            fired, s_stop = bq, best
            break
        s_a = s_b
        for j in range(nq):
            fa[j] = fb[j]
            pa[j] = pb[j]
        if defective:
            copy_into(wv[V_ZA, :n3], wv[V_ZB, :n3])
        for k in range(ns):
            ma[k] = mb[k]
            Ea[k] = Eb[k]
    cnt[NSTEPS] += steps
    _state(cx, y0, s_stop, y_out)
    cnt[NFEV] += 1
    delta = 0.0
    if fired >= 0 and ti[mi, I_POLISH] != 0:
        # Newton on the guard in double-double, then the state there (see _exact_polish)
        if defective or s_stop == 0.0:  # otherwise _state just left exp(lambda_k s_stop) in E
            _exps(tf, tc, mi, ns, w, s_stop, E, wv[V_MS])
        rate = _value_rate(wr, wc, tf, tc, mi, fired, ns, w, s_stop, E)[1]
        delta = polish_event(
            ArcMode(ti, tf, tc, wv, wc, nqr, mi, ns, nst, n, m_size, g_max, forced, w),
            t0,
            t0_lo,
            y0,
            s_stop,
            fired,
            rate,
            ybuf,
        )
        if abs(delta) <= 1e-9 * max(1.0, s_stop):
            zs = wv[V_ZS, :n]
            rhs(prob, mode, t0 + s_stop, ybuf, zs)  # dy/dt at the event, for the first-order shift
            for i in range(n):
                y_out[i] = wv[V_YH, i] + (wv[V_YL, i] + zs[i] * delta)
            cnt[POLISHED] += 1
        else:
            delta = 0.0
    if fired >= 0 or status != K_OK:
        # the stop time t0 + t0_lo + s_stop + delta as hi + lo (double-double sums)
        oh, ol = dd.two_sum(s_stop, delta)
        oh, ol = dd.add_d(oh, ol, t0_lo)
        t_stop, t_lo = dd.add_d(oh, ol, t0)
    else:
        t_stop, t_lo = t_end, 0.0
    for i in range(n):
        if not np.isfinite(y_out[i]):
            return K_NONFINITE, t_stop, t_lo, -1
    _dense(cx, y0, t_eval, y_eval, si, t0, t0_lo, t_stop, ybuf)
    return status, t_stop, t_lo, fired
