"""Periodic orbits by shooting: a closed-form 1-DOF stick-slip cycle, multipliers against finite differences."""

import math

import mpmath
import numpy as np
import pytest

from nsbench import get_problem
from nsbench.periodic import HybridFlow, ShootingError, find_orbit, shoot


def _closed_form_cycle(c, k, fs, fr, v0, digits=40):
    """The 1-DOF stick-slip cycle (m = 1) in closed form, to ``digits`` digits (independent of nsbench).

    The block leaves the belt where the spring and damper reach the static limit,
    ``x_s = (fr - c v0) / k``, with ``v = v0``; it slips with friction ``+fs`` (``v < v0``):
    ``x'' + c x' + k x = fs``, an underdamped oscillation about ``fs / k``, until ``v = v0``
    again at ``t1``; then it sticks and moves with the belt until ``x = x_s``.
    """
    mp = mpmath.mp
    mp.dps = digits
    c, k, fs, fr, v0 = (mpmath.mpf(x) for x in (c, k, fs, fr, v0))
    xs = (fr - c * v0) / k
    a = c / 2
    wd = mpmath.sqrt(k - a * a)
    A = xs - fs / k
    B = (v0 + a * A) / wd

    def x(t):
        return fs / k + mpmath.e ** (-a * t) * (A * mpmath.cos(wd * t) + B * mpmath.sin(wd * t))

    def v(t):
        return mpmath.e ** (-a * t) * ((B * wd - a * A) * mpmath.cos(wd * t) - (a * B + A * wd) * mpmath.sin(wd * t))

    # v dips below v0 right after the slip (x'' = fs - fr < 0 there) and comes back within one
    # damped period: the first sign change of v - v0 on a fine grid, then bisection to 40 digits
    grid = [2 * mpmath.pi / wd * j / 2000 for j in range(1, 2001)]
    lo = next(t for t, t_next in zip(grid, grid[1:]) if v(t) < v0 <= v(t_next))
    t1 = mpmath.findroot(lambda t: v(t) - v0, (lo, lo + 2 * mpmath.pi / wd / 2000), solver="bisect")
    stick = (xs - x(t1)) / v0
    return float(t1 + stick), float(x(t1)), float(xs)


def test_one_dof_stick_slip_cycle_matches_closed_form():
    problem = get_problem("one-dof")
    c = problem.coefficients
    period, x_stick, x_slip = _closed_form_cycle(c.c[0], c.k[0], c.fs[0], c.fr[0], c.v0)
    orbit = find_orbit(HybridFlow(problem))
    assert orbit.pattern == ("slip1", "stick1")
    assert orbit.period == pytest.approx(period, rel=1e-12)
    stick = next(e for e in orbit.events if e.kind == "stick")
    slip = next(e for e in orbit.events if e.kind == "slip")
    assert stick.y[0] == pytest.approx(x_stick, abs=1e-12)
    assert slip.y[0] == pytest.approx(x_slip, abs=1e-12)
    # the stick phase forgets every perturbation: the one nontrivial multiplier is zero
    assert orbit.multipliers.size == 1 and abs(orbit.multipliers[0]) < 1e-12
    assert orbit.stable


def _strobe_map_fd(flow, orbit, eps=1e-6):
    """Finite-difference Jacobian of the period map at the orbit's start (free components)."""
    free = orbit.free
    cols = []
    for j in free:
        d = np.zeros_like(orbit.y0)
        d[j] = eps
        plus = flow.run(orbit.t0, orbit.y0 + d, orbit.mode0, orbit.period).y
        minus = flow.run(orbit.t0, orbit.y0 - d, orbit.mode0, orbit.period).y
        cols.append(((plus - minus) / (2 * eps))[free])
    return np.array(cols).T


def test_forced_orbit_multipliers_match_finite_differences():
    problem = get_problem("two-dof", case=2)
    flow = HybridFlow(problem)
    orbit = find_orbit(flow)
    assert orbit.forced and orbit.forcing_periods >= 1
    assert orbit.period == pytest.approx(orbit.forcing_periods * 2 * math.pi / problem.coefficients.w, rel=1e-14)
    again = flow.run(orbit.t0, orbit.y0, orbit.mode0, orbit.period)
    assert np.max(np.abs(again.y - orbit.y0)) < 1e-10
    fd = np.linalg.eigvals(_strobe_map_fd(flow, orbit))
    mine = orbit.multipliers
    assert len(fd) == len(mine)
    for z in mine:
        assert np.min(np.abs(fd - z)) < 1e-6


def test_autonomous_orbit_multipliers_match_finite_differences():
    """Autonomous: the nontrivial multipliers are the FD monodromy's eigenvalues other than the trivial 1."""
    problem = get_problem("two-dof", case=1, v0=0.17)
    flow = HybridFlow(problem)
    orbit = find_orbit(flow)
    fd = np.linalg.eigvals(_strobe_map_fd(flow, orbit))
    trivial = int(np.argmin(np.abs(fd - 1.0)))
    assert abs(fd[trivial] - 1.0) < 1e-6  # the flow direction
    rest = np.delete(fd, trivial)
    for z in orbit.multipliers:
        assert np.min(np.abs(rest - z)) < 1e-6
    assert orbit.multipliers.size == rest.size


def test_steady_sliding_has_no_orbit():
    problem = get_problem("two-dof", case=1, v0=0.25)  # from rest the motion settles to steady sliding
    with pytest.raises(ShootingError, match="steady sliding"):
        find_orbit(HybridFlow(problem))


def test_shooting_reduces_to_the_shortest_period():
    problem = get_problem("one-dof")
    flow = HybridFlow(problem)
    orbit = find_orbit(flow)
    tripled = shoot(flow, orbit.t0, orbit.y0 + 1e-4, orbit.mode0, 3 * orbit.period * (1 + 1e-5))
    assert tripled.period == pytest.approx(orbit.period, rel=1e-12)
