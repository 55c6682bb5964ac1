"""Chebyshev-Gauss-Lobatto machinery for collocation integrators: nodes, operators, interpolation.

Everything lives on the reference interval ``tau in [-1, 1]`` with the
ascending nodes ``tau_j = -cos(j pi / N)``, ``j = 0..N`` (so node 0 is the
segment start and node ``N`` its end). The operators are built once per degree
``N`` and cached; :func:`barycentric` and :func:`clenshaw` are compiled (numba)
so the compiled integrator loops can call them.

The operators are computed in 40-digit arithmetic (mpmath) and rounded once to
double, so each entry is the double nearest its exact value. That makes them the
same doubles on every machine: a product of the matrices in double precision
would go through BLAS, whose kernel (chosen per CPU and by ``OPENBLAS_CORETYPE``)
sums in its own order, and ``ofapi``'s and ``mcpi``'s event logs moved in their
last bits with it. No BLAS or LAPACK call is left on their path; the compiled
loops sum in a fixed order.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import mpmath
import numpy as np

from nsbench.model.compile import hot

#: Working precision (decimal digits) of the operators before their one rounding to double.
DIGITS = 40


def _rounded(rows: list[list]) -> np.ndarray:
    """A matrix of mpmath numbers rounded entry by entry to the nearest double."""
    return np.array([[float(v) for v in row] for row in rows], dtype=float)


@functools.lru_cache(maxsize=None)
def _exact_parts(N: int) -> tuple[list, list, list, list]:
    """Nodes, basis ``T_k(tau_j)`` (``k = 0..N+1``), coefficient map and integration map in :data:`DIGITS` digits."""
    with mpmath.workdps(DIGITS):
        # tau_j = -cos(j pi / N) = cos((N - j) pi / N), so T_k(tau_j) = cos(k (N - j) pi / N): cospi is exact
        # where the value is 0 or +-1 (a recurrence would leave a residue of 1e-40 there, not a zero)
        tau = [-mpmath.cospi(mpmath.mpf(j) / N) for j in range(N + 1)]
        basis = [[mpmath.cospi(mpmath.mpf(k * (N - j)) / N) for k in range(N + 2)] for j in range(N + 1)]
        # discrete orthogonality: a_k = gamma_k sum_j'' T_k(tau_j) f_j
        to_coefficients = [
            [
                (mpmath.mpf(1 if k in (0, N) else 2) / N) * basis[j][k] * (mpmath.mpf(1) / 2 if j in (0, N) else 1)
                for j in range(N + 1)
            ]
            for k in range(N + 1)
        ]
        # coefficients of f to those of int_{-1}^tau f (exact rationals), with F(-1) = 0
        integration = [[mpmath.mpf(0)] * (N + 1) for _ in range(N + 2)]
        integration[1][0] = mpmath.mpf(1)
        if N >= 2:
            integration[1][2] = mpmath.mpf(-1) / 2
        for k in range(2, N + 2):
            integration[k][k - 1] += mpmath.mpf(1) / (2 * k)
            if k + 1 <= N:
                integration[k][k + 1] -= mpmath.mpf(1) / (2 * k)
        for i in range(N + 1):
            integration[0][i] = -mpmath.fsum((-1) ** k * integration[k][i] for k in range(1, N + 2))
    return tau, basis, to_coefficients, integration


def cgl_nodes(N: int) -> np.ndarray:
    """The ``N + 1`` Chebyshev-Gauss-Lobatto nodes ``-cos(j pi / N)``, ascending, each the nearest double."""
    return _rounded([_exact_parts(N)[0]])[0]


def values_to_coefficients(N: int) -> np.ndarray:
    """The ``(N+1) x (N+1)`` map from node values to Chebyshev coefficients (discrete orthogonality)."""
    return _rounded(_exact_parts(N)[2])


def integrate_coefficients(N: int) -> np.ndarray:
    """The ``(N+2) x (N+1)`` map from the coefficients of ``f`` to those of ``int_{-1}^tau f``."""
    return _rounded(_exact_parts(N)[3])


def _integration_matrix(N: int) -> np.ndarray:
    """``E = T P A`` (node values of ``f`` to node values of its running integral), rounded once."""
    _, basis, to_coefficients, integration = _exact_parts(N)
    with mpmath.workdps(DIGITS):
        product = mpmath.matrix(basis) * (mpmath.matrix(integration) * mpmath.matrix(to_coefficients))
        rows = [[product[i, j] for j in range(N + 1)] for i in range(N + 1)]
    E = _rounded(rows)
    E[0, :] = 0.0  # the integral from -1 to -1, exactly
    return E


def barycentric_weights(N: int) -> np.ndarray:
    """Weights of the second barycentric form on the CGL nodes: ``(-1)^j``, halved at the ends."""
    weights = (-1.0) ** np.arange(N + 1)
    weights[[0, N]] *= 0.5
    return weights


@dataclass(frozen=True)
class ChebyshevOperators:
    """The cached operators of degree ``N`` (all arrays read-only).

    Attributes
    ----------
    N
        Polynomial degree (``N + 1`` nodes).
    nodes
        ``tau_j = -cos(j pi / N)``, ascending.
    to_coefficients
        ``A``: node values to Chebyshev coefficients.
    integration
        ``E``: node values of ``f`` to node values of ``int_{-1}^{tau_i} f`` of its
        degree-``N`` interpolant (row 0 is zero, row ``N`` holds the
        Clenshaw-Curtis weights). In time units the integral is ``(h/2) E``.
    weights
        Barycentric weights.
    """

    N: int
    nodes: np.ndarray
    to_coefficients: np.ndarray
    integration: np.ndarray
    weights: np.ndarray


@functools.lru_cache(maxsize=None)
def operators(N: int) -> ChebyshevOperators:
    """Build (once per ``N``) the CGL operators of degree ``N >= 2``."""
    if N < 2:
        raise ValueError(f"Chebyshev degree N = {N} must be >= 2")
    ops = ChebyshevOperators(
        N=N,
        nodes=cgl_nodes(N),
        to_coefficients=values_to_coefficients(N),
        integration=_integration_matrix(N),
        weights=barycentric_weights(N),
    )
    for array in (ops.nodes, ops.to_coefficients, ops.integration, ops.weights):
        array.flags.writeable = False
    return ops


@hot
def barycentric(nodes, weights, values, tau, out):
    """Interpolant of ``values`` (rows = nodes) at ``tau`` into ``out`` (second barycentric form)."""
    m, n = values.shape
    for j in range(m):
        if tau == nodes[j]:
            for i in range(n):
                out[i] = values[j, i]
            return
    for i in range(n):
        out[i] = 0.0
    denominator = 0.0
    for j in range(m):
        c = weights[j] / (tau - nodes[j])
        denominator += c
        for i in range(n):
            out[i] += c * values[j, i]
    for i in range(n):
        out[i] /= denominator


@hot
def clenshaw(coefficients, tau, out):
    """Evaluate ``sum_k a_k T_k(tau)`` (rows of ``coefficients`` = ``k``) into ``out``."""
    m, n = coefficients.shape
    for i in range(n):
        b1 = 0.0
        b2 = 0.0
        for k in range(m - 1, 0, -1):
            b0 = coefficients[k, i] + 2.0 * tau * b1 - b2
            b2 = b1
            b1 = b0
        out[i] = coefficients[0, i] + tau * b1 - b2
