"""Packed per-mode tables that the compiled fast path reads (built in plain numpy).

The closed-form flow of each mode of a linear problem comes from
:class:`nsbench.integrators.exact.ModeFlow` (eigen-decomposition, particular
solution); here its pieces are copied into fixed-size arrays indexed by mode,
so numba code can evaluate any mode's flow without Python objects. Modes are
indexed in the order of ``problem.modes`` (``itertools.product((-1, 0, 1))``,
block 1 slowest), which :func:`nsbench.bifurcation._jit_model.mode_index` reproduces.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from nsbench.errors import UnsupportedProblemError

NMAX = 4  # states of the largest problem (two blocks)


class FlowTable(NamedTuple):
    """Closed-form flow data of every mode (see :class:`~nsbench.integrators.exact.ModeFlow`)."""

    ns: np.ndarray      # (modes,) number of slipping states
    slip: np.ndarray    # (modes, 4) indices of slipping states
    nst: np.ndarray     # (modes,) number of stuck states
    stuck: np.ndarray   # (modes, 4) indices of stuck states (x, v pairs)
    lam: np.ndarray     # (modes, 4) complex eigenvalues of the slipping block matrix
    vec: np.ndarray     # (modes, 4, 4) complex eigenvectors
    vinv: np.ndarray    # (modes, 4, 4) their inverse
    ainv: np.ndarray    # (modes, 4, 4) inverse of the slipping block matrix
    ask: np.ndarray     # (modes, 4, 4) coupling of slipping to stuck states
    b0s: np.ndarray     # (modes, 4) constant forcing of the slipping states
    p1: np.ndarray      # (modes, 4) slope of the particular solution
    z: np.ndarray       # (modes, 4) complex amplitude of the harmonic particular solution
    rate: np.ndarray    # (modes,) fastest rate of the mode (scan step scale)
    scal: np.ndarray    # [forced (0/1), w, v0]
    cw: np.ndarray      # (modes, 4) weight of each modal term: 2 for one of a conjugate pair, 0 for its partner


def empty_table(n_modes: int = 1) -> FlowTable:
    """A table of the right types for methods that do not use closed forms (RK4)."""
    c = np.complex128
    return FlowTable(
        np.zeros(n_modes, np.int64), np.zeros((n_modes, NMAX), np.int64), np.zeros(n_modes, np.int64),
        np.zeros((n_modes, NMAX), np.int64), np.zeros((n_modes, NMAX), c), np.zeros((n_modes, NMAX, NMAX), c),
        np.zeros((n_modes, NMAX, NMAX), c), np.zeros((n_modes, NMAX, NMAX)), np.zeros((n_modes, NMAX, NMAX)),
        np.zeros((n_modes, NMAX)), np.zeros((n_modes, NMAX)), np.zeros((n_modes, NMAX), c),
        np.ones(n_modes), np.zeros(3), np.ones((n_modes, NMAX)),
    )


def flow_table(problem) -> FlowTable:
    """Pack the closed-form flow of every mode of a linear ``problem``.

    Raises
    ------
    UnsupportedProblemError
        If the problem has cubic springs, or a mode is defective or resonant
        (the Python ``exact`` integrator then falls back to a matrix
        exponential, which the compiled path does not carry).
    """
    from nsbench.integrators.exact import ModeFlow

    if not problem.is_linear:
        raise UnsupportedProblemError(f"closed-form flow needs a linear problem; {problem!r} has cubic springs")
    t = empty_table(len(problem.modes))
    forced = False
    for mi, mode in enumerate(problem.modes):
        mf = ModeFlow(problem, mode)
        if mf.use_expm:
            raise UnsupportedProblemError(
                f"{problem!r}: mode {mode} is defective or resonant; the compiled closed form "
                "does not cover it (use the 'exact' integrator)")
        forced = mf.forced
        ns, nst = mf.slip.size, mf.stuck.size
        t.ns[mi], t.nst[mi] = ns, nst
        t.slip[mi, :ns] = mf.slip
        t.stuck[mi, :nst] = mf.stuck
        t.rate[mi] = mf.fastest_rate
        if ns:
            t.lam[mi, :ns] = mf.lam
            t.vec[mi, :ns, :ns] = mf.vec
            t.vinv[mi, :ns, :ns] = mf.vec_inv
            t.ainv[mi, :ns, :ns] = mf.a_inv
            if nst:
                t.ask[mi, :ns, :nst] = mf.a_sk
            t.cw[mi, :ns] = _pair_weights(mf.lam, mf.vec, mf.vec_inv)
            t.b0s[mi, :ns] = mf.b0[mf.slip]
            t.p1[mi, :ns] = mf.p1
            if mf.forced:
                t.z[mi, :ns] = mf.z
    t.scal[:] = (1.0 if forced else 0.0, problem.coefficients.w, problem.v0)
    return t


def _pair_weights(lam: np.ndarray, vec: np.ndarray, vinv: np.ndarray) -> np.ndarray:
    """Weights that sum each conjugate pair of modal terms as twice the real part of one.

    For a real system, the terms of ``lam`` and ``conj(lam)`` are conjugate
    (their eigenvectors, inverse rows and hence coefficients are conjugate), so
    their sum is ``2 Re`` of the first: half the exponentials. Pairs whose
    vectors are not conjugate to rounding keep weight 1 each.
    """
    w = np.ones(lam.size)
    used = set()
    for c in range(lam.size):
        if c in used or lam[c].imag <= 0:
            continue
        for d in range(lam.size):
            if d == c or d in used:
                continue
            scale = max(1.0, abs(lam[c]))
            if (abs(lam[d] - np.conj(lam[c])) <= 1e-12 * scale
                    and np.allclose(vec[:, d], np.conj(vec[:, c]), rtol=0, atol=1e-13)
                    and np.allclose(vinv[d], np.conj(vinv[c]), rtol=0, atol=1e-13 * max(1.0, np.abs(vinv).max()))):
                w[c], w[d] = 2.0, 0.0
                used.update((c, d))
                break
    return w
