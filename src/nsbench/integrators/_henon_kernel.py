"""Compiled arc kernel of ``henon-rk4``: fixed-step RK4, Henon steps, grazing checks, sections, dense output.

After a step that crosses a guard ``S``, one RK4 step of size ``-S`` in the
independent variable ``sigma = S`` (field ``(f, 1) / dS/dt`` over ``(y, t)``, with
the *old* mode's field) lands on the surface; this keeps RK4's order 4 for
event times (METHODS.md section 7). A guard that dips across and back within
one step is caught from the cubic Hermite interpolant of the guard (values and
rates at the step ends), and located by bisection on RK4 sub-steps, as is any
Henon point outside its step (near-grazing). Sections use the same Henon step;
dense output is the cubic Hermite interpolant, consistent with order 4. The
step grid starts at the arc's start. Calling convention: :mod:`nsbench.model.abi`.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from nsbench.model.abi import (
    K_BUDGET,
    K_HIT_FULL,
    K_HIT_STOP,
    K_NONFINITE,
    K_OK,
    NFEV,
    NSTEPS,
    SI_IEVAL,
    SI_NHITS,
    X0,
    X1,
)
from nsbench.model.compile import hot, inline
from nsbench.model.law import guard_rate, guard_value, rhs
from nsbench.model.records import (
    copy_into,
    linear_section_rate,
    linear_section_value,
    record_hit,
    section_crossed,
    sort_hits,
)

HENON_STEPS, BISECTIONS = X0, X1  # counter slots of this kernel
#: The options vector ``fo``: the step.
OPTIONS = ("h",)
O_H = 0


class Surface(NamedTuple):
    """A surface to land on: guard ``idx`` of the arc (``fn = 0``) or section ``idx`` (``fn = 1``)."""

    fn: int
    idx: int
    kinds: np.ndarray
    blocks: np.ndarray
    sec_c: np.ndarray
    sec_l: np.ndarray


@inline
def _value(p, mode, sf, t, y):
    if sf.fn == 0:
        return guard_value(p, mode, sf.kinds[sf.idx], sf.blocks[sf.idx], t, y)
    return linear_section_value(sf.sec_c[sf.idx], sf.sec_l[sf.idx], y)


@inline
def _rate(p, mode, sf, t, y, dy):
    if sf.fn == 0:
        return guard_rate(p, mode, sf.kinds[sf.idx], sf.blocks[sf.idx], t, y, dy)
    return linear_section_rate(sf.sec_c[sf.idx], dy)


@hot
def _rk4(p, mode, t, y, h, fy, out, work):
    """One RK4 step into ``out``; ``fy = f(t, y)`` known. Three new evaluations."""
    n = y.shape[0]
    k2, k3, k4, tmp = work[0, :n], work[1, :n], work[2, :n], work[3, :n]
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


@hot
def _henon(p, mode, sf, ta, tb, t1, y1, out, work):
    """RK4 step in sigma = the surface's function from (t1, y1) to zero. Returns (ok, t_star); state into out."""
    n = y1.shape[0]
    f, tmp, acc = work[4, :n], work[5, :n], work[6, :n]
    ds = -_value(p, mode, sf, t1, y1)
    t_acc = 0.0
    t_s = t1
    for j in range(n):
        tmp[j] = y1[j]
        acc[j] = 0.0
    weights = (1.0, 2.0, 2.0, 1.0)
    fractions = (0.5, 0.5, 1.0, 0.0)
    for stage in range(4):
        rhs(p, mode, t_s, tmp, f)
        r = _rate(p, mode, sf, t_s, tmp, f)
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


@hot
def _bisect(p, mode, sf, sign, t, y, fy, t1, start, out, work):
    """First zero of sign * the surface's function in (t, t1] from RK4 sub-steps of (t, y).

    Returns ``(found, t_hit, n_substeps)``; the state at ``t_hit`` goes into ``out``.
    """
    ys = work[7, : y.shape[0]]
    lo = t
    hi = -1.0
    positive_seen = not start
    n_sub = 0
    for k in range(1, 9):
        tau = t + (t1 - t) * k / 8.0
        _rk4(p, mode, t, y, tau - t, fy, ys, work)
        n_sub += 1
        v = sign * _value(p, mode, sf, tau, ys)
        if v > 0.0:
            positive_seen = True
            lo = tau
        elif positive_seen:
            hi = tau
            copy_into(out, ys)
            break
    if hi < 0.0:
        return False, 0.0, n_sub
    for _ in range(80):
        mid = 0.5 * (lo + hi)
        if mid <= lo or mid >= hi:
            break
        _rk4(p, mode, t, y, mid - t, fy, ys, work)
        n_sub += 1
        v = sign * _value(p, mode, sf, mid, ys)
        if v > 0.0:
            lo = mid
        else:
            hi = mid
            copy_into(out, ys)
    return True, hi, n_sub


