"""The N-block chain (MODEL.md section 7): identities with the 1- and 2-DOF problems, parameters, validation."""

from __future__ import annotations

import numpy as np
import pytest

import nsbench
from nsbench.errors import ConfigError
from nsbench.problems import get_problem, list_problems


def test_chain_is_registered():
    assert "chain" in list_problems()
    p = get_problem("chain")
    assert p.n_blocks == 4 and p.config()["params"] == {"n": 4}


@pytest.mark.parametrize("case", [1, 2, 3, 4])
@pytest.mark.parametrize("dimensional", [False, True])
def test_two_blocks_are_the_two_dof_problem(case, dimensional):
    chain, two = (
        get_problem("chain", n=2, case=case, dimensional=dimensional),
        get_problem("two-dof", case=case, dimensional=dimensional),
    )
    assert chain.coefficients == two.coefficients
    assert chain.scales == two.scales and chain.state_names == two.state_names


@pytest.mark.parametrize("case", [1, 2, 3, 4])
def test_one_block_is_the_one_dof_problem(case):
    assert get_problem("chain", n=1, case=case).coefficients == get_problem("one-dof", case=case).coefficients
    assert (
        get_problem("chain", n=1, case=case, dimensional=True).coefficients
        == get_problem("one-dof", case=case, dimensional=True).coefficients
    )


@pytest.mark.parametrize("case", [1, 2])
def test_event_logs_equal_to_the_last_bit(case):
    """``exact`` on chain n = 2 / n = 1 gives the two-dof / one-dof event log bit for bit."""
    for n, other in ((2, "two-dof"), (1, "one-dof")):
        a = nsbench.simulate(get_problem("chain", n=n, case=case), "exact", 300.0).events
        b = nsbench.simulate(get_problem(other, case=case), "exact", 300.0).events
        assert len(a) > 50
        assert a.equals(b), (n, other)


def test_two_dof_overrides_map_to_chain_names():
    """two-dof's c2, kappa, mu, rho2, rf2 are chain's c2, kappa2, mu2, rho2, rf2."""
    two = get_problem("two-dof", case=4, c2=0.1, kappa=2.0, mu=0.5, rho2=1.5, rf1=0.7, rf2=1.2, F=0.3, v0=0.2)
    chain = get_problem("chain", n=2, case=4, c2=0.1, kappa2=2.0, mu2=0.5, rho2=1.5, rf1=0.7, rf2=1.2, F=0.3, v0=0.2)
    assert chain.coefficients == two.coefficients
    dim_two = get_problem("two-dof", case=2, dimensional=True, m2=2.0, k2=3.0, fs1=1.5, fr2=3.0, w=0.7)
    dim_chain = get_problem("chain", n=2, case=2, dimensional=True, m2=2.0, k2=3.0, fs1=1.5, fr2=3.0, w=0.7)
    assert dim_chain.coefficients == dim_two.coefficients


def test_uniform_values_and_per_block_overrides():
    p = get_problem("chain", n=5, case=3, kappa=2.0, mu4=0.5, rho=1.2, rf3=1.1, c=0.1, h2=0.3)
    c = p.coefficients
    assert c.k == (1.0, 2.0, 2.0, 2.0, 2.0)  # kappa_1 = 1: block 1 sets the scales
    assert c.m == (1.0, 1.0, 1.0, 0.5, 1.0)
    assert c.fr == (1.0, 1.2, 1.2, 1.2, 1.2)
    assert c.fs == (5 / 6, 5 / 6, 1.1, 5 / 6, 5 / 6)
    assert c.c == (0.1,) * 5
    assert c.h == (0.576, 0.3, 0.576, 0.576, 0.576)
    assert p.state_names == tuple(f"{q}{i}" for i in range(1, 6) for q in ("x", "v"))
    assert p.parameters["mu4"] == 0.5 and p.parameters["kappa1"] == 1.0


def test_dimensional_scales_come_from_block_one():
    p = get_problem("chain", n=3, case=1, dimensional=True, m=2.0, k=8.0, fr=4.0, fs=3.0)
    assert p.scales.length == pytest.approx(0.5) and p.scales.time == pytest.approx(0.5)
    assert p.scales.force == 4.0


def test_problem_config_round_trip():
    p = get_problem("chain", n=7, case=2, mu3=0.5)
    q = nsbench.problems.problem_from_config(p.config())
    assert q.coefficients == p.coefficients and q.n_blocks == 7


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(n=0), r"n = 0 .* integer from 1 to 64"),
        (dict(n=65), r"n = 65 .* integer from 1 to 64"),
        (dict(n=2.5), r"n = 2.5 "),
        (dict(n=True), r"n = True "),
        (dict(n=3, c5=0.1), r"'c5' names block 5, but the chain has n = 3"),
        (dict(n=3, kappa1=2.0), r"'kappa1' is 1 by definition"),
        (dict(n=3, rf2=1.2), r"rf2 = 1.2 is out of range: .* <= rho2 = 1"),
        (dict(n=3, r_f=1.5), r"r_f = 1.5 is out of range"),
        (dict(n=3, mu3=-1.0), r"mu3 = -1 is out of range: mass ratio mu3 must be > 0"),
        (dict(n=3, c=float("nan")), r"c = nan is not allowed"),
        (dict(n=3, zz=1.0), r"unknown parameter 'zz'; allowed: c, kappa"),
        (dict(n=3, case=7), r"unknown case 7"),
        (dict(n=3, dimensional=True, fs2=3.0), r"fs2 = 3 is out of range: kinetic friction fs2 must be <= static"),
        (dict(n=3, dimensional=True, m2=0.0), r"m2 = 0 is out of range: mass m2 must be > 0"),
        (dict(n=3, dimensional=True, kappa=2.0), r"unknown parameter 'kappa'"),
    ],
)
def test_bad_input_names_the_value(kwargs, match):
    with pytest.raises(ConfigError, match=match):
        get_problem("chain", **kwargs)


def _canonical(events, tol: float = 1e-9):
    """The log with each group of events closer than ``tol`` in time sorted by (kind, block).

    From rest, the inner blocks of a long chain are physically tied (the coupling
    reaches block ``i`` only at order ``t**(2 i)``), so they stick within rounding of
    one another, and the order the arithmetic gives inside such a group is not a
    property of the integrator.
    """
    t = events["t"].to_numpy()
    group = np.concatenate([[0], np.cumsum(np.diff(t) > tol)])
    rows = sorted(zip(group, events["kind"], events["block"], t), key=lambda r: r[:3])
    return [r[1:3] for r in rows], np.array([r[3] for r in rows]), group


def test_many_blocks_run_through_the_core():
    """64 blocks: exact against RK4 on the same log (no mode enumeration, lazy tables)."""
    p = get_problem("chain", n=64, case=1)
    a = nsbench.simulate(p, "exact", 40.0)
    b = nsbench.simulate(p, "henon-rk4", 40.0, options={"h": 0.005})
    assert a.ok and b.ok and len(a.events) > 10
    seq_a, t_a, groups = _canonical(a.events)
    seq_b, t_b, _ = _canonical(b.events)
    assert groups.max() >= 5  # several distinct event times, one of them a large tie group
    assert seq_a == seq_b
    # RK4 with Henon's step at h = 0.005: event times within 1e-7 over 40 time units (order 4)
    assert np.max(np.abs(t_a - t_b)) < 1e-7
