"""Continuation of the piecewise-linear problems' periodic orbits: the impact oscillator through its
grazing (closed form ``sigma = A``) and the relay through its sliding bifurcation (closed form
``relay_feedback.sliding_bifurcation``)."""

import numpy as np
import pytest

from nsbench import get_problem
from nsbench.periodic import HybridFlow, continue_orbit, find_orbit, shoot
from nsbench.problems.relay_feedback import sliding_bifurcation, symmetric_orbit

#: nsbench's own values (not from Nordmark 1991): a one-impact orbit per forcing period that is
#: stable from sigma = 0.5 A up to a period doubling just before it grazes (docs/problems.md).
IMPACT = {"zeta": 0.05, "F": 1.0, "w": 2.0, "r": 0.8}
XTOL = 1e-11  # the locator's bisection bracket (continue_orbit's default)


def _impact(sigma, **extra):
    return get_problem("impact-oscillator", **IMPACT, sigma=sigma, **extra)


def _grazing(branch):
    found = [b for b in branch.bifurcations if b.kind == "grazing"]
    assert len(found) == 1, [(b.kind, b.value) for b in branch.bifurcations]
    return found[0]


def test_non_impacting_orbit_ends_at_the_closed_form_grazing():
    base = _impact(1.0)
    a = base.grazing_stop()
    x0, v0 = base.free_orbit(0.0)
    start = {"x0": float(x0), "v0": float(v0)}  # on the closed-form orbit: no transient needed

    def at(sigma):
        return _impact(sigma, **start)

    flow = HybridFlow(at(1.2 * a))
    orbit = find_orbit(flow, transient=0.0)
    x, v = base.free_orbit(orbit.t0)
    assert orbit.pattern == () and np.max(np.abs(orbit.y0 - [x, v])) <= 1e-12
    branch = continue_orbit(flow, at, "sigma", orbit, 1.2 * a, 0.5 * a, steps=12)
    bif = _grazing(branch)
    assert bif.category == "grazing" and "branch ends" in bif.detail
    # the non-impacting orbit's gap sigma - A is linear in sigma: bisection and secant end within
    # the bracket, and the integrator decides a graze to rounding of x (a few ulp of A)
    assert abs(bif.value - a) <= XTOL + 8 * np.spacing(a)


def test_impacting_orbit_from_simulation_grazes_at_the_closed_form_value():
    a = _impact(1.0).grazing_stop()

    def at(sigma):
        return _impact(sigma)

    flow = HybridFlow(at(0.5 * a))
    orbit = find_orbit(flow)  # the orbit the motion from rest settles on
    assert orbit.pattern == ("impact1",) and orbit.forcing_periods == 1 and orbit.stable
    branch = continue_orbit(flow, at, "sigma", orbit, 0.5 * a, 1.05 * a, steps=21)
    kinds = [b.kind for b in branch.bifurcations]
    assert kinds == ["period-doubling", "grazing"], kinds
    bif = _grazing(branch)
    # Newton stops short of the graze (an impact's saltation grows like 1/speed); the end is the
    # secant zero of the impact speed, linear in sigma there, from that distance (bif.bracket):
    # its error is the speed's departure from linearity over the secant, a few per cent of it.
    assert bif.bracket < 1e-8
    assert abs(bif.value - a) <= 0.1 * bif.bracket + XTOL
    # speeds fall to zero towards the graze along the stable part of the branch
    speeds = [abs(o.events[0].y[1]) for o in branch.orbits if o.pattern == ("impact1",)]
    assert speeds[-1] < 1e-2 and all(np.diff(speeds[:-1]) < 0)


def test_impacting_orbit_is_the_orbit_a_simulation_settles_on():
    a = _impact(1.0).grazing_stop()
    problem = _impact(0.7 * a)
    flow = HybridFlow(problem)
    start, mode = problem.initial_state(), problem.initial_mode(0.0, problem.initial_state())
    period = 2 * np.pi / problem.w
    settled = flow.run(0.0, start, mode, 400 * period)  # contraction 0.684 per period: 1e-66 left
    guess = settled.y + np.array([1e-3, -1e-3])  # Newton from a point off the orbit
    orbit = shoot(flow, 400 * period, guess, settled.mode, period)
    assert orbit.pattern == ("impact1",) and orbit.stable
    assert np.max(np.abs(orbit.y0 - settled.y)) <= 1e-10