@hot
def _dips(p0, p1, d0, d1, skip_start):
    """Whether the cubic Hermite with positive ends p0, p1 and end slopes d0, d1 dips to <= 0."""
    # p(s) = h00 p0 + h01 p1 + h10 d0 + h11 d1 with h00 + h01 = 1 and |h10|, |h11| <= 4/27:
    # far from zero compared with the slopes it cannot dip (most steps end here)
    if min(p0, p1) > (4.0 / 27.0) * (abs(d0) + abs(d1)):
        return False
    a = 2.0 * p0 - 2.0 * p1 + d0 + d1
    b = -3.0 * p0 + 3.0 * p1 - 2.0 * d0 - d1
    # critical points: 3a s^2 + 2b s + d0 = 0
    qa, qb, qc = 3.0 * a, 2.0 * b, d0
    r0, r1 = 0.0, 0.0
    nroots = 0
    if qa == 0.0:
        if qb != 0.0:
            r0 = -qc / qb
            nroots = 1
    else:
        disc = qb * qb - 4.0 * qa * qc
        if disc >= 0.0:
            sq = np.sqrt(disc)
            r0 = (-qb - sq) / (2.0 * qa)
            r1 = (-qb + sq) / (2.0 * qa)
            nroots = 2
    for k in range(nroots):
        s = r0 if k == 0 else r1
        if 0.0 < s < 1.0 and 6.0 * a * s + 2.0 * b > 0.0:
            if skip_start and s < 1e-6:
                continue
            if ((a * s + b) * s + d0) * s + p0 <= 0.0:
                return True
    return False


@hot
def _hermite_into(ta, ya, fa, tb, yb, fb, t, out, col):
    h = tb - ta
    th = (t - ta) / h
    h00 = (1.0 + 2.0 * th) * (1.0 - th) ** 2
    h10 = th * (1.0 - th) ** 2
    h01 = th * th * (3.0 - 2.0 * th)
    h11 = th * th * (th - 1.0)
    for j in range(ya.shape[0]):
        out[col, j] = h00 * ya[j] + h * h10 * fa[j] + h01 * yb[j] + h * h11 * fb[j]


def scratch(n_states: int, n_sections: int, n_guards: int = 0) -> np.ndarray:
    """The kernel's scratch (``kd.f2a``) for ``n_states`` states, ``n_guards`` guards and ``n_sections`` sections."""
    return np.zeros((N_ROWS, max(n_states, n_guards, n_sections, 1)))


N_ROWS = 20  # rows of the scratch: 8 RK4 stages and temporaries, 6 states, 4 guard rows, sections, a spare


