"""Compiled loop of ``moreau-jean``: Moreau-Jean time-stepping of the friction chain, one-step problem by
enumeration (short chains) or by an active-set iteration (long chains).

Per step of size ``h`` (MODEL.md section 7 with ``h_i = 0``; ``u = v - v_belt``)::

    x_theta = x_k + theta h (theta v_{k+1} + (1 - theta) v_k)
    M (v_{k+1} - v_k) = h (-C v_theta - K x_theta + F_theta) + P,     P = h f
    x_{k+1} = x_k + h (theta v_{k+1} + (1 - theta) v_k)

which is ``W v_{k+1} = b + h f`` with ``W = M + h theta C + h^2 theta^2 K`` and ``b``
known. The friction impulse of block ``i`` obeys the set-valued law at the *new*
velocity: ``f_i = -fs_i sign(u_i)`` if ``u_i != 0``, ``|f_i| <= fr_i`` if ``u_i = 0``.
With a status per block (stick, slip+, slip-) the step is a linear solve, so the
one-step problem is solved exactly (to rounding) by enumeration: the previous
step's status first; if it is not consistent, every one of the ``3^n`` statuses,
keeping the consistent one with the fewest changes from the previous status and,
among those, the fewest reversals (a block whose velocity reaches the belt sticks
if its force allows, as in the event-driven model). A consistent status always
exists (the solution of the monotone problem with ``fr = fs`` is one).

For long chains (``3^n`` statuses, ``2^n`` inverses) the one-step problem is solved
instead by a primal-dual active-set iteration (:func:`_active_set`, a semismooth
Newton method on the complementarity form of the law) started from the previous
status, each linear step by Thomas' algorithm on the tridiagonal ``W``; it stops at a
status that passes the same consistency test, and a step that finds none within
:func:`active_set_cap` solves ends the run (``NOT_CONVERGED``).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from nsbench.model.compile import jit


class StepData(NamedTuple):
    """What every step reads: the operators of the step size, the chain's coefficients, the scheme."""

    W: np.ndarray  # M + h theta C + h^2 theta^2 K
    winv: np.ndarray  # (2^n, n, n): inverse of W on each set of slipping blocks (bit mask), embedded
    m: np.ndarray
    c: np.ndarray
    K: np.ndarray
    fs: np.ndarray
    fr: np.ndarray
    F: float
    w: float
    v0: float
    theta: float
    h: float
    method: int  # ENUMERATION or ACTIVE_SET: how a step whose previous status is inconsistent is solved
    cap: int  # the active set's most solves per step (active_set_cap)


#: Slots of ``Trajectory.counters``: one-step problems solved, steps that needed the enumeration,
#: candidate solves.
ONE_STEP_PROBLEMS, ENUMERATIONS, CANDIDATE_SOLVES, N_COUNTERS = 0, 1, 2, 3


class Trajectory(NamedTuple):
    """The buffers a run fills: step times, states, statuses, and the counters."""

    T: np.ndarray
    Y: np.ndarray
    MODES: np.ndarray
    counters: np.ndarray  # one-step problems solved, steps that needed the enumeration, candidate solves


#: Outcome codes of :func:`mj_run`.
OK, BUDGET, NO_STATUS, NOT_CONVERGED = 0, 1, 2, 3
#: One-step solvers (:attr:`StepData.method`).
ENUMERATION, ACTIVE_SET = 0, 1


def active_set_cap(n: int) -> int:
    """The iteration cap of the active-set solver on ``n`` blocks: a run whose step needs more ends with a failure."""
    return 4 * n + 20


#: Relative slack of the static-friction test (rounding of the solve, about 1e3 ulps).
STATIC_SLACK = 1e-13


