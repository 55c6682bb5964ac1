"""CGL operators against closed-form integrals, Chebyshev series and each other."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.polynomial import chebyshev as C

import mpmath

from nsbench.integrators import _chebyshev as cheb


@pytest.mark.parametrize("N", [2, 7, 12, 16])
def test_nodes_are_ascending_cgl_points(N):
    tau = cheb.cgl_nodes(N)
    assert tau[0] == -1.0 and tau[-1] == 1.0
    assert np.all(np.diff(tau) > 0)
    np.testing.assert_allclose(tau, -np.cos(np.pi * np.arange(N + 1) / N), atol=1e-16)
    np.testing.assert_array_equal(tau, -tau[::-1])  # exact symmetry


@pytest.mark.parametrize("N", [4, 9, 12])
def test_coefficients_recover_a_chebyshev_series(N):
    a = np.random.default_rng(N).normal(size=N + 1)
    values = C.chebval(cheb.cgl_nodes(N), a)
    np.testing.assert_allclose(cheb.values_to_coefficients(N) @ values, a, atol=1e-14)


@pytest.mark.parametrize("N", [4, 8, 12, 16])
def test_integration_matrix_is_exact_for_degree_n(N):
    ops = cheb.operators(N)
    tau = ops.nodes
    for k in range(N + 1):
        exact = (tau ** (k + 1) - (-1.0) ** (k + 1)) / (k + 1)
        np.testing.assert_allclose(ops.integration @ tau**k, exact, atol=5e-16 * N)
    assert np.all(ops.integration[0] == 0.0)
    # last row: Clenshaw-Curtis weights, positive and summing to the interval length
    assert ops.integration[-1].sum() == pytest.approx(2.0, abs=1e-15)
    assert np.all(ops.integration[-1] > 0)


def test_integration_converges_spectrally_on_exp():
    errors = []
    for N in (4, 8, 12, 16):
        tau = cheb.cgl_nodes(N)
        E = cheb.operators(N).integration
        errors.append(np.abs(E @ np.exp(tau) - (np.exp(tau) - np.exp(-1.0))).max())
    assert errors[-1] < 1e-15
    assert all(b < 1e-3 * a for a, b in zip(errors[:2], errors[1:3]))


def test_integration_coefficients_match_numpy():
    N = 9
    a = np.random.default_rng(1).normal(size=N + 1)
    b = cheb.integrate_coefficients(N) @ a
    np.testing.assert_allclose(b, C.chebint(a, lbnd=-1.0), atol=1e-14)


@pytest.mark.parametrize("N", [5, 12])
def test_barycentric_and_clenshaw_evaluate_the_interpolant(N):
    ops = cheb.operators(N)
    rng = np.random.default_rng(3)
    a = rng.normal(size=(N + 1, 3))
    values = C.chebval(ops.nodes, a).T  # (N+1, 3) node values of three series
    coeffs = ops.to_coefficients @ values
    out_b, out_c = np.empty(3), np.empty(3)
    for tau in (-1.0, -0.999, -0.3, 0.0, 0.71, 1.0, *ops.nodes[1:3]):
        cheb.barycentric(ops.nodes, ops.weights, values, tau, out_b)
        cheb.clenshaw(coeffs, tau, out_c)
        exact = C.chebval(tau, a)
        np.testing.assert_allclose(out_b, exact, atol=1e-13)
        np.testing.assert_allclose(out_c, exact, atol=1e-13)


def test_operators_are_cached_and_read_only():
    assert cheb.operators(12) is cheb.operators(12)
    with pytest.raises(ValueError):
        cheb.operators(12).integration[1, 1] = 0.0
    with pytest.raises(ValueError, match="N = 1"):
        cheb.operators(1)


@pytest.mark.parametrize("N", [3, 8, 12])
def test_every_operator_entry_is_its_exact_value_rounded_once(N):
    """The operators are the nearest doubles of their exact values, so no BLAS kernel can change a bit.

    Computed independently at 50 digits: ``E[i, j]`` is the integral of the Lagrange basis polynomial
    ``l_j`` from -1 to ``tau_i`` (Gauss-Legendre quadrature, exact for its degree), ``A[k, j]`` the
    discrete-orthogonality weight ``gamma_k T_k(tau_j)`` (halved at the ends), ``T_k(tau_j) = cos(k (N - j) pi / N)``.
    """
    ops = cheb.operators(N)
    with mpmath.workdps(50):
        tau = [-mpmath.cospi(mpmath.mpf(j) / N) for j in range(N + 1)]  # cospi: exact zeros
        assert [float(t) for t in tau] == ops.nodes.tolist()

        def lagrange(j):
            return lambda s: mpmath.fprod((s - tau[m]) / (tau[j] - tau[m]) for m in range(N + 1) if m != j)

        for j in range(N + 1):
            for k in range(N + 1):
                gamma = mpmath.mpf(1 if k in (0, N) else 2) / N
                half = mpmath.mpf(1) / 2 if j in (0, N) else 1
                assert float(gamma * half * mpmath.cospi(mpmath.mpf(k * (N - j)) / N)) == ops.to_coefficients[k, j]
            for i in range(1, N + 1):
                exact = mpmath.quad(lagrange(j), [-1, tau[i]], method="gauss-legendre")
                assert float(exact) == ops.integration[i, j], (i, j)