@hot
def henon_arc(kd, fo, p, arc, sec, hits, dense, si, y_out, cnt):
    """Advance one frozen mode from ``(t0, y0)`` on the grid ``t0 + k h``, the last point ``t_end``.

    ``kd.f2a``: the scratch (:func:`scratch`); ``fo[O_H]``: the step. Arguments and
    result: :mod:`nsbench.model.abi` (``t0_lo`` is not used: the method's own error is
    far above it). ``p`` is the problem (:class:`~nsbench.model.abi.ProblemData`).
    """
    mode, ng = arc.mode, arc.n_guards
    t0, y0, t_end, max_steps = arc.t0, arc.y0, arc.t_end, arc.max_steps
    sc, sl, sd, hit_from, hit_stop = sec.coeffs, sec.levels, sec.directions, sec.hit_from, sec.hit_stop
    t_eval, y_eval = dense.t, dense.y
    h = fo[O_H]
    n = y0.shape[0]
    ns = sl.shape[0]
    kinds, blocks, signs = arc.guard_kind[:ng], arc.guard_index[:ng], arc.guard_sign[:ng]
    n_float = np.ceil((t_end - t0) / h - 1e-9)
    # a step count past int64 (a step far below the span's resolution) would wrap around and end
    # the arc in one step: clamp it, so that the step budget ends such a run instead
    n_steps_total = max(1, int(n_float)) if n_float < 4e18 else 4_000_000_000_000_000_000
    wk = kd.f2a
    work = wk[0:8]  # rows cut to the state's length where used (contiguous views)
    y, fy, y1, f1, ystar, ybest = wk[8, :n], wk[9, :n], wk[10, :n], wk[11, :n], wk[12, :n], wk[13, :n]
    phi, psi, phi1, psi1 = wk[14, :ng], wk[15, :ng], wk[16, :ng], wk[17, :ng]
    sec_v = wk[18, :ns]
    dummy_l = wk[19, :1]
    copy_into(y, y0)
    t = t0
    rhs(p, mode, t, y, fy)
    cnt[NFEV] += 1
    for q in range(ng):
        phi[q] = signs[q] * guard_value(p, mode, kinds[q], blocks[q], t, y)
        psi[q] = signs[q] * guard_rate(p, mode, kinds[q], blocks[q], t, y, fy)
    for k in range(ns):
        sec_v[k] = linear_section_value(sc[k], sl[k], y)
    status = K_OK
    fired = -1
    step = 0
    while t < t_end:
        if step >= max_steps:
            status = K_BUDGET
            break
        step += 1
        t1 = t_end if step >= n_steps_total else t0 + step * h
        hk_ = t1 - t
        _rk4(p, mode, t, y, hk_, fy, y1, work)
        rhs(p, mode, t1, y1, f1)
        cnt[NFEV] += 4
        cnt[NSTEPS] += 1
        finite = True
        for j in range(n):
            if not np.isfinite(y1[j]):
                finite = False
        if not finite:
            status = K_NONFINITE
            break
        start = step == 1  # the arc's first step starts on the surface of its phase
        best_t = np.inf
        for q in range(ng):
            p1 = signs[q] * guard_value(p, mode, kinds[q], blocks[q], t1, y1)
            d1 = signs[q] * guard_rate(p, mode, kinds[q], blocks[q], t1, y1, f1)
            phi1[q] = p1
            psi1[q] = d1
            end_crossed = p1 <= 0.0
            crossed = end_crossed or ((phi[q] > 0.0 or start) and _dips(phi[q], p1, hk_ * psi[q], hk_ * d1, start))
            if not crossed:
                continue
            ok = False
            t_hit = 0.0
            if end_crossed:
                cnt[HENON_STEPS] += 1
                cnt[NFEV] += 4
                ok, t_hit = _henon(p, mode, Surface(0, q, kinds, blocks, sc, dummy_l), t, t1, t1, y1, ystar, work)
            if not ok:
                cnt[BISECTIONS] += 1
                ok, t_hit, n_sub = _bisect(
                    p, mode, Surface(0, q, kinds, blocks, sc, dummy_l), signs[q], t, y, fy, t1, start, ystar, work
                )
                cnt[NFEV] += 3 * n_sub
            if ok and t_hit < best_t:  # earliest; the lowest index on a tie
                best_t = t_hit
                fired = q
                copy_into(ybest, ystar)
        tb = t1
        if fired >= 0:
            tb = best_t
            copy_into(y1, ybest)
            rhs(p, mode, tb, y1, f1)
            cnt[NFEV] += 1
        # sections between t and tb
        first_new = si[SI_NHITS]
        for k in range(ns):
            vb = linear_section_value(sc[k], sl[k], y1)
            if section_crossed(sd[k], sec_v[k], vb):
                ok = True
                t_hit = tb
                if vb == 0.0:
                    copy_into(ystar, y1)
                else:
                    cnt[HENON_STEPS] += 1
                    cnt[NFEV] += 4
                    ok, t_hit = _henon(p, mode, Surface(1, k, kinds, blocks, sc, sl), t, tb, tb, y1, ystar, work)
                    if not ok:
                        cnt[BISECTIONS] += 1
                        sgn = 1.0 if sec_v[k] > 0.0 else -1.0
                        ok, t_hit, n_sub = _bisect(
                            p, mode, Surface(1, k, kinds, blocks, sc, sl), sgn, t, y, fy, tb, False, ystar, work
                        )
                        cnt[NFEV] += 3 * n_sub
                if ok and t_hit >= hit_from:
                    if si[SI_NHITS] >= hits.t.shape[0]:
                        return K_HIT_FULL, t, 0.0, -1
                    record_hit(hits, si, k, t_hit, ystar)
            sec_v[k] = vb
        if si[SI_NHITS] > first_new:
            sort_hits(hits, first_new, si[SI_NHITS])
            if 0 <= hit_stop <= si[SI_NHITS]:
                si[SI_NHITS] = hit_stop
                t_stop = hits.t[hit_stop - 1]
                i = si[SI_IEVAL]
                while i < t_eval.shape[0] and t_eval[i] <= t_stop:
                    _hermite_into(t, y, fy, tb, y1, f1, t_eval[i], y_eval, i)
                    i += 1
                si[SI_IEVAL] = i
                copy_into(y_out, hits.y[hit_stop - 1])
                return K_HIT_STOP, t_stop, 0.0, -1
        # dense output on (t, tb]
        i = si[SI_IEVAL]
        while i < t_eval.shape[0] and t_eval[i] <= tb:
            _hermite_into(t, y, fy, tb, y1, f1, t_eval[i], y_eval, i)
            i += 1
        si[SI_IEVAL] = i
        t = tb
        copy_into(y, y1)
        copy_into(fy, f1)
        for q in range(ng):
            phi[q] = phi1[q]
            psi[q] = psi1[q]
        if fired >= 0:
            break
    copy_into(y_out, y)
    return status, t, 0.0, fired