@jit
def _candidate(status, W, winv, b, h, v0, fs, fr, vnew, rhs):
    """Solve the step for ``status``; return whether the result is consistent with the friction law.

    Takes the arrays themselves, not the :class:`StepData` bundle: passing the bundle to a call in the
    hot loop costs reference counting of every array in it (3.5 times slower, measured).
    """
    n = status.shape[0]
    mask = 0
    for i in range(n):
        if status[i] != 0:
            mask |= 1 << i
    inv = winv[mask]
    for i in range(n):
        if status[i] != 0:
            r = b[i] - h * fs[i] * status[i]
            for j in range(n):
                if status[j] == 0:
                    r -= W[i, j] * v0
            rhs[i] = r
        else:
            rhs[i] = 0.0
    for i in range(n):
        if status[i] == 0:
            vnew[i] = v0
        else:
            s = 0.0
            for j in range(n):
                s += inv[i, j] * rhs[j]
            vnew[i] = s
    for i in range(n):
        if status[i] == 0:
            s = -b[i]
            for j in range(n):
                s += W[i, j] * vnew[j]
            if abs(s) > h * fr[i] * (1.0 + STATIC_SLACK):
                return False
        elif status[i] * (vnew[i] - v0) < 0.0:
            return False
    return True


@jit
def _tridiagonal_candidate(status, W, b, h, v0, fs, vnew, idx, diag, sup, rhs):
    """Solve the step for ``status`` on a chain (``W`` tridiagonal): the slipping blocks' rows of
    ``W v = b + h f`` with the stuck blocks at ``v0``, by Thomas' algorithm on the slipping blocks in order.

    ``W`` restricted to any subset of the blocks is tridiagonal in the subset's order (two slipping blocks
    that are not neighbours in the chain have no coupling), symmetric and strictly diagonally dominant (the
    masses add to the springs' weakly dominant rows), so the elimination needs no pivoting: O(n) per solve.
    """
    n = status.shape[0]
    p = 0
    for i in range(n):
        if status[i] == 0:
            vnew[i] = v0
        else:
            r = b[i] - h * fs[i] * status[i]
            if i > 0 and status[i - 1] == 0:
                r -= W[i, i - 1] * v0
            if i < n - 1 and status[i + 1] == 0:
                r -= W[i, i + 1] * v0
            idx[p] = i
            rhs[p] = r
            p += 1
    # forward elimination: diag[q] the pivot, sup[q] the coupling to the next slipping block
    for q in range(p):
        i = idx[q]
        dq = W[i, i]
        r = rhs[q]
        if q > 0:
            lo = W[i, idx[q - 1]]  # 0 unless the previous slipping block is the chain neighbour
            if lo != 0.0:
                mult = lo / diag[q - 1]
                dq -= mult * sup[q - 1]
                r -= mult * rhs[q - 1]
        diag[q] = dq
        rhs[q] = r
        sup[q] = W[i, idx[q + 1]] if q < p - 1 else 0.0
    for q in range(p - 1, -1, -1):
        x = rhs[q]
        if q < p - 1:
            x -= sup[q] * vnew[idx[q + 1]]
        vnew[idx[q]] = x / diag[q]


@jit
def _active_set(status, W, b, h, v0, fs, fr, work, iwork, cap):
    """The one-step problem by a primal-dual active-set (semismooth Newton) iteration; ``status`` is updated.

    From ``status`` (the previous step's), solve the linear step; every block that violates the law
    changes at once: a stuck block whose impulse exceeds the static bound ``h fr`` slips in the direction
    its load drives it, a slipping block whose new velocity crossed the belt's sticks (a later iteration
    lets it slip the other way if its load exceeds the bound). It stops at the first consistent status
    (the enumeration's test, slack :data:`STATIC_SLACK`) and returns the number of solves, or ``-1`` after
    ``cap`` solves without one (a cycle: the law with ``fr > fs`` is not monotone). ``work`` (4, n) holds
    the new velocities (row 0) and scratch, ``iwork`` (2, n) scratch.
    """
    n = status.shape[0]
    vnew, diag, sup, rhs = work[0], work[1], work[2], work[3]
    trial, idx = iwork[0], iwork[1]
    for i in range(n):
        trial[i] = status[i]
    for it in range(cap):
        _tridiagonal_candidate(trial, W, b, h, v0, fs, vnew, idx, diag, sup, rhs)
        changed = False
        for i in range(n):
            if trial[i] == 0:
                r = -b[i]  # the friction impulse h f_i the stuck block needs: (W v - b)_i
                lo = i - 1 if i > 0 else 0
                hi = i + 2 if i < n - 1 else n
                for j in range(lo, hi):
                    r += W[i, j] * vnew[j]
                if abs(r) > h * fr[i] * (1.0 + STATIC_SLACK):
                    status[i] = -1 if r > 0.0 else 1  # a friction +fs needed beyond fr: the load drives u < 0
                    changed = True
                else:
                    status[i] = 0
            elif trial[i] * (vnew[i] - v0) < 0.0:
                status[i] = 0
                changed = True
            else:
                status[i] = trial[i]
        if not changed:
            return it + 1
        for i in range(n):
            trial[i] = status[i]
    return -1


