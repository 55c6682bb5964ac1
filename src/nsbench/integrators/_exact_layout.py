"""Memory layout of ``exact``'s mode tables: a few packed arrays, indexed by offsets.

Compiled functions pay a reference-count update per array at every call, so
the per-mode data live in three arrays (integers, floats, complex numbers; one
row per visited mode) and the scratch of an arc in three more, instead of
thirty separate arrays. The offsets below depend only on the number of states
``n`` (``n + 3`` is the augmented state ``[y, 1, cos w t, sin w t]``) and of
guards ``G = n`` (two per stuck block at most).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from nsbench.problems.kernels import jit

# ---- integer table, per mode: counts and flags, then the mode, slip and stuck state indices
I_NS, I_NST, I_DEFECTIVE, I_READY, I_POLISH = 0, 1, 2, 3, 4
I_MODE = 5
#: extra objective rows kept in the work arrays beyond the guards (sections)
SECTION_ROWS = 8
#: rows of the float vector scratch ``wv``
V_A0, V_A1, V_FA, V_PA, V_FB, V_PB, V_Z0, V_ZS, V_Y, V_SG, V_MA, V_MB, V_RHS = range(13)
V_YH, V_YL, V_RH, V_RL, V_P0, V_P0L, V_DH, V_DL, V_SCR = range(14, 23)
N_V = 24
#: complex vector rows of ``wc`` after the objective rows
C_AW, C_COEF, C_E, C_EA, C_EB, C_C0, C_RES = range(7)
N_C = 8
STACK = 64  # depth of the subdivision stack (rows of ``wv`` after the vectors)


@jit
def i_slip(n):
    return I_MODE + n // 2


@jit
def i_stuck(n):
    return I_MODE + n // 2 + n


@jit
def f_offsets(n):
    """Offsets in a float row: cw, ainv, ask, ass (n x n), b0s, p1, p1_lo, rate, q (G x (n+3)), aug."""
    n3 = n + 3
    cw = 0
    ainv = cw + n
    ask = ainv + n * n
    ass = ask + n * n
    b0s = ass + n * n
    p1 = b0s + n
    p1_lo = p1 + n
    rate = p1_lo + n
    q = rate + 1
    aug = q + n * n3
    end = aug + n3 * n3
    return cw, ainv, ask, ass, b0s, p1, p1_lo, rate, q, aug, end


@jit
def c_offsets(n):
    """Offsets in a complex row: lam, lam_lo, z, z_lo, vec, vec_lo, vinv (n x n each)."""
    lam = 0
    lam_lo = n
    z = 2 * n
    z_lo = 3 * n
    vec = 4 * n
    vec_lo = vec + n * n
    vinv = vec_lo + n * n
    end = vinv + n * n
    return lam, lam_lo, z, z_lo, vec, vec_lo, vinv, end


class Tables(NamedTuple):
    """The closed forms of the modes visited so far, and the scratch of one arc.

    ``keys, slots``: open-addressing index from a mode's hash to its row.
    ``ti, tf, tc``: one row per mode (layout: the ``I_*`` columns, :func:`f_offsets`,
    :func:`c_offsets`). ``scal = [forced, w, v0]``. Scratch: ``wr`` (per objective
    row: ``g0, g1, scale, w^2 |GA|``, then the row ``q`` on ``[y, 1, cos, sin]``,
    then the curvature weights), ``wc`` (the objectives' modal coefficients, then
    complex vectors, then ``B``), ``wv`` (float vectors, the subdivision stack, the
    polish's scratch).
    """

    keys: np.ndarray
    slots: np.ndarray
    ti: np.ndarray
    tf: np.ndarray
    tc: np.ndarray
    scal: np.ndarray
    wr: np.ndarray
    wc: np.ndarray
    wv: np.ndarray
    wm: np.ndarray


def empty_tables(capacity: int, n_blocks: int, sections: int = SECTION_ROWS) -> Tables:
    """Tables for ``capacity`` modes of a problem with ``n_blocks`` blocks, none filled, scratch for ``sections``."""
    n = 2 * n_blocks
    nq = n + sections
    width = max(n + 3, nq, 12)
    return Tables(
        keys=np.zeros(2 * capacity, np.uint64), slots=np.full(2 * capacity, -1, np.int64),
        ti=np.zeros((capacity, I_MODE + n_blocks + 2 * n), np.int64),
        tf=np.zeros((capacity, f_offsets(n)[-1])), tc=np.zeros((capacity, c_offsets(n)[-1]), np.complex128),
        scal=np.zeros(3), wr=np.zeros((nq, 4 + (n + 3) + n)),
        wc=np.zeros((nq + N_C + n, n + 1), np.complex128), wv=np.zeros((N_V + STACK + n, width)),
        wm=np.zeros((3, n + 3, n + 3)))


def with_sections(t: Tables, sections: int) -> Tables:
    """``t`` with scratch for at least ``sections`` sections (the mode rows are shared, not copied)."""
    n = (t.wr.shape[1] - 7) // 2  # wr has 4 + (n + 3) + n columns
    if t.wr.shape[0] >= n + sections:
        return t
    bigger = empty_tables(1, n // 2, sections)
    return t._replace(wr=bigger.wr, wc=bigger.wc, wv=bigger.wv)
