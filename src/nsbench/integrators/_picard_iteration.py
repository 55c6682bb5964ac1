"""Compiled (numba) Picard-Chebyshev iteration of one collocation segment, with optimal feedback.

The unknowns are the increments ``D_j = y(t_j) - y_a`` at the CGL nodes
``t_j = t_a + w (tau_j + 1)`` rather than the states themselves: the increments
are small, so the integral ``w E G`` adds no rounding of ``y_a`` and the end
state can be carried to the next segment with compensated summation.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from nsbench.model.compile import hot
from nsbench.model.law import jacobian, rhs

#: Return codes of :func:`picard_iterations`.
CONVERGED, MAX_ITER = 0, 1
#: Increments that stop shrinking below this (relative to the state scale) have reached round-off.
ROUNDOFF = 64.0 * np.finfo(np.float64).eps


class Nodal(NamedTuple):
    """The node arrays of a segment's iteration: increments ``D``, states ``X``, fields ``G``, Jacobians
    ``J`` and the work arrays ``P, Y, Z``."""

    D: np.ndarray
    X: np.ndarray
    G: np.ndarray
    J: np.ndarray
    P: np.ndarray
    Y: np.ndarray
    Z: np.ndarray


class Iteration(NamedTuple):
    """How to iterate: the feedback ``order``, Jacobians at the nodes (``jac_node``), ``tol``, ``max_iter``."""

    order: int
    jac_node: bool
    tol: float
    max_iter: int


@hot
def integrate_rows(E, w, F, out):
    """``out = w E F`` (node values to node values of the running integral; row 0 is zero)."""
    m, n = F.shape
    for i in range(n):
        out[0, i] = 0.0
    for j in range(1, m):
        for i in range(n):
            s = 0.0
            for k in range(m):
                s += E[j, k] * F[k, i]
            out[j, i] = w * s


@hot
def _jacobian_times(J, Z, out, accumulate):
    """``out[j] (+)= J[j] @ Z[j]`` for the nodes ``j >= 1``."""
    m, n = Z.shape
    for j in range(1, m):
        for a in range(n):
            s = 0.0
            for b in range(n):
                s += J[j, a, b] * Z[j, b]
            out[j, a] = out[j, a] + s if accumulate else s


@hot
def picard_iterations(p, mode, t_a, y_a, w, nodes, E, nodal, it_settings):
    """Iterate the segment ``[t_a, t_a + 2w]`` of the frozen-mode field in place.

    ``nodal`` (:class:`Nodal`): on entry ``D`` holds the initial guess of the
    increments (row 0 zero) and ``G[0]`` the field at ``(t_a, y_a)``; ``X, J, P, Y,
    Z`` are work arrays. ``it_settings``: :class:`Iteration`. One iteration, with
    ``X = y_a + D``:

    - ``G_j = g(X_j, t_j)`` at the nodes ``j >= 1``;
    - the Picard update ``P = w E G`` and its correction ``dP = P - D``;
    - ``order >= 1``: ``P_j += J_j (w E dP)_j``; ``order == 2``: also
      ``P_j += J_j J_j ((w E)^2 dP)_j``, with ``J_j`` the Jacobian at ``X_j``
      (``jac_node``) or at the segment start. No matrix is inverted.

    It stops when ``max|P - D| <= tol max(1, max|X|)``, or when the increments
    stall at round-off. On return ``D`` is the last iterate and ``X = y_a + D``.

    Returns
    -------
    (code, iterations, nfev, njev)
        ``code`` is :data:`CONVERGED` or :data:`MAX_ITER` (also for non-finite iterates).
    """
    D, X, G, J, P, Y, Z = nodal
    order, jac_node, tol, max_iter = it_settings
    m, n = D.shape
    nfev = 0
    njev = 0
    for j in range(m):
        for i in range(n):
            X[j, i] = y_a[i] + D[j, i]
    if order > 0 and not jac_node:
        jacobian(p, mode, t_a, y_a, J[0])
        njev += 1
        for j in range(1, m):
            for a in range(n):
                for b in range(n):
                    J[j, a, b] = J[0, a, b]
    previous = np.inf
    it = 0
    while it < max_iter:
        it += 1
        for j in range(1, m):
            rhs(p, mode, t_a + w * (nodes[j] + 1.0), X[j], G[j])
        nfev += m - 1
        integrate_rows(E, w, G, P)
        for j in range(m):
            for i in range(n):
                Y[j, i] = P[j, i] - D[j, i]
        if order >= 1:
            if jac_node:
                for j in range(1, m):
                    jacobian(p, mode, t_a + w * (nodes[j] + 1.0), X[j], J[j])
                njev += m - 1
            integrate_rows(E, w, Y, Z)  # Z = w E dP
            _jacobian_times(J, Z, P, True)
            if order >= 2:
                integrate_rows(E, w, Z, Y)  # Y = (w E)^2 dP
                _jacobian_times(J, Y, Z, False)  # Z = J Y
                _jacobian_times(J, Z, P, True)
        delta = 0.0
        scale = 1.0
        for j in range(1, m):
            for i in range(n):
                d = abs(P[j, i] - D[j, i])
                if not d <= delta:  # also propagates NaN
                    delta = d
                scale = max(scale, abs(X[j, i]))
                D[j, i] = P[j, i]
                X[j, i] = y_a[i] + P[j, i]
        if not np.isfinite(delta):
            return MAX_ITER, it, nfev, njev
        if delta <= tol * scale or (delta >= previous and delta <= ROUNDOFF * scale):
            return CONVERGED, it, nfev, njev
        previous = delta
    return MAX_ITER, it, nfev, njev
