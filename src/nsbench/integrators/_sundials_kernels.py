"""Compiled (numba) right-hand sides, residuals, Jacobians and root functions for the SUNDIALS adapters.

Built on the friction family's law (:mod:`nsbench.problems.friction_law`: the same
parameter vector ``p``, the same mode arrays; the SUNDIALS adapters run that family
only). Two formulations:

- CVODE: the frozen-mode ODE on ``[x1, v1, ..., c, s]`` where, for a forced
  problem, ``c = cos(w t)`` and ``s = sin(w t)`` are states (``c' = -w s``,
  ``s' = w c``) and ``p`` is the coefficient vector with ``F = 0``: the forcing
  enters only through ``c``, so the step-size control sees it.
- IDA: the DAE on ``[x1, v1, ..., f1, ...]`` with the friction forces as
  algebraic variables. A slipping block is an ODE (``m v' = -R + f``,
  ``f = -s S(s (v - v0))``, the friction law's slip force; ``-fs s`` for Coulomb); a stuck block has the algebraic constraint ``v = v0`` and
  ``f = R`` (the momentum balance with ``v' = 0``), an index-1 system.
"""

from __future__ import annotations

import numpy as np

from nsbench.model.compile import jit
from nsbench.problems import friction_law as k
from nsbench.model.records import linear_section_value
from nsbench.problems.friction_law import COULOMB, FR, M, block, law_of, n_blocks, slip_force, slip_slope, v0_of


@jit
def cvode_rhs(p, mode, F, w, y, out):
    """Frozen-mode field of the CVODE formulation (``p`` has ``F = 0``)."""
    nb = n_blocks(p)
    n = 2 * nb
    k.rhs(p, mode, 0.0, y, out)
    if F != 0.0:
        last = nb - 1
        if mode[last] != 0:
            out[2 * last + 1] += F * y[n] / block(p, M, last)
        out[n] = -w * y[n + 1]
        out[n + 1] = w * y[n]


@jit
def cvode_jacobian(p, mode, F, w, y, out):
    """Jacobian of :func:`cvode_rhs`."""
    nb = n_blocks(p)
    n = 2 * nb
    out[:, :] = 0.0
    k.jacobian(p, mode, 0.0, y, out)
    if F != 0.0:
        last = nb - 1
        if mode[last] != 0:
            out[2 * last + 1, n] = F / block(p, M, last)
        out[n, n + 1] = -w
        out[n + 1, n] = w


@jit
def cvode_roots(p, mode, F, kinds, blocks, signs, sec_coeffs, sec_levels, y, out):
    """``expected_sign * guard`` for each guard, then each section's value."""
    nb = n_blocks(p)
    n = 2 * nb
    for q in range(kinds.shape[0]):
        g = k.guard_value(p, mode, kinds[q], blocks[q], 0.0, y)
        if kinds[q] != k.VELOCITY and blocks[q] == nb - 1 and F != 0.0:
            g -= F * y[n]
        out[q] = signs[q] * g
    m = kinds.shape[0]
    for j in range(sec_levels.shape[0]):
        out[m + j] = linear_section_value(sec_coeffs[j], sec_levels[j], y[:n])


@jit
def ida_residual(p, mode, t, y, yp, out):
    """Residual of the DAE formulation (see the module docstring)."""
    nb = n_blocks(p)
    n = 2 * nb
    v0 = v0_of(p)
    for i in range(nb):
        r = k.restoring(p, t, y, i)
        f = y[n + i]
        out[2 * i] = yp[2 * i] - y[2 * i + 1]
        if mode[i] == 0:
            out[2 * i + 1] = y[2 * i + 1] - v0
            out[n + i] = f - r
        else:
            out[2 * i + 1] = block(p, M, i) * yp[2 * i + 1] + r - f
            out[n + i] = f - slip_force(p, i, mode[i], y[2 * i + 1])


@jit
def ida_jacobian(p, mode, slip_all, t, y, cj, scratch, out):
    """``dF/dy + cj dF/dyp`` of :func:`ida_residual`; ``scratch`` is an n x n work array."""
    nb = n_blocks(p)
    n = 2 * nb
    out[:, :] = 0.0
    # dR_i/dy_j = -m_i * (slip Jacobian)[2i+1, j]
    k.jacobian(p, slip_all, t, y, scratch)
    coulomb = law_of(p) == COULOMB
    for i in range(nb):
        m = block(p, M, i)
        if not coulomb:  # keep only dR/dv in the slip Jacobian's row: remove the law's d(friction)/dv
            scratch[2 * i + 1, 2 * i + 1] += slip_slope(p, i, slip_all[i] * (y[2 * i + 1] - v0_of(p))) / m
        out[2 * i, 2 * i] = cj
        out[2 * i, 2 * i + 1] = -1.0
        if mode[i] == 0:
            out[2 * i + 1, 2 * i + 1] = 1.0
            out[n + i, n + i] = 1.0
            for j in range(n):
                out[n + i, j] = m * scratch[2 * i + 1, j]
        else:
            out[2 * i + 1, 2 * i + 1] = cj * m
            for j in range(n):
                out[2 * i + 1, j] += -m * scratch[2 * i + 1, j]
            out[2 * i + 1, n + i] = -1.0
            out[n + i, n + i] = 1.0
            if not coulomb:  # f = -s S(s (v - v0)): d(f - that)/dv = S'
                out[n + i, 2 * i + 1] = slip_slope(p, i, mode[i] * (y[2 * i + 1] - v0_of(p)))


@jit
def ida_roots(p, kinds, blocks, signs, sec_coeffs, sec_levels, y, out):
    """Guards on the DAE variables: ``v_i - v0`` in slip, ``f_i -+ fr_i`` (the friction bound) in stick."""
    nb = n_blocks(p)
    n = 2 * nb
    for q in range(kinds.shape[0]):
        i = blocks[q]
        if kinds[q] == k.VELOCITY:
            g = y[2 * i + 1] - v0_of(p)
        elif kinds[q] == k.UPPER:
            g = y[n + i] - block(p, FR, i)
        else:
            g = y[n + i] + block(p, FR, i)
        out[q] = signs[q] * g
    m = kinds.shape[0]
    for j in range(sec_levels.shape[0]):
        out[m + j] = linear_section_value(sec_coeffs[j], sec_levels[j], y[:n])


@jit
def _slip_force(p, i, phase, v):
    return slip_force(p, i, phase, v)


@jit
def _restoring(p, t, y, i):
    return k.restoring(p, t, y, i)


@jit
def _restoring_rate(p, t, y, dy, i):
    return k.restoring_rate(p, t, y, dy, i)


def consistent_start(p: np.ndarray, mode: np.ndarray, t: float, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Consistent ``(y, yp)`` of the DAE at a mode switch from the mechanical state ``y``."""
    nb = int(n_blocks(p))
    n = 2 * nb
    yy = np.concatenate([np.asarray(y, dtype=float), np.zeros(nb)])
    field = np.empty(n)
    k.rhs(p, mode, t, yy, field)
    yp = np.concatenate([field, np.zeros(nb)])
    for i in range(nb):
        if mode[i] == 0:
            yy[n + i] = _restoring(p, t, yy, i)
            yp[n + i] = _restoring_rate(p, t, yy, yp, i)  # d/dt of f = R along the flow
        else:
            yy[n + i] = _slip_force(p, i, mode[i], yy[2 * i + 1])
    return yy, yp
