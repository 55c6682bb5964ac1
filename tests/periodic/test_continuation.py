"""Continuation and bifurcations against independent computations: closed form, brute force, finite differences."""

import math

import numpy as np
import pytest

from nsbench import get_problem, simulate
from nsbench.periodic import HybridFlow, continue_orbit, find_orbit, locate_target
from tests.periodic.test_shooting import _closed_form_cycle, _strobe_map_fd


def test_continued_one_dof_cycle_matches_closed_form_at_every_step():
    def problem_at(v0):
        return get_problem("one-dof", v0=v0)

    flow = HybridFlow(problem_at(1 / 12))
    branch = continue_orbit(flow, problem_at, "v0", find_orbit(flow), 1 / 12, 0.2, steps=8)
    assert branch.values[-1] == pytest.approx(0.2) and "reached" in branch.end_reason
    for value, orbit in zip(branch.values, branch.orbits):
        c = orbit.problem.coefficients
        period, _, _ = _closed_form_cycle(c.c[0], c.k[0], c.fs[0], c.fr[0], value)
        assert orbit.period == pytest.approx(period, rel=1e-11)
    assert not branch.bifurcations


def _case1(v0):
    return get_problem("two-dof", case=1, v0=v0)


@pytest.fixture(scope="module")
def grazing():
    """Where block 2's sticking phase vanishes as v0 grows (case 1): the end of the (slip2, stick2) branch."""
    return locate_target(_case1, "v0", 0.16, 0.27, 0.28, steps=40)


def _sticks(v0, orbit, periods):
    """Stick events of block 2 in the last 20 periods of a brute-force run at ``v0`` started on ``orbit``."""
    res = simulate(_case1(v0), "exact", orbit.t0 + periods * orbit.period, t0=orbit.t0, y0=orbit.y0)
    late = res.events[res.events["t"] > orbit.t0 + (periods - 20) * orbit.period]
    return int(((late["kind"] == "stick") & (late["block"] == 2)).sum())


def test_grazing_is_located_to_1e8_against_brute_force(grazing):
    bif, orbit = grazing
    assert bif.kind == "grazing-sliding" and bif.category == "sliding"
    assert orbit.pattern == ("slip2", "stick2") and orbit.stable
    v_near = orbit.problem.parameters["v0"]
    assert 0 < bif.value - v_near < 1e-10
    # Independent check: long runs of the exact solver from the orbit nearest the grazing,
    # 2e-9 on either side. Below, block 2 keeps sticking once per period; above, its velocity
    # no longer reaches the belt speed and the sticking stops (the motion decays to sliding).
    # (The orbit's basin shrinks to nothing at the grazing, so the runs start on it.)
    assert _sticks(bif.value - 2e-9, orbit, 200) == 20
    assert _sticks(bif.value + 2e-9, orbit, 200) == 0


def test_grazing_value_does_not_depend_on_the_step_size(grazing):
    other, _ = locate_target(_case1, "v0", 0.16, 0.27, 0.28, steps=13)
    assert abs(other.value - grazing[0].value) < 1e-9


def test_period_doubling_multiplier_is_minus_one_by_finite_differences():
    """Case 2 along v0: a period doubling near 0.362 (the paper's fixed-point bifurcation near 0.35)."""

    def problem_at(v0):
        return get_problem("two-dof", case=2, v0=v0)

    bif, orbit = locate_target(problem_at, "v0", 0.3, 0.35, 0.37, steps=20, kind="period-doubling")
    assert bif.category == "fixed-point"
    flow = HybridFlow(problem_at(bif.value))
    from nsbench.periodic import shoot

    at = shoot(flow, orbit.t0, orbit.y0, orbit.mode0, orbit.period)
    # independent of the saltation product: eigenvalues of the finite-difference period map
    fd = np.linalg.eigvals(_strobe_map_fd(flow, at, eps=1e-6))
    assert np.min(np.abs(fd + 1.0)) < 1e-6
    assert at.forcing_periods == 1 and math.isclose(at.period, 2 * math.pi, rel_tol=1e-14)


def test_fold_at_a_branch_end_is_located_from_the_multiplier():
    """Case 1 along r_f: the branch from rest at 0.8 turns back (a multiplier reaches +1) near 0.8616.

    Near a fold Newton's region shrinks like the square root of the distance, so the
    first failing step says little; the end is found where (1 - mu)^2, linear in the
    parameter, reaches zero. Two step sizes must give the same value.
    """

    def problem_at(r_f):
        return get_problem("two-dof", case=1, r_f=r_f)

    a, near = locate_target(problem_at, "r_f", 0.8, 0.86, 0.8625, steps=17, kind="fold")
    b, _ = locate_target(problem_at, "r_f", 0.8, 0.86, 0.8625, steps=40, kind="fold")
    assert a.kind == b.kind == "fold" and a.category == "fixed-point"
    assert abs(a.value - b.value) < 1e-9
    assert np.min(np.abs(near.multipliers - 1.0)) < 1e-2


def test_branch_switching_at_a_period_doubling_follows_the_doubled_orbit():
    """Case 2 along v0: past the period doubling near 0.3624 the doubled orbit exists and is followed."""
    from nsbench.periodic import double

    def problem_at(v0):
        return get_problem("two-dof", case=2, v0=v0)

    bif, near = locate_target(problem_at, "v0", 0.3, 0.35, 0.37, steps=20, kind="period-doubling")
    flow = HybridFlow(problem_at(bif.value))
    past = bif.value + 1e-3
    doubled = double(flow, problem_at, bif, near, past)
    assert doubled is not None and doubled.forcing_periods == 2
    # two distinct stroboscopic points, a period apart, that swap: not the single orbit run twice
    half = flow.run(doubled.t0, doubled.y0, doubled.mode0, 0.5 * doubled.period)
    gap = float(np.max(np.abs(half.y - doubled.y0)))
    assert gap > 1e-4
    back = flow.run(doubled.t0, doubled.y0, doubled.mode0, doubled.period)
    assert float(np.max(np.abs(back.y - doubled.y0))) < 1e-10
    # just past a supercritical doubling the doubled orbit is the stable one
    assert doubled.stable
