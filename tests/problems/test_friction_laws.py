"""Friction laws (coulomb, weakening, stribeck): values, the field and Jacobian they give, validation.

The slip levels are written out here from their published forms (weakening:
Leine et al. 1998; Stribeck: a Gaussian decay plus a viscous term) and compared
with the compiled law, the numpy form and the generic form heyoka builds its
expressions from; the Jacobian is checked by the complex step of the field
written here, never by the law itself.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import nsbench
from nsbench.errors import ConfigError
from nsbench.problems.friction_laws import slip_level
from nsbench.problems.modes import STICK

RNG = np.random.default_rng(27)


def _level(law: dict, u, fs):
    """The slip level ``S(u)``, ``u = |v - v0|`` in the phase, from the laws' definitions."""
    if law.get("law", "coulomb") == "coulomb":
        return fs + 0.0 * u
    if law["law"] == "weakening":
        return fs / (1.0 + law["delta"] * u)
    fk, vs, cv = law["fk"], law["vs"], law.get("cv", 0.0)
    return fk + (fs - fk) * np.exp(-((u / vs) ** 2)) + cv * u


def _field(problem, law, mode, t, y):
    """Slip: ``m v' = -R - s S(s (v - v0))``; stick: ``x' = v0, v' = 0`` (complex arithmetic too)."""
    c = problem.coefficients
    x, v = list(y[0::2]), list(y[1::2])
    r = problem.restoring_forces(t, x, v, cos=np.cos)
    out = []
    for i, phase in enumerate(mode):
        if phase == STICK:
            out += [c.v0 + 0.0 * y[0], 0.0 * y[0]]
        else:
            out += [v[i], (-r[i] - phase * _level(law, phase * (v[i] - c.v0), c.fs[i])) / c.m[i]]
    return np.array(out)


LAWS = [
    {"law": "weakening", "delta": 3.0},
    {"law": "stribeck", "fk": 0.4, "vs": 0.3},
    {"law": "stribeck", "fk": 0.5, "vs": 0.2, "cv": 0.1},
]
PROBLEMS = [("one-dof", {"case": 1}), ("two-dof", {"case": 4}), ("chain", {"case": 2, "n": 3})]


@pytest.mark.parametrize("law", LAWS, ids=lambda d: "-".join(f"{v}" for v in d.values()))
@pytest.mark.parametrize("name, params", PROBLEMS)
def test_a_law_gives_the_field_and_jacobian_of_its_definition(name, params, law):
    problem = nsbench.get_problem(name, **params, **law)
    assert not problem.is_linear and law["law"] in problem.nonlinear_reason
    n = problem.n_states
    for mode in problem.modes:
        for _ in range(2):
            y, t = RNG.normal(size=n) * 0.3, RNG.uniform(0, 20)
            # slip speeds s (v - v0) >= 0, as while the phase holds
            for i, phase in enumerate(mode):
                if phase != STICK:
                    y[2 * i + 1] = problem.v0 + phase * abs(y[2 * i + 1])
            np.testing.assert_allclose(
                problem.rhs(mode, t, y), _field(problem, law, mode, t, y), rtol=1e-14, atol=1e-15
            )
            jac = problem.jacobian(mode, t, y)
            for j in range(n):
                e = np.zeros(n)
                e[j] = 1e-30
                column = np.imag(_field(problem, law, mode, t, y + 1j * e)) / 1e-30
                np.testing.assert_allclose(jac[:, j], column, rtol=1e-13, atol=1e-14)


@pytest.mark.parametrize("law", LAWS, ids=lambda d: "-".join(f"{v}" for v in d.values()))
def test_the_generic_form_heyoka_uses_is_the_compiled_one(law):
    problem = nsbench.get_problem("one-dof", case=1, c=0.0, **law)  # x = 0, c = 0: v' = S(u) in slip-
    spec = problem.law_spec
    fields = spec.fields(problem.coefficients.fs)
    fs = problem.coefficients.fs[0]
    for u in (0.0, 1e-9, 0.01, 0.3, 2.0):
        generic = slip_level(spec.code, u, fs, fields["fk"][0], fields["delta"][0], fields["vs"][0], fields["cv"][0])
        y = np.array([0.0, problem.v0 - u])  # slip-: u = -(v - v0)
        field = problem.rhs((-1,), 0.0, y)[1]
        assert field == pytest.approx(generic, rel=1e-15, abs=1e-16)
        assert generic == pytest.approx(_level(law, u, fs), rel=1e-15)


def test_every_law_starts_at_fs_and_the_published_values():
    # weakening at Leine's delta = 3: S(0.2) = 1 / 1.6 = 0.625
    assert slip_level(1, 0.2, 1.0, 0.0, 3.0, 1.0, 0.0) == 0.625
    # Stribeck: S(vs) = fk + (fs - fk) / e
    assert slip_level(2, 0.3, 1.0, 0.4, 0.0, 0.3, 0.0) == pytest.approx(0.4 + 0.6 / math.e, rel=1e-15)
    for code in (0, 1, 2):
        assert slip_level(code, 0.0, 0.83, 0.4, 3.0, 0.3, 0.1) == 0.83


