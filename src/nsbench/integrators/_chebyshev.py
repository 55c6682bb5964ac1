"""Chebyshev-Gauss-Lobatto machinery for collocation integrators: nodes, operators, interpolation.

Everything lives on the reference interval ``tau in [-1, 1]`` with the
ascending nodes ``tau_j = -cos(j pi / N)``, ``j = 0..N`` (so node 0 is the
segment start and node ``N`` its end). The operators are built once per degree
``N`` with numpy and cached; :func:`barycentric` and :func:`clenshaw` are
compiled (numba) so the compiled integrator loops can call them.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from nsbench.model.compile import hot


def cgl_nodes(N: int) -> np.ndarray:
    """The ``N + 1`` Chebyshev-Gauss-Lobatto nodes ``-cos(j pi / N)``, ascending."""
    # -cos(j pi / N) written as a sine of a symmetric argument: exactly antisymmetric nodes
    return np.sin(np.pi * (2.0 * np.arange(N + 1) - N) / (2.0 * N))


def chebyshev_basis(tau: np.ndarray, degree: int) -> np.ndarray:
    """``T[j, k] = T_k(tau_j)`` for ``k = 0..degree``, by the three-term recurrence."""
    tau = np.asarray(tau, dtype=float)
    basis = np.empty((tau.size, degree + 1))
    basis[:, 0] = 1.0
    if degree >= 1:
        basis[:, 1] = tau
    for k in range(1, degree):
        basis[:, k + 1] = 2.0 * tau * basis[:, k] - basis[:, k - 1]
    return basis


def values_to_coefficients(N: int) -> np.ndarray:
    """The ``(N+1) x (N+1)`` map from node values to Chebyshev coefficients (discrete orthogonality)."""
    tau = cgl_nodes(N)
    halves = np.ones(N + 1)
    halves[[0, N]] = 0.5
    gamma = np.full(N + 1, 2.0 / N)
    gamma[[0, N]] = 1.0 / N
    return gamma[:, None] * chebyshev_basis(tau, N).T * halves[None, :]


def integrate_coefficients(N: int) -> np.ndarray:
    """The ``(N+2) x (N+1)`` map from the coefficients of ``f`` to those of ``int_{-1}^tau f``."""
    P = np.zeros((N + 2, N + 1))
    P[1, 0] = 1.0
    if N >= 2:
        P[1, 2] = -0.5
    for k in range(2, N + 2):
        P[k, k - 1] += 1.0 / (2 * k)
        if k + 1 <= N:
            P[k, k + 1] -= 1.0 / (2 * k)
    # constant of integration: F(-1) = sum_k (-1)^k b_k = 0
    signs = (-1.0) ** np.arange(1, N + 2)
    P[0, :] = -signs @ P[1:, :]
    return P


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
    tau = cgl_nodes(N)
    A = values_to_coefficients(N)
    E = chebyshev_basis(tau, N + 1) @ integrate_coefficients(N) @ A
    E[0, :] = 0.0  # the integral from -1 to -1, exactly
    ops = ChebyshevOperators(N=N, nodes=tau, to_coefficients=A, integration=E, weights=barycentric_weights(N))
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
