"""Largest Lyapunov exponent of the mapping points: negative on a periodic case, positive on a chaotic one.

The periodic case (case 1, v0 = 0.1) is checked to be periodic independently
(its peaks repeat); the chaotic one is case 2 with F = 0.1417, near the
border-collision the paper names, found by exploring the F sweep: its
ensemble of nearby starts, and two integrators, find a positive
exponent.

On the chaotic case no test depends on the bitwise course of a trajectory
(which changes with the machine): every check compares ensemble estimates with
their own standard errors, with margins whose false-failure probability is
stated where they are made.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import nsbench
from nsbench.bifurcation import detect
from nsbench.bifurcation.lyapunov import _verdict, largest_exponent
from nsbench.errors import ConfigError
from nsbench.sections import peaks


@pytest.fixture(scope="module")
def chaotic():
    return nsbench.get_problem("two-dof", case=2, F=0.1417)


@pytest.fixture(scope="module")
def chaotic_exact(chaotic):
    """10000 iterations with exact, seed 0, as 64 members x 156 iterations.

    64 members rather than the default 32: a member is now and then captured by
    a coexisting stable motion (see test_positive_exponent_on_a_chaotic_case),
    and the more members, the smaller the standard error of the others.
    """
    return largest_exponent(chaotic, "exact", members=64, seed=0, workers=2)


def combined_error(a, b) -> float:
    return math.sqrt(a.standard_error**2 + b.standard_error**2)


def test_negative_exponent_on_a_periodic_case():
    p = nsbench.get_problem("two-dof", case=1, v0=0.1)
    sec = nsbench.simulate(p, "exact", 1300.0, sections=[peaks(p)]).sections
    x1 = sec[sec["t"] >= 1000.0]["x1"].to_numpy()[:, None]
    assert detect.period_of(x1, 1e-8) > 0
    res = largest_exponent(p, "exact", iterations=800)
    assert res.status == "success" and res.converged and res.consistent
    # every member ends on the same periodic orbit; they differ only by the point
    # of it where they start counting, so the estimate is clearly negative
    assert res.exponent < -0.05 and res.exponent + 4 * res.standard_error < 0 and res.ci_high < 0
    assert np.all(res.members < 0) and res.exponent_per_time < 0
    # The mapping points of this orbit repeat every 3 (measured), so members of 150
    # iterations cover whole periods and all give the orbit's exponent. The 25
    # iterations of each member above do not: a member's error depends on where on
    # the orbit it starts, and only members starting at random points make that
    # error show in the standard error (from one common point every member gives
    # -0.1069 with a standard error of 1e-8, 1e6 standard errors off).
    whole = largest_exponent(p, "exact", iterations=8 * 150, members=8)
    assert whole.converged and whole.standard_error < 1e-6
    assert abs(res.exponent - whole.exponent) <= 4 * combined_error(res, whole)


# 12 s: behind `slow`; test_henon_rk4_agrees_with_exact compares two integrators' exponents on every default run
@pytest.mark.slow
def test_an_integrator_without_a_compiled_kernel_gives_the_same_exponent():
    # scipy's DOP853 runs arc by arc through the same core. Members of 30 iterations
    # cover 10 periods of the period-3 orbit, so both give the orbit's exponent; they
    # differ by DOP853's error in the separation (about rtol relative to d0 = 1e-8:
    # 1e-2 per iteration at worst, mostly cancelling because both copies share it).
    # Measured over 600 iterations: 9.4e-6 at rtol 1e-10, 1.8e-6 at rtol 1e-12.
    p = nsbench.get_problem("two-dof", case=1, v0=0.1)
    kwargs = dict(iterations=4 * 30, members=4, workers=2)
    exact = largest_exponent(p, "exact", **kwargs)
    dop = largest_exponent(p, "scipy-dop853", options={"rtol": 1e-10, "atol": 1e-12}, **kwargs)
    assert exact.status == dop.status == "success"
    assert abs(dop.exponent - exact.exponent) < 1e-4


def test_positive_exponent_on_a_chaotic_case(chaotic, chaotic_exact):
    res = chaotic_exact
    assert res.status == "success"
    assert res.n_members == 64 and res.iterations == 64 * 156 and res.logs.shape == (64, 156)
    # exponent / standard_error is Student t with ~63 degrees of freedom: were the true
    # exponent <= 0, it would exceed 4 with probability < 1e-4. Measured about +0.077
    # with standard error 0.003 on two machines (AMD EPYC, Intel Xeon).
    assert res.exponent - 4 * res.standard_error > 0
    assert res.ci_low > 0 and res.exponent_per_time - 4 * res.standard_error_per_time > 0
    # About 1 % of the members are captured by a coexisting stable motion (exponent -0.21
    # per mapping point; 7 of 640 measured), mostly during their transient from rest: an
    # ensemble of 64 holds ~0.7 such members on average. They are set apart, so the
    # estimate is the chaotic attractor's; failing the majority rule needs 17 captures of
    # 64 where 0.7 are expected.
    assert res.converged and res.n_kept >= 0.75 * 64
    for i in res.outliers:
        assert res.members[i] < 0  # the stable motion
    kept = np.delete(res.members, list(res.outliers))
    assert (kept > 0).all()  # every kept member stretches
    # the uncertainty comes from the kept members' spread, not from one series
    assert res.standard_error == pytest.approx(np.std(kept, ddof=1) / math.sqrt(len(kept)))
    assert res.exponent_all == pytest.approx(np.mean(res.members))


def test_two_seeds_agree_within_their_uncertainty(chaotic, chaotic_exact):
    other = largest_exponent(chaotic, "exact", seed=1, workers=2)
    assert other.status == "success"
    assert not np.array_equal(other.members, chaotic_exact.members)  # really other starts
    # with honest standard errors, (a - b) / sqrt(SEa^2 + SEb^2) is about Student t
    # with ~90 degrees of freedom: |.| > 4 has probability 1e-4. Captured members (see
    # above) are set apart in both, so they do not enter the comparison. (Seed 1 has
    # one: its mean over all members is +0.066, its chaotic estimate +0.075.)
    assert other.converged
    assert abs(other.exponent - chaotic_exact.exponent) <= 4 * combined_error(other, chaotic_exact)


def test_henon_rk4_agrees_with_exact(chaotic, chaotic_exact):
    # 16 members: each runs its transient with RK4 steps of 0.01, which costs
    other = largest_exponent(chaotic, "henon-rk4", options={"h": 0.01}, iterations=4000, members=16, workers=2)
    assert other.status == "success" and other.n_members == 16
    # same margin as for two seeds: the RK4 discretisation error (event times to
    # about 1e-10) adds no visible bias at this precision
    assert other.exponent > 0
    assert abs(other.exponent - chaotic_exact.exponent) <= 4 * combined_error(other, chaotic_exact)


def test_the_result_does_not_depend_on_the_workers(chaotic):
    kwargs = dict(iterations=80, members=4, transient=200.0)
    one = largest_exponent(chaotic, "exact", workers=1, **kwargs)
    two = largest_exponent(chaotic, "exact", workers=2, **kwargs)
    assert np.array_equal(one.logs, two.logs) and one.exponent == two.exponent


def test_verdict_rule():
    # members measured on the chaotic case (seed 0): a plausible ensemble
    members = np.array([0.0669, 0.0797, 0.0816, 0.0857, 0.0730, 0.0636, 0.0733, 0.0794])
    mean, se, precise, outliers = _verdict(members, tol=0.01)
    assert mean == pytest.approx(members.mean()) and se == pytest.approx(members.std(ddof=1) / math.sqrt(8))
    assert precise and outliers == ()
    # a member on another attractor (a periodic orbit) is flagged and left out of the estimate
    chaotic = members.copy()
    members[3] = -0.12
    mean, se, precise, outliers = _verdict(members, tol=0.01)
    assert outliers == (3,) and precise
    others = np.delete(chaotic, 3)
    assert mean == pytest.approx(others.mean()) and se == pytest.approx(others.std(ddof=1) / math.sqrt(7))
    # a wide spread is not precise
    assert not _verdict(np.array([0.0, 0.1, 0.05, 0.15, -0.05]), tol=0.01)[2]
    # members of one periodic orbit agree to rounding; a difference far below the
    # tolerance is significant against that spread but not relevant
    periodic = np.full(8, -0.1205505) + 1e-10 * np.arange(8)
    periodic[0] += 1e-6
    assert _verdict(periodic, tol=0.01)[2:] == (True, ())


def test_bad_input_is_refused(chaotic):
    with pytest.raises(ConfigError, match="members"):
        largest_exponent(chaotic, members=3)
    with pytest.raises(ConfigError, match="per member"):
        largest_exponent(chaotic, iterations=100, members=8)
    with pytest.raises(ConfigError, match="no-such"):
        largest_exponent(chaotic, "no-such")


def test_lyapunov_command(capsys, tmp_path):
    import pandas as pd

    from nsbench.cli import main

    out = tmp_path / "logs.csv"
    assert (
        main(
            [
                "lyapunov",
                "two-dof",
                "--case",
                "1",
                "--param",
                "v0=0.1",
                "--iterations",
                "200",
                "--members",
                "4",
                "--seed",
                "3",
                "--out",
                str(out),
            ]
        )
        == 0
    )
    text = capsys.readouterr().out
    assert "largest Lyapunov exponent -" in text and "4 members x 50 iterations" in text and "seed 3" in text
    logs = pd.read_csv(out)
    assert list(logs.columns) == ["member", "iteration", "log_growth"] and len(logs) == 200
    assert main(["lyapunov", "two-dof", "--case", "1", "--integrator", "no-such"]) == 2
    assert main(["lyapunov", "two-dof", "--case", "1", "--members", "2"]) == 2
    assert main(["lyapunov", "two-dof", "--case", "1", "--iterations", "1e4.5"]) == 2
    assert main(["lyapunov", "two-dof", "--case", "1", "--seed", "0.5"]) == 2


@pytest.mark.parametrize("workers", [0, 1])
def test_a_whole_system_method_is_refused_once_not_per_member(workers):
    # the members are runs of the hybrid core (event-driven integrators only): one error up front,
    # in this process and with workers alike, instead of a failure per member
    problem = nsbench.get_problem("two-dof", case=2)
    with pytest.raises(ConfigError, match="switch-model is a whole-system method .*Lyapunov exponent needs"):
        largest_exponent(problem, integrator="switch-model", iterations=80, members=4, transient=10.0, workers=workers)


def test_a_problem_without_slip_events_is_refused_once():
    # the exponent is measured between mapping points (slip events): the relay system has none
    problem = nsbench.get_problem("relay-feedback")
    with pytest.raises(ConfigError, match="relay-feedback has none .its event kinds: cross"):
        largest_exponent(problem, iterations=80, members=4, transient=10.0, workers=1)


def test_a_return_map_step_that_steps_over_a_crossing_gives_no_mapping_point():
    """A step of the return map runs through the engine with simulate's check: the loose dop853 run of
    2-DOF case 3 that steps over block 1's stick near t = 25.68 (tests/test_engine.py) gives no mapping
    point (and its reason) when the integrator does not check its own steps, instead of a wrong one."""
    import dataclasses

    from nsbench.bifurcation.lyapunov import _mapping_point
    from nsbench.engine import prepare
    from nsbench.integrators.scipy_ import ScipyDOP853

    class Unchecked(ScipyDOP853):
        name = "test-lyapunov-dop853-unchecked"
        check_steps = False
        capabilities = dataclasses.replace(ScipyDOP853.capabilities, checks_steps=False)

    p = nsbench.get_problem("two-dof", case=3)
    ref = nsbench.simulate(p, "reference", 40.0).events
    slips = ref[(ref["kind"] == "slip") & (ref["t"] > 25.0)]
    for integ in (Unchecked(rtol=1e-6, atol=1e-8), nsbench.get_integrator("scipy-dop853", rtol=1e-6, atol=1e-8)):
        prepare(p, integ)
        point, status = _mapping_point(integ, p, 0.0, p.initial_state(), None, 25.0, 15.0)
        if not integ.capabilities.checks_steps:
            assert point is None and status.startswith("event missed")
        else:  # the first slip after t = 25 of the reference, to the loose tolerance
            assert point is not None and abs(point[0] - float(slips["t"].iloc[0])) < 1e-4
            assert point[3] == int(slips["block"].iloc[0])
