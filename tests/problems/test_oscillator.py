"""The hybrid structure of the oscillator: field, Jacobian, guards, transitions, regions."""

from __future__ import annotations

import numpy as np
import pytest

import nsbench
from nsbench.problems import STICK, mode_name

RNG = np.random.default_rng(12345)


@pytest.fixture(params=[("two-dof", 4), ("two-dof", 2), ("one-dof", 4)], ids=lambda p: f"{p[0]}-{p[1]}")
def problem(request):
    name, case = request.param
    return nsbench.get_problem(name, case=case)


def test_nine_modes_for_two_blocks(case1):
    assert len(case1.modes) == 9
    assert len(set(case1.modes)) == 9
    assert mode_name((-1, 0)) == "slip-|stick"


def test_rhs_matches_the_model_equations():
    p = nsbench.get_problem("two-dof", case=4)
    c = p.parameters
    t, (x1, v1, x2, v2) = 0.7, (0.3, -0.2, -0.1, 0.5)
    r1 = c["c1"] * v1 + x1 + c["h1"] * x1**3 + c["kappa"] * (x1 - x2) + c["h2"] * (x1 - x2) ** 3
    r2 = c["c2"] * v2 + c["kappa"] * (x2 - x1) + c["h2"] * (x2 - x1) ** 3 - c["F"] * np.cos(c["Omega"] * t)
    f = p.rhs((-1, 1), t, np.array([x1, v1, x2, v2]))
    assert f[0] == v1 and f[2] == v2
    assert f[1] == pytest.approx(-r1 + c["rf1"])
    assert f[3] == pytest.approx((-r2 - c["rf2"]) / c["mu"])
    g = p.rhs((STICK, 1), t, np.array([x1, v1, x2, v2]))
    assert g[0] == c["v0"] and g[1] == 0.0


def test_rhs_is_vectorised_over_states(problem):
    y = RNG.normal(size=(problem.n_states, 7))
    t = np.linspace(0, 3, 7)
    for mode in problem.modes:
        many = problem.rhs(mode, t, y)
        one = np.column_stack([problem.rhs(mode, t[k], y[:, k]) for k in range(7)])
        np.testing.assert_allclose(many, one, rtol=0, atol=1e-15)
        jm = problem.jacobian(mode, t, y)
        assert jm.shape == (problem.n_states, problem.n_states, 7)
        np.testing.assert_allclose(jm[:, :, 3], problem.jacobian(mode, t[3], y[:, 3]), atol=1e-15)


def test_jacobian_against_central_differences(problem):
    y = RNG.normal(size=problem.n_states) * 0.5
    t = 1.3
    eps = 1e-6
    for mode in problem.modes:
        jac = problem.jacobian(mode, t, y)
        for j in range(problem.n_states):
            e = np.zeros(problem.n_states)
            e[j] = eps
            fd = (problem.rhs(mode, t, y + e) - problem.rhs(mode, t, y - e)) / (2 * eps)
            np.testing.assert_allclose(jac[:, j], fd, rtol=1e-7, atol=1e-8)


def test_linear_form_reproduces_the_field():
    p = nsbench.get_problem("two-dof", case=2)
    for mode in p.modes:
        a, b0, bc, bs = p.linear_form(mode)
        for _ in range(3):
            y, t = RNG.normal(size=4), RNG.uniform(0, 10)
            expected = p.rhs(mode, t, y)
            got = a @ y + b0 + bc * np.cos(p.coefficients.w * t) + bs * np.sin(p.coefficients.w * t)
            np.testing.assert_allclose(got, expected, atol=1e-14)
    with pytest.raises(ValueError):
        nsbench.get_problem("two-dof", case=3).linear_form((-1, -1))


def test_linear_form_keeps_the_friction_constant_unrounded():
    # the constant of a slipping forced block is -fs s / m, formed once: taking F / m off
    # (F - fs s) / m rounded it (0.81 came out as 0.8099999999999999 at this point)
    p = nsbench.get_problem("two-dof", case=2, F=0.517, Omega=0.767, omega_r=7.2, v0=0.314, r_f=0.81)
    c = p.coefficients
    for mode in p.modes:
        _, b0, bc, _ = p.linear_form(mode)
        for i, phase in enumerate(mode):
            if phase != STICK:
                assert b0[2 * i + 1] == -c.fs[i] * phase / c.m[i]
        assert bc[3] == (c.F / c.m[1] if mode[1] != STICK else 0.0)


