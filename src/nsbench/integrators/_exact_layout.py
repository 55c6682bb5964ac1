"""Memory layout of ``exact``'s mode tables: a few packed arrays, indexed by offsets.

Compiled functions pay a reference-count update per array at every call, so
the per-mode data live in three arrays (integers, floats, complex numbers; one
row per visited mode) and the scratch of an arc in three more, instead of
thirty separate arrays. The offsets below depend only on the number of states
``n`` (``n + 3`` is the augmented state ``[y, 1, cos w t, sin w t]``), the size
``m`` of a mode vector and the most guards ``G`` a mode has (the problem's).
The whole set travels to the kernel as a :class:`~nsbench.model.abi.KernelData`
(:func:`kernel_data`).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from nsbench.model.abi import KernelData
from nsbench.model.compile import jit

# ---- integer table, per mode: counts and flags, then the mode, slip and stuck state indices
I_NS, I_NST, I_DEFECTIVE, I_READY, I_POLISH = 0, 1, 2, 3, 4
I_MODE = 5
#: extra objective rows kept in the work arrays beyond the guards (sections)
SECTION_ROWS = 8
#: rows of the float vector scratch ``wv``
V_A0, V_A1, V_FA, V_PA, V_FB, V_PB, V_Z0, V_ZS, V_Y, V_SG, V_MA, V_MB, V_RHS, V_LAM = range(14)
V_YH, V_YL, V_RH, V_RL, V_P0, V_P0L, V_DH, V_DL, V_SCR = range(14, 23)
#: defective modes: the augmented states ``z`` at the two ends of a scan step, and a bound on ``|z|`` over
#: the step (row 23 is the kernel's)
V_ZA, V_ZB, V_ZM = 24, 25, 26
N_V = 27
#: the matrices of ``wm``: three scratch matrices of the matrix exponential, then (defective modes)
#: the nonnegative majorant of the augmented matrix and its exponential over one scan step
W_MAJOR, W_MAJOR_EXP = 3, 4
N_W = 5
#: complex vector rows of ``wc`` after the objective rows
C_AW, C_COEF, C_E, C_EA, C_EB, C_C0, C_RES = range(7)
N_C = 8
STACK = 64  # depth of the subdivision stack (rows of ``wv`` after the vectors)


@jit
def i_slip(m):
    """First column of the slip state indices in an integer row (after the ``m`` mode entries)."""
    return I_MODE + m


@jit
def i_stuck(m, n):
    """First column of the stuck state indices in an integer row."""
    return I_MODE + m + n


@jit
def f_offsets(n, g):
    """Offsets in a float row: cw, ainv, ask, ass (n x n), b0s, p1, p1_lo, b0k (the stuck states' constant
    rates), rate, q (g x (n+3)), aug."""
    n3 = n + 3
    cw = 0
    ainv = cw + n
    ask = ainv + n * n
    ass = ask + n * n
    b0s = ass + n * n
    p1 = b0s + n
    p1_lo = p1 + n
    b0k = p1_lo + n
    rate = b0k + n
    q = rate + 1
    aug = q + g * n3
    end = aug + n3 * n3
    return cw, ainv, ask, ass, b0s, p1, p1_lo, b0k, rate, q, aug, end


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


#: entries of ``scal``: forced (1/0), w, and the dimensions n, m, G
S_FORCED, S_W, S_N, S_M, S_G = range(5)


class Tables(NamedTuple):
    """The closed forms of the modes visited so far, and the scratch of one arc.

    ``keys, slots``: open-addressing index from a mode's hash to its row.
    ``ti, tf, tc``: one row per mode (layout: the ``I_*`` columns, :func:`f_offsets`,
    :func:`c_offsets`). ``scal``: the ``S_*`` entries. Scratch: ``wr`` (per objective
    row: ``g0, g1, scale, w^2 |GA|``, then the row ``q`` on ``[y, 1, cos, sin]``,
    then the curvature weights: one per modal term, or for a defective mode the
    ``n + 3`` entries of the row ``q M^2`` that gives ``g''``), ``wc`` (the objectives'
    modal coefficients, then complex vectors, then ``B``), ``wv`` (float vectors, the
    subdivision stack, the polish's scratch), ``wm`` (:data:`N_W` matrices of the
    augmented size).
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


def empty_tables(capacity: int, n: int, m: int, g: int, sections: int = SECTION_ROWS) -> Tables:
    """Tables for ``capacity`` modes of a problem with ``n`` states, modes of size ``m`` and at most ``g``
    guards per mode, none filled, with scratch for ``sections`` sections."""
    nq = g + sections
    width = max(n + 3, nq, 12)
    scal = np.zeros(5)
    scal[S_N], scal[S_M], scal[S_G] = n, m, g
    return Tables(
        keys=np.zeros(2 * capacity, np.uint64),
        slots=np.full(2 * capacity, -1, np.int64),
        ti=np.zeros((capacity, I_MODE + m + 2 * n), np.int64),
        tf=np.zeros((capacity, f_offsets(n, g)[-1])),
        tc=np.zeros((capacity, c_offsets(n)[-1]), np.complex128),
        scal=scal,
        wr=np.zeros((nq, 4 + 2 * (n + 3))),
        wc=np.zeros((nq + N_C + n, n + 1), np.complex128),
        wv=np.zeros((N_V + STACK + n, width)),
        wm=np.zeros((N_W, n + 3, n + 3)),
    )


def with_sections(t: Tables, sections: int) -> Tables:
    """``t`` with scratch for at least ``sections`` sections (the mode rows are shared, not copied)."""
    n, m, g = (int(t.scal[k]) for k in (S_N, S_M, S_G))
    if t.wr.shape[0] >= g + sections:
        return t
    bigger = empty_tables(1, n, m, g, sections)
    return t._replace(wr=bigger.wr, wc=bigger.wc, wv=bigger.wv)


def kernel_data(t: Tables) -> KernelData:
    """The tables as the core hands them to the kernel (``exact_arc`` names the fields back)."""
    return KernelData(
        u1=t.keys,
        i1=t.slots,
        i2=t.ti,
        f1a=t.scal,
        f1b=np.zeros(0),
        f2a=t.tf,
        f2b=t.wr,
        f2c=t.wv,
        f3a=t.wm,
        f3b=np.zeros((0, 0, 0)),
        c2a=t.tc,
        c2b=t.wc,
    )
