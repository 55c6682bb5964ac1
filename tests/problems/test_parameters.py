"""Presets, validation messages and Buckingham-pi groups (MODEL.md sections 2-4)."""

from __future__ import annotations

import math

import pytest

import nsbench
from nsbench.errors import ConfigError
from nsbench.units import pi_groups


def test_table3_presets_use_exact_fractions():
    p = nsbench.get_problem("two-dof", case=4)
    v = p.parameters
    assert v["rf1"] == v["rf2"] == 5 / 6
    assert v["v0"] == 1 / 12
    assert v["F"] == 5 / 12
    assert v["h1"] == v["h2"] == 0.576
    assert v["Omega"] == 1.0 and v["kappa"] == 1.0 and v["mu"] == 1.0


@pytest.mark.parametrize(
    "case, linear, forced", [(1, True, False), (2, True, True), (3, False, False), (4, False, True)]
)
@pytest.mark.parametrize("name", ["one-dof", "two-dof"])
def test_cases_switch_cubic_and_force(name, case, linear, forced):
    p = nsbench.get_problem(name, case=case)
    assert p.is_linear is linear
    assert p.is_forced is forced


def test_dimensional_table3_matches_dimensionless_preset():
    dim = nsbench.get_problem("two-dof", case=4, dimensional=True)
    groups = pi_groups("two-dof", **dim.parameters)
    ref = nsbench.get_problem("two-dof", case=4).parameters
    for key, value in groups.items():
        assert math.isclose(value, ref[key], rel_tol=1e-14), key


def test_config1_and_config2_have_the_same_pi_groups():
    # MODEL.md section 2 (the paper's Table 2)
    # (h = F = 0; w only matters with a force, scaled here by the time scale 1 vs 1/3)
    c1 = dict(m1=2, m2=1, c1=0.03, c2=0.03, k1=2, k2=1, fr1=2.4, fr2=2.4, fs1=2, fs2=2, v0=0.2, h1=0, h2=0, F=0, w=1.0)
    c2 = dict(m1=2, m2=1, c1=0.09, c2=0.09, k1=18, k2=9, fr1=7.2, fr2=7.2, fs1=6, fs2=6, v0=0.2, h1=0, h2=0, F=0, w=3.0)
    g1, g2 = pi_groups("two-dof", **c1), pi_groups("two-dof", **c2)
    assert g1.keys() == g2.keys()
    for key in g1:
        assert math.isclose(g1[key], g2[key], rel_tol=1e-13, abs_tol=1e-15), key


def test_shorthands_set_the_paper_reduced_parameters():
    p = nsbench.get_problem("two-dof", r_f=0.6, omega_r=2.0)
    assert p.parameters["rf1"] == p.parameters["rf2"] == 0.6
    assert p.parameters["kappa"] == 4.0 and p.parameters["mu"] == 1.0
    q = nsbench.get_problem("two-dof", inv_omega_r=4.0)
    assert q.parameters["kappa"] == pytest.approx(1 / 16)
    assert q.parameters["omega_r"] == pytest.approx(0.25)


@pytest.mark.parametrize(
    "kwargs, fragment",
    [
        (dict(c1=-0.1), "c1 = -0.1 is out of range: damping c1 must be >= 0"),
        (dict(kappa=0.0), "kappa = 0 is out of range"),
        (dict(mu=-1), "mass ratio mu must be > 0"),
        (dict(rf1=1.2), "rf1 = 1.2 is out of range"),
        (dict(r_f=1.5), "r_f = 1.5 is out of range"),
        (dict(rf2=0.9, rho2=0.8), "rf2 = 0.9 is out of range"),
        (dict(v0=float("nan")), "v0 = nan is not allowed: it must be a finite real number"),
        (dict(F=float("inf")), "F = inf is not allowed"),
        (dict(h1=-0.2), "h1 = -0.2 is out of range"),
        (dict(fs1=2.0), "unknown parameter 'fs1'"),
        (dict(r_f=0.5, rf1=0.5), "do not also give rf1"),
        (dict(omega_r=2, kappa=3), "give only one"),
        (dict(Omega="fast"), "Omega = 'fast' is not a number"),
    ],
)
def test_bad_dimensionless_parameters_name_the_parameter(kwargs, fragment):
    with pytest.raises(ValueError, match=".*") as info:
        nsbench.get_problem("two-dof", **kwargs)
    assert fragment in str(info.value)
    assert isinstance(info.value, ConfigError)


@pytest.mark.parametrize(
    "kwargs, fragment",
    [
        (dict(m1=0.0), "mass m1 must be > 0"),
        (dict(m2=-1.0), "mass m2 must be > 0"),
        (dict(k1=0.0), "stiffness k1 must be > 0"),
        (dict(fs1=3.0), "kinetic friction fs1 must be <= static friction fr1 = 2.4"),
        (dict(fs2=2.5), "fs2 = 2.5 is out of range"),
        (dict(fr1=-1.0), "static friction fr1 must be > 0"),
        (dict(c2=-0.01), "damping c2 must be >= 0"),
        (dict(kappa=1.0), "unknown parameter 'kappa'"),
    ],
)
def test_bad_dimensional_parameters_name_the_parameter(kwargs, fragment):
    with pytest.raises(ConfigError) as info:
        nsbench.get_problem("two-dof", dimensional=True, **kwargs)
    assert fragment in str(info.value)


@pytest.mark.parametrize("case", [0, 5, "x", 1.5, True, None.__class__])
def test_unknown_case_is_rejected(case):
    with pytest.raises(ConfigError, match="unknown case"):
        nsbench.get_problem("two-dof", case=case)


def test_unknown_problem_lists_registered_ones():
    with pytest.raises(
        ConfigError,
        match="registered: block-on-ground, bouncing-ball, casella-sliding, chain, circle-oscillator, den-hartog, "
        "henon-heiles, impact-oscillator, one-dof, relay-feedback, two-dof, woodpecker",
    ):
        nsbench.get_problem("three-dof")


def test_one_dof_validation():
    with pytest.raises(ConfigError, match="r_f = 1.1 is out of range"):
        nsbench.get_problem("one-dof", r_f=1.1)
    with pytest.raises(ConfigError, match="fs = 3 is out of range"):
        nsbench.get_problem("one-dof", dimensional=True, fs=3)
    with pytest.raises(ConfigError, match="unknown parameter 'kappa'"):
        nsbench.get_problem("one-dof", kappa=2)


def test_config_round_trip():
    p = nsbench.get_problem("two-dof", case=3, v0=0.1, r_f=0.7)
    q = nsbench.problem_from_config(p.config())
    assert q.config() == p.config()
    assert q.coefficients == p.coefficients


def test_a_config_with_a_parameter_outside_params_is_refused():
    # a parameter at the top level used to be dropped silently (the standard case ran instead)
    with pytest.raises(ConfigError, match=r"unknown key\(s\) 'F'.*go under 'params'"):
        nsbench.problem_from_config({"name": "two-dof", "case": 2, "F": 0.517})
