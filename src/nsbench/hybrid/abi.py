"""The calling convention between the compiled hybrid loop and the compiled arc kernels.

An arc kernel advances one frozen mode from ``(t0 + t0_lo, y0)`` until the first
zero of one of the mode's guards, ``t_end``, a stop on section hits, or a
failure. Every kernel has the signature::

    status, t_stop, t_lo, fired = kernel(kd, fo, p, mode, gk, gb, gs, ng, t0, t0_lo, y0, t_end,
                                         max_steps, sc, sl, sd, hit_from, hit_stop, hk, ht, hy, si,
                                         t_eval, y_eval, y_out, cnt)

- ``kd``: the kernel's own data (tables, operators); ``fo``: its float options.
- ``p``: the problem's packed coefficients (:func:`nsbench.problems.kernels.pack`).
- ``mode, gk, gb, gs, ng``: the mode and its guards (:func:`nsbench.hybrid.rules.guards_of`).
- ``sc, sl, sd``: linear state sections (coefficient rows, levels, directions).
- ``hk, ht, hy``: the section-hit buffers; a hit at ``t >= hit_from`` is appended
  at ``si[SI_NHITS]`` (:func:`record_hit`). When the buffer is full the kernel returns
  :data:`K_HIT_FULL` at once; the loop restores its counters, grows the buffers and
  runs the arc again. With ``hit_stop >= 0`` the arc stops at the hit that makes
  ``si[SI_NHITS] == hit_stop`` (:data:`K_HIT_STOP`, ``y_out`` the state there).
- ``t_eval, y_eval``: requested times and their states (rows); the kernel fills
  every ``t_eval[i] <= t_stop`` from ``si[SI_IEVAL]`` on and advances that slot.
- ``y_out``: the state where the arc stopped (before any transition);
  ``fired``: index of the guard that fired (-1 if none); ``t_lo``: low part of
  a compensated stop time (0 if not computed).
- ``cnt``: counters; :data:`NFEV`, :data:`NJEV`, :data:`NSTEPS`, then
  :data:`N_EXTRA` method-specific slots (their names are the integrator's).
"""

from __future__ import annotations

from nsbench.problems.kernels import hot, inline, jit, section_crossed  # noqa: F401 - re-exported for kernels

# kernel statuses
K_OK, K_HIT_STOP, K_HIT_FULL, K_BUDGET, K_NONFINITE, K_NEED_MODE = 0, 1, 2, 3, 4, 5
#: first method-specific failure code (a kernel may define K_FAIL + 0, + 1, ...)
K_FAIL = 8

# counter slots
NFEV, NJEV, NSTEPS = 0, 1, 2
X0, X1, X2, X3 = 3, 4, 5, 6
N_EXTRA = 4
N_COUNTERS = 3 + N_EXTRA

# slots of the loop's integer state ``si`` (0..3 belong to nsbench.hybrid.rules.settle)
SI_NHITS = 4        # section hits stored
SI_IEVAL = 5        # dense states filled
SI_PHASE = 6        # where the loop resumes
SI_STATUS = 7       # outcome of the run (RUN_* codes of nsbench.hybrid.loop)
SI_DETAIL = 8       # kernel failure code, or the index of the fired guard after an arc
SI_NG = 9           # number of guards of the current mode (in gk, gb, gs)
SI_CLOCK = 10       # nanoseconds spent inside arc kernels
SI_STOPPED = 11     # 1 when a stop rule (hits or events) ended the run



@inline
def copy_into(dst, src):
    """``dst[:] = src`` for 1-d arrays, without a temporary (usable without reference counting)."""
    for i in range(src.shape[0]):
        dst[i] = src[i]


@hot
def record_hit(hk, ht, hy, si, k, t, y):
    """Append the hit of section ``k`` at ``(t, y)`` (the caller checked there is room)."""
    j = si[SI_NHITS]
    hk[j] = k
    ht[j] = t
    for i in range(y.shape[0]):
        hy[j, i] = y[i]
    si[SI_NHITS] = j + 1

SI_ARC_STATUS = 12  # status of an arc computed in Python (the loop's callback path)
N_SI = 13


@hot
def sort_hits(hk, ht, hy, lo, hi):
    """Insertion sort of the hits ``lo .. hi - 1`` by time (one step or segment has few)."""
    for a in range(lo + 1, hi):
        b = a
        while b > lo and ht[b] < ht[b - 1]:
            ht[b], ht[b - 1] = ht[b - 1], ht[b]
            hk[b], hk[b - 1] = hk[b - 1], hk[b]
            for i in range(hy.shape[1]):
                hy[b, i], hy[b - 1, i] = hy[b - 1, i], hy[b, i]
            b -= 1