@jit
def mj_run(d, t0, y0, mode0, n_steps, out):
    """Run ``n_steps`` steps of :class:`StepData` ``d`` from ``(t0, y0)`` in status ``mode0``; fill the
    :class:`Trajectory` ``out``; return ``(code, steps done)``."""
    m, c, K, F, w, theta, h = d.m, d.c, d.K, d.F, d.w, d.theta, d.h
    W, winv, v0, fs, fr = d.W, d.winv, d.v0, d.fs, d.fr
    active = d.method == ACTIVE_SET
    T, Y, MODES, counters = out.T, out.Y, out.MODES, out.counters
    n = m.shape[0]
    x = np.empty(n)
    v = np.empty(n)
    for i in range(n):
        x[i] = y0[2 * i]
        v[i] = y0[2 * i + 1]
    status = mode0.copy()
    trial = np.empty(n, np.int64)
    best = np.empty(n, np.int64)
    work = np.empty((4, n))  # the active set's: new velocities (row 0, shared with the enumeration) and scratch
    iwork = np.empty((2, n), np.int64)
    vnew = work[0]
    vbest = np.empty(n)
    b = np.empty(n)
    xt = np.empty(n)
    rhs = np.empty(n)
    cap = d.cap
    T[0] = t0
    for i in range(2 * n):
        Y[0, i] = y0[i]
    for i in range(n):
        MODES[0, i] = status[i]
    last = n - 1
    n_codes = 0 if active else 3**n
    a1 = h * theta * (1.0 - theta)
    for k in range(n_steps):
        t = t0 + k * h
        t1 = t0 + (k + 1) * h
        for i in range(n):
            xt[i] = x[i] + a1 * v[i]
        for i in range(n):
            kx = 0.0
            for j in range(i - 1 if i > 0 else 0, i + 2 if i < n - 1 else n):  # K is the chain's: tridiagonal
                kx += K[i, j] * xt[j]
            b[i] = m[i] * v[i] - h * ((1.0 - theta) * c[i] * v[i] + kx)
        if F != 0.0:
            b[last] += h * F * (theta * np.cos(w * t1) + (1.0 - theta) * np.cos(w * t))
        counters[ONE_STEP_PROBLEMS] += 1
        first_ok = True
        if active:
            solves = _active_set(status, W, b, h, v0, fs, fr, work, iwork, cap)
            if solves < 0:
                counters[CANDIDATE_SOLVES] += cap
                return NOT_CONVERGED, k
            counters[CANDIDATE_SOLVES] += solves
            if solves > 1:
                counters[ENUMERATIONS] += 1
        else:
            counters[CANDIDATE_SOLVES] += 1
            first_ok = _candidate(status, W, winv, b, h, v0, fs, fr, vnew, rhs)
        if not first_ok:
            counters[ENUMERATIONS] += 1
            found = False
            best_changes, best_rev = n + 1, n + 1
            for code in range(n_codes):
                q = code
                changes = 0
                rev = 0
                for i in range(n):
                    digit = q % 3
                    q //= 3
                    trial[i] = 0 if digit == 0 else (1 if digit == 1 else -1)
                    if trial[i] != status[i]:
                        changes += 1
                        if trial[i] != 0 and status[i] != 0:
                            rev += 1
                if changes > best_changes or (changes == best_changes and rev >= best_rev):
                    continue
                counters[CANDIDATE_SOLVES] += 1
                if _candidate(trial, W, winv, b, h, v0, fs, fr, vnew, rhs):
                    found = True
                    best_changes, best_rev = changes, rev
                    for i in range(n):
                        best[i] = trial[i]
                        vbest[i] = vnew[i]
            if not found:
                return NO_STATUS, k
            for i in range(n):
                status[i] = best[i]
                vnew[i] = vbest[i]
        for i in range(n):
            x[i] = x[i] + h * (theta * vnew[i] + (1.0 - theta) * v[i])
            v[i] = vnew[i]
        T[k + 1] = t1
        for i in range(n):
            Y[k + 1, 2 * i] = x[i]
            Y[k + 1, 2 * i + 1] = v[i]
            MODES[k + 1, i] = status[i]
    return OK, n_steps