def test_impact_jacobian_matches_central_differences():
    problem = _impact(0.7 * _impact(1.0).grazing_stop())
    flow = HybridFlow(problem)
    orbit = find_orbit(flow)
    p = flow.run(orbit.t0, orbit.y0, orbit.mode0, orbit.period)
    jac = flow.jacobian(p)
    h = 1e-6
    fd = np.column_stack(
        [
            (
                flow.run(orbit.t0, orbit.y0 + h * e, orbit.mode0, orbit.period).y
                - flow.run(orbit.t0, orbit.y0 - h * e, orbit.mode0, orbit.period).y
            )
            / (2 * h)
            for e in np.eye(2)
        ]
    )
    # central differences: O(h^2) truncation and O(eps / h) rounding, both below 1e-8 here
    assert np.max(np.abs(jac - fd)) <= 1e-7 * (1 + np.max(np.abs(jac)))


def test_relay_sliding_bifurcation_by_continuation_matches_the_closed_form():
    def at(lam):
        return get_problem("relay-feedback", lam=lam)

    flow = HybridFlow(at(0.06))
    orbit = find_orbit(flow, transient=600.0, window=200.0)
    x2, x3, period = symmetric_orbit(at(0.06), (1.06, 1.6, 5.2))
    assert orbit.pattern == ("cross1", "cross1") and abs(orbit.period - period) <= 1e-9
    branch = continue_orbit(flow, at, "lam", orbit, 0.06, 0.04, steps=10)
    assert [b.kind for b in branch.bifurcations] == ["crossing-sliding"]
    bif = branch.bifurcations[0]
    assert bif.category == "sliding" and "slide1" in bif.right_pattern + bif.left_pattern
    lam_star, _, _ = sliding_bifurcation((0.0487, 1.62, 5.27))
    # the bracket (<= xtol) plus the closed form's own error: its three equations are solved to a
    # residual of 1e-12 with a Jacobian of order one, so lam* is good to about 1e-11
    assert bif.bracket <= XTOL
    assert abs(bif.value - lam_star) <= bif.bracket + 1e-10
    assert branch.orbits[-1].pattern == ("exit1", "slide1", "exit1", "slide1")


def test_a_symmetric_orbit_is_started_off_its_switching_surface():
    # The relay's symmetric orbit has two arcs of one half-period each. The guess starts at a crossing,
    # and the arcs before its first and after its last event were taken for the two halves of one arc
    # through the start: their "middle" was the crossing itself, the start sat on x1 = 0, and every
    # continuation step from it stalled in Newton (two spurious branch ends near lam = 0.052, found
    # with transient 300; other transients happened to start elsewhere).
    def at(lam):
        return get_problem("relay-feedback", lam=lam)

    flow = HybridFlow(at(0.052))
    orbit = find_orbit(flow, transient=300.0, window=200.0)
    first = min(e.t for e in orbit.events) - orbit.t0
    # the middle of an arc: a quarter period from the next crossing (to the shooting's precision)
    assert abs(first - orbit.period / 4) <= 1e-9 * orbit.period
    assert abs(orbit.y0[0]) > 0.1
    branch = continue_orbit(flow, at, "lam", orbit, 0.052, 0.046, steps=3)
    assert branch.end_reason == "reached lam = 0.046"
    assert [b.kind for b in branch.bifurcations] == ["crossing-sliding"]
    lam_star, _, _ = sliding_bifurcation((0.0487, 1.62, 5.27))
    assert abs(branch.bifurcations[0].value - lam_star) <= branch.bifurcations[0].bracket + 1e-10


@pytest.mark.parametrize("name", ["henon-heiles", "bouncing-ball"])
def test_a_problem_without_event_linearisation_is_refused(name):
    from nsbench.errors import ConfigError

    with pytest.raises(ConfigError, match="piecewise-linear"):
        HybridFlow(get_problem(name))


# 22 s: behind `slow`; the tests above continue both problems through the API, and
# tests/cli/test_continuation.py runs the command on every default run
@pytest.mark.slow
def test_the_command_line_continues_both_problems(tmp_path, capsys):
    import pandas as pd

    from nsbench.cli import main

    impact = ["--param", "zeta=0.05", "--param", "w=2", "--param", "r=0.8", "--sweep", "sigma=0.3:0.36"]
    runs = {  # short ranges across each bifurcation (A = 0.3326, lam* = 0.04869)
        "impact-oscillator": [*impact, "--steps", "6", "--no-doubling"],
        "relay-feedback": ["--sweep", "lam=0.052:0.046", "--steps", "3", "--transient", "300"],
    }
    for problem, args in runs.items():
        out = tmp_path / problem
        code = main(["continuation", problem, *args, "--out", str(out), "--formats", "png", "--no-progress"])
        assert code == 0 and (out / "branches.png").is_file()
        bifs = pd.read_csv(out / "bifurcations.csv")
        assert {"grazing": "impact-oscillator", "crossing-sliding": "relay-feedback"}.keys() & set(bifs["kind"])
    text = capsys.readouterr().out
    assert "grazing (grazing)" in text and "crossing-sliding (sliding)" in text
