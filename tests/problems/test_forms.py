"""The vector field is written once per problem: every other form of it is checked against the law.

A problem's law (its compiled ``rhs``, ``jacobian``, ``guard_value``,
``guard_rate``) is the one place its dynamics are written. Some problems also
carry a second, hand-written form for an integrator that cannot call compiled
code or wants the structure: ``linear_form`` and ``guard_row`` (``exact`` and
``exact-mp`` solve from them) and ``symbolic_field`` and ``symbolic_guard``
(heyoka compiles them). Here every built-in problem's forms are compared with
its law, mode by mode, at random states and times:

- ``linear_form`` reproduces ``rhs`` and ``guard_row`` reproduces every guard of
  the mode, to a few ulps of the terms' magnitudes (both sides are the same
  affine expression, rounded differently);
- ``symbolic_field`` and ``symbolic_guard``, evaluated on floats, reproduce
  ``rhs`` and the guard to a few ulps;
- ``jacobian`` is the derivative of ``rhs`` and ``guard_rate`` the derivative
  of ``guard_value`` along the field (central differences: the bound is the
  step's truncation plus the rounding divided by the step).

The friction family's heyoka expressions and SUNDIALS residuals have their own
tests (``tests/integrators/test_heyoka_model.py``, ``test_sundials.py``).
"""

from __future__ import annotations

import numpy as np
import pytest

import nsbench

RNG = np.random.default_rng(20261126)
EPS = np.finfo(float).eps

#: Built-in problems, with parameters that make every term of the field non-zero where the defaults do not.
PROBLEMS = [
    ("bouncing-ball", {}),
    ("bouncing-ball", {"g": 3.7, "e": 0.5, "x0": 2.0, "v0": 1.5}),
    ("block-on-ground", {"c": 0.3, "fs": 0.8, "fr": 1.1}),
    ("impact-oscillator", {}),
    ("relay-feedback", {}),
    ("relay-feedback", {"lam": 0.06}),
    ("henon-heiles", {}),
    ("one-dof", {"case": 2}),
    ("two-dof", {"case": 2}),
    ("two-dof", {"case": 4}),
    ("chain", {"case": 2, "n": 3}),
    ("casella-sliding", {}),
    ("circle-oscillator", {}),
    ("den-hartog", {}),
    ("woodpecker", {}),
    ("woodpecker", {"dimensional": True}),
]


def _modes(problem) -> list[tuple[int, ...]]:
    """Every mode of the problem: the friction family lists its own, the others name theirs."""
    if hasattr(problem, "modes"):
        return list(problem.modes)
    return [(code,) for code in problem.mode_names]


def _points(problem, count=4):
    scale = np.maximum(1.0, np.abs(problem.initial_state()))
    return [(float(RNG.uniform(0.0, 20.0)), RNG.normal(size=problem.n_states) * scale) for _ in range(count)]


def _ids(item):
    name, params = item
    return name + "".join(f"-{k}={v}" for k, v in params.items())


@pytest.fixture(params=PROBLEMS, ids=[_ids(p) for p in PROBLEMS])
def problem(request):
    name, params = request.param
    return nsbench.get_problem(name, **params)


def test_the_linear_form_and_the_guard_rows_are_the_law(problem):
    if not problem.is_linear:
        pytest.skip(f"{problem.name} is not piecewise linear: it has no linear form")
    w = problem.forcing_frequency
    for mode in _modes(problem):
        a, b0, bc, bs = problem.linear_form(mode)
        for t, y in _points(problem):
            z = np.concatenate([y, [1.0, np.cos(w * t), np.sin(w * t)]])
            got = a @ y + b0 + bc * z[-2] + bs * z[-1]
            size = np.abs(a) @ np.abs(y) + np.abs(b0) + np.abs(bc) + np.abs(bs)
            want = problem.rhs(mode, t, y)
            # a few ulps of the largest term: the law may form a zero row as a difference of terms
            # (the relay's sliding field, (A - B C A / C B) x), the linear form has it exactly
            assert np.all(np.abs(got - want) <= 8 * EPS * (size + np.abs(want)).max()), (mode, t, y, got, want)
            for guard in problem.guards(mode):
                q = problem.guard_row(mode, guard.code, guard.block - 1)
                value = problem.guard_value(guard, t, y)
                assert abs(q @ z - value) <= 8 * EPS * (np.abs(q) @ np.abs(z)), (mode, guard, q @ z, value)


def test_the_symbolic_form_is_the_law(problem):
    if not hasattr(problem, "symbolic_field"):
        pytest.skip(f"{problem.name} has no symbolic form")
    for mode in _modes(problem):
        for t, y in _points(problem):
            got = np.array([float(v) for v in problem.symbolic_field(mode, t, list(y))])
            want = problem.rhs(mode, t, y)
            # the same sums and products in another order: a few ulps of the largest term (quadratic in y)
            size = 1.0 + np.abs(y).max() ** 2
            assert np.all(np.abs(got - want) <= 16 * EPS * size), (mode, got, want)
            for guard in problem.guards(mode):
                got_g = float(problem.symbolic_guard(mode, guard.code, guard.block - 1, t, list(y)))
                assert got_g == pytest.approx(float(problem.guard_value(guard, t, y)), rel=8 * EPS, abs=8 * EPS)


def test_the_jacobian_and_the_guard_rates_are_derivatives_of_the_law(problem):
    h = 1e-5
    for mode in _modes(problem):
        for t, y in _points(problem, 2):
            jac = problem.jacobian(mode, t, y)
            f = problem.rhs(mode, t, y)
            for j in range(problem.n_states):
                e = np.zeros(problem.n_states)
                e[j] = h
                fd = (problem.rhs(mode, t, y + e) - problem.rhs(mode, t, y - e)) / (2 * h)
                # truncation h^2 |f'''| / 6 (fields at most cubic: |f'''| <= 6 |f| / |y|^3 scale) + rounding
                bound = 1e-6 * (1.0 + np.abs(f) + np.abs(jac[:, j]))
                assert np.all(np.abs(jac[:, j] - fd) <= bound), (mode, j, jac[:, j], fd)
            for guard in problem.guards(mode):
                rate = problem.guard_rate(guard, t, y, f)
                fd = (problem.guard_value(guard, t + h, y + h * f) - problem.guard_value(guard, t - h, y - h * f)) / (
                    2 * h
                )
                assert abs(rate - fd) <= 1e-6 * (1.0 + abs(rate) + np.abs(f).max()), (mode, guard, rate, fd)