def test_guards_have_the_expected_signs(case2):
    guards = case2.guards((-1, STICK))
    assert [(g.block, g.kind, g.expected_sign) for g in guards] == [
        (1, "velocity", -1),
        (2, "upper", -1),
        (2, "lower", +1),
    ]


def test_guard_rate_is_the_time_derivative_along_the_flow(problem):
    for mode in problem.modes:
        y = RNG.normal(size=problem.n_states) * 0.4
        for i, phase in enumerate(mode):
            if phase == STICK:
                y[2 * i + 1] = problem.v0
        t, dt = 2.1, 1e-6
        f = problem.rhs(mode, t, y)
        for g in problem.guards(mode):
            fd = (g.value(t + dt, y + dt * f) - g.value(t - dt, y - dt * f)) / (2 * dt)
            assert g.rate(t, y, f) == pytest.approx(fd, rel=1e-6, abs=1e-8)


def test_transition_map(case1):
    v0 = case1.v0
    slip = case1.guards((-1, -1))[0]
    # block 1 reaches belt speed where |R1| <= 1: it sticks
    y = np.array([0.5, v0 - 1e-17, 0.2, 0.0])
    tr = case1.transition((-1, -1), slip, 0.0, y)
    assert (tr.kind, tr.block, tr.mode) == ("stick", 1, (STICK, -1))
    assert tr.y[1] == v0 and tr.y is not y
    # far from the origin |R1| > 1: it reverses with s = -sign(R1)
    tr = case1.transition((-1, -1), slip, 0.0, np.array([2.0, v0, 0.0, 0.0]))
    assert (tr.kind, tr.mode) == ("reverse", (-1, -1))
    tr = case1.transition((1, -1), slip, 0.0, np.array([-2.0, v0, 0.0, 0.0]))
    assert (tr.kind, tr.mode) == ("reverse", (1, -1))
    # stick guards: upper limit -> slip-, lower -> slip+
    upper, lower = case1.guards((STICK, -1))[:2]
    assert case1.transition((STICK, -1), upper, 0.0, np.array([1.0, v0, 0, 0])).mode == (-1, -1)
    assert case1.transition((STICK, -1), lower, 0.0, np.array([-1.0, v0, 0, 0])).mode == (1, -1)


def test_initial_mode_standard_scenario(case2):
    assert case2.initial_mode(0.0, case2.initial_state()) == (-1, -1)
    assert case2.initial_mode(0.0, np.array([0.0, case2.v0, 0.0, 1.0])) == (STICK, 1)


def test_sliding_regions_at_belt_speed(case1):
    c = case1.parameters
    x1, x2 = np.meshgrid(np.linspace(-2, 2, 5), np.linspace(-2, 2, 5))
    r1, r2 = case1.belt_speed_restoring(0.0, [x1, x2])
    np.testing.assert_allclose(r1, c["c1"] * c["v0"] + x1 + c["kappa"] * (x1 - x2))
    np.testing.assert_allclose(r2, c["c2"] * c["v0"] + c["kappa"] * (x2 - x1))
    inside = case1.in_sliding_region(1, 0.0, [x1, x2])
    np.testing.assert_array_equal(inside, np.abs(r1) <= 1.0)


def test_power_sums_to_the_energy_derivative(problem):
    for mode in problem.modes:
        y = RNG.normal(size=problem.n_states) * 0.5
        for i, phase in enumerate(mode):
            if phase == STICK:
                y[2 * i + 1] = problem.v0
        t, dt = 0.9, 1e-6
        f = problem.rhs(mode, t, y)
        de = (problem.energy(y + dt * f) - problem.energy(y - dt * f)) / (2 * dt)
        assert sum(problem.power(mode, t, y).values()) == pytest.approx(de, rel=1e-7, abs=1e-9)
