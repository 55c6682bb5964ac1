"""The friction family's compiled law against MODEL.md's equations, written out independently.

The law (:mod:`nsbench.problems.friction_law`) is the one form of the field the
core, the integrators and the numpy API use. The check here rebuilds the field
from the family's generic force code (:meth:`FrictionOscillator.restoring_forces`,
plain arithmetic, also what heyoka's expressions and exact-mp evaluate) and the
friction law of MODEL.md section 1, and takes derivatives by the complex step
(exact to rounding for this arithmetic), never from the law itself.
"""

from __future__ import annotations

import numpy as np
import pytest

import nsbench
from nsbench.problems.modes import STICK

RNG = np.random.default_rng(7)


def _field(problem, mode, t, y):
    """MODEL.md: slip ``m v' = -R - fs s``; stick ``x' = v0, v' = 0`` (any arithmetic, complex included)."""
    c = problem.coefficients
    x, v = list(y[0::2]), list(y[1::2])
    r = problem.restoring_forces(t, x, v, cos=np.cos)
    out = []
    for i, phase in enumerate(mode):
        if phase == STICK:
            out += [c.v0 + 0.0 * y[0], 0.0 * y[0]]
        else:
            out += [v[i], (-r[i] - c.fs[i] * phase) / c.m[i]]
    return np.array(out)


def _complex_step(f, y, direction, h=1e-30):
    return np.imag(f(np.asarray(y, dtype=complex) + 1j * h * np.asarray(direction))) / h


CASES = [
    ("two-dof", {"case": 4}),
    ("two-dof", {"case": 2}),
    ("one-dof", {"case": 4}),
    ("one-dof", {"case": 1}),
    ("chain", {"case": 4, "n": 3}),
]


@pytest.mark.parametrize("name, params", CASES)
def test_the_law_is_the_field_of_model_md(name, params):
    problem = nsbench.get_problem(name, v0=0.13, **params)
    n = problem.n_states
    for mode in problem.modes:
        for _ in range(3):
            y, t = RNG.normal(size=n) * 0.7, RNG.uniform(0, 20)
            np.testing.assert_allclose(problem.rhs(mode, t, y), _field(problem, mode, t, y), rtol=1e-14, atol=1e-15)
            jac = problem.jacobian(mode, t, y)
            for j in range(n):
                e = np.zeros(n)
                e[j] = 1.0
                column = _complex_step(lambda z: _field(problem, mode, t, z), y, e)
                np.testing.assert_allclose(jac[:, j], column, rtol=1e-13, atol=1e-14)


@pytest.mark.parametrize("name, params", CASES)
def test_the_guards_are_those_of_model_md(name, params):
    problem = nsbench.get_problem(name, v0=0.13, **params)
    c = problem.coefficients
    n = problem.n_states
    for mode in problem.modes:
        y, t = RNG.normal(size=n) * 0.7, RNG.uniform(0, 20)
        dy = problem.rhs(mode, t, y)
        r = problem.restoring_forces(t, list(y[0::2]), list(y[1::2]))
        for g in problem.guards(mode):
            i = g.block - 1
            if g.kind == "velocity":
                want, sign = y[2 * i + 1] - c.v0, mode[i]
            else:
                want, sign = (r[i] - c.fr[i], -1) if g.kind == "upper" else (r[i] + c.fr[i], 1)
                assert mode[i] == STICK
            assert g.expected_sign == sign
            assert g.value(t, y) == pytest.approx(want, rel=1e-14, abs=1e-15)

            # the rate along dy, the explicit time dependence of the force included
            def guard_at(z, tt=t):
                rr = problem.restoring_forces(tt, list(z[0::2]), list(z[1::2]), cos=np.cos)
                return z[2 * i + 1] if g.kind == "velocity" else rr[i]

            h = 1e-30
            z = np.asarray(y, dtype=complex) + 1j * h * dy
            along = np.imag(guard_at(z, t + 1j * h)) / h
            assert g.rate(t, y, dy) == pytest.approx(along, rel=1e-13, abs=1e-14)


def test_the_numpy_form_evaluates_columns_like_single_states():
    problem = nsbench.get_problem("two-dof", case=4)
    mode = (1, 0)
    ys, ts = RNG.normal(size=(4, 5)), RNG.uniform(0, 10, size=5)
    cols = problem.rhs(mode, ts, ys)
    for j in range(5):
        np.testing.assert_array_equal(cols[:, j], problem.rhs(mode, ts[j], ys[:, j]))
    jac = problem.jacobian(mode, ts, ys)
    assert jac.shape == (4, 4, 5)
    np.testing.assert_array_equal(jac[..., 2], problem.jacobian(mode, ts[2], ys[:, 2]))