def test_coulomb_is_the_default_and_unchanged():
    for name, params in PROBLEMS:
        default = nsbench.get_problem(name, **params)
        explicit = nsbench.get_problem(name, **params, law="coulomb")
        assert default.law_spec.is_coulomb and explicit.law_spec == default.law_spec
        assert default.is_linear == default.coefficients.is_linear and "friction law" not in default.nonlinear_reason
        np.testing.assert_array_equal(default.packed, explicit.packed)
        assert "law" not in default.parameters
        # the slip field is -R - fs s, bit for bit (the Coulomb branch takes no slip-speed term)
        y = RNG.normal(size=default.n_states)
        mode = tuple(1 for _ in range(default.n_blocks))
        c = default.coefficients
        r = default.restoring_forces(0.7, list(y[0::2]), list(y[1::2]))
        expected = np.array([(-r[i] - c.fs[i] * 1) / c.m[i] for i in range(default.n_blocks)])
        assert np.array_equal(default.rhs(mode, 0.7, y)[1::2], expected)


def test_the_leine_preset():
    p = nsbench.get_problem("one-dof", case="leine")
    c = p.coefficients
    assert (c.m, c.k, c.c, c.fs, c.fr, c.v0, c.F) == ((1.0,), (1.0,), (0.0,), (1.0,), (1.0,), 0.2, 0.0)
    assert p.law_spec.name == "weakening" and p.law_spec.delta == 3.0
    assert p.parameters["law"] == "weakening" and p.parameters["delta"] == 3.0
    # the dimensional form has the same numbers (every scale is 1)
    d = nsbench.get_problem("one-dof", case="leine", dimensional=True)
    np.testing.assert_array_equal(d.packed, p.packed)
    assert nsbench.get_problem("one-dof", case="Leine", delta=2.0).law_spec.delta == 2.0
    assert nsbench.get_problem("one-dof", case="leine", law="coulomb").is_linear
    # rebuilt from its config
    from nsbench.problems import problem_from_config

    np.testing.assert_array_equal(problem_from_config(p.config()).packed, p.packed)


@pytest.mark.parametrize(
    "params, match",
    [
        ({"law": "viscous"}, "law = 'viscous' is not a friction law; allowed: coulomb, weakening, stribeck"),
        ({"law": 3}, "is not a friction law"),
        ({"law": "weakening"}, "law=weakening needs the parameter.* delta"),
        ({"law": "weakening", "delta": -0.1}, "delta = -0.1 is out of range: .* must be >= 0"),
        ({"law": "weakening", "delta": float("nan")}, "delta = nan is not allowed"),
        ({"law": "weakening", "delta": "x"}, "delta = 'x' is not a number"),
        ({"law": "stribeck", "fk": 0.4}, "needs the parameter.* vs"),
        ({"law": "stribeck", "fk": 0.4, "vs": 0.0}, "vs = 0 is out of range: .* must be > 0"),
        ({"law": "stribeck", "fk": 0.4, "vs": -1.0}, "vs = -1 is out of range"),
        ({"law": "stribeck", "fk": 0.9, "vs": 0.3}, "fk = 0.9 is out of range: .* <= the slip level at rest r_f"),
        ({"law": "stribeck", "fk": -0.1, "vs": 0.3}, "fk = -0.1 is out of range"),
        ({"law": "stribeck", "fk": 0.4, "vs": 0.3, "cv": float("inf")}, "cv = inf is not allowed"),
        ({"law": "stribeck", "fk": 0.4, "vs": 0.3, "cv": -1.0}, "cv = -1 is out of range"),
        ({"delta": 3.0}, "delta belongs to law=weakening, not law=coulomb"),
        ({"law": "weakening", "delta": 1.0, "vs": 0.3}, "vs belongs to law=stribeck, not law=weakening"),
    ],
)
def test_bad_law_parameters_are_refused_by_name(params, match):
    with pytest.raises(ConfigError, match=match):
        nsbench.get_problem("one-dof", **params)


def test_fk_is_checked_against_every_block():
    with pytest.raises(ConfigError, match="fk = 0.7 .* rf of block 2 = 0.6"):
        nsbench.get_problem("two-dof", rf2=0.6, law="stribeck", fk=0.7, vs=0.3)
    with pytest.raises(ConfigError, match="fk = 2 .* fs = 1"):
        nsbench.get_problem("block-on-ground", law="stribeck", fk=2.0, vs=0.3)
    p = nsbench.get_problem("chain", n=3, law="weakening", delta=1.5)
    assert p.law_spec.delta == 1.5 and not p.is_linear