def operators(m, c, K, h: float, theta: float, inverses: bool = True):
    """``W`` and, for every subset ``L`` of slipping blocks (bit mask), the inverse of ``W[L, L]`` embedded in n x n.

    ``inverses=False`` (the active-set solver, which solves the tridiagonal systems as it goes) skips the
    ``2^n`` inverses and returns a placeholder for them.
    """
    n = len(m)
    W = np.diag(m) + h * theta * np.diag(c) + h * h * theta * theta * K
    if not inverses:
        return W, np.zeros((1, 1, 1))
    winv = np.zeros((2**n, n, n))
    for mask in range(1, 2**n):
        idx = [i for i in range(n) if mask >> i & 1]
        winv[mask][np.ix_(idx, idx)] = spd_inverse(W[np.ix_(idx, idx)])
    return W, winv


def spd_inverse(a: np.ndarray) -> np.ndarray:
    """The inverse of a symmetric positive definite matrix by Gauss-Jordan elimination in a fixed order.

    Not ``np.linalg.inv``: LAPACK's elimination goes through BLAS, whose kernel (chosen per CPU and by
    ``OPENBLAS_CORETYPE``) orders its sums in its own way, so the step's doubles would depend on the
    machine. An SPD matrix needs no pivoting (every pivot is a ratio of leading principal minors, all
    positive), and each update below is one rounded product and one rounded difference per entry.
    """
    n = a.shape[0]
    work = np.concatenate([np.array(a, dtype=float), np.eye(n)], axis=1)
    for k in range(n):
        pivot = work[k, k]
        if not pivot > 0.0:
            raise ValueError(f"spd_inverse: pivot {k} is {pivot!r}; the matrix is not positive definite")
        work[k, :] = work[k, :] / pivot
        for r in range(n):
            if r != k and work[r, k] != 0.0:
                work[r, :] = work[r, :] - work[r, k] * work[k, :]
    return work[:, n:].copy()


@jit
def mj_ball(g, e, theta, h, t0, x0, v0, n_steps, T, Y, MODES, P):
    """Moreau-Jean on the bouncing ball: Newton's impact law at the velocity level, one contact.

    The contact is active in a step when the position predicted half a step ahead,
    ``x_k + h v_k / 2``, is not above the ground; then the impulse ``P >= 0`` makes
    ``v_{k+1} + e v_k >= 0`` with complementarity (``P = 0`` or equality). A step whose
    post-impact speed ``e |v_k|`` is at most one step's gain of speed under gravity
    ``g h`` is resting (mode 1): the ball cannot leave the ground for more than a step.
    Fills ``T``, ``Y`` (x, v), ``MODES`` and ``P`` (the impulse of the step ending there).
    """
    x = x0
    v = v0
    T[0] = t0
    Y[0, 0] = x
    Y[0, 1] = v
    MODES[0, 0] = 0
    P[0] = 0.0
    mode = 0
    for k in range(n_steps):
        vfree = v - h * g
        vnew = vfree
        imp = 0.0
        if x + 0.5 * h * v <= 0.0 and vfree + e * v < 0.0:
            vnew = -e * v
            imp = vnew - vfree
        if imp > 0.0 and e * abs(v) <= g * h:
            mode = 1
        x = x + h * (theta * vnew + (1.0 - theta) * v)
        v = vnew
        T[k + 1] = t0 + (k + 1) * h
        Y[k + 1, 0] = x
        Y[k + 1, 1] = v
        MODES[k + 1, 0] = mode
        P[k + 1] = imp
    return n_steps
