"""``circle-oscillator``: nosnoc's oscillator with a circular switching surface against its closed form."""

from __future__ import annotations

import math

import numpy as np
import pytest

import nsbench
from nsbench.errors import ConfigError, UnsupportedProblemError
from nsbench.integrators import get_integrator
from nsbench.problems.circle_oscillator import NOSNOC_T_END, closed_form, crossing_time
from nsbench.testing import parametrize_with_checks
from tests.testing.test_conformance import BUILTINS

#: nosnoc_py's exact solution at its TSIM = pi / 2 (examples/oscillator: X_SOL), written out here:
#: the start (exp(-1), 0) spirals out counter-clockwise, e^t Rot(2 pi t), to (1, 0) at t = 1, then
#: clockwise, e^(t - 1) Rot(-2 pi (t - 1)) (1, 0).
_S = NOSNOC_T_END - 1.0
X_SOL = np.array([math.exp(_S) * math.cos(2 * math.pi * _S), -math.exp(_S) * math.sin(2 * math.pi * _S)])
#: reference is heyoka in quad precision: its doubles are correct to an ulp or two; 1e-10 is the issue's bound.
BOUND = 1e-10


@pytest.mark.parametrize("integrator", ["reference", "heyoka-q"])
def test_reference_meets_nosnocs_exact_solution(integrator):
    p = nsbench.get_problem("circle-oscillator")
    run = nsbench.simulate(p, integrator, NOSNOC_T_END)
    assert list(run.events["kind"]) == ["cross"] and run.events["mode"].iloc[0] == "outside"
    assert abs(run.events["t"].iloc[0] - 1.0) <= BOUND
    assert np.abs(run.events[["x1", "x2"]].to_numpy()[0] - [1.0, 0.0]).max() <= BOUND
    assert np.abs(run.y_final - X_SOL).max() <= BOUND
    assert np.abs(closed_form(p, NOSNOC_T_END) - X_SOL).max() <= 1e-14


def test_another_start_and_rate_against_the_closed_form():
    p = nsbench.get_problem("circle-oscillator", omega=3.0, radius=1.5, x1_0=0.3, x2_0=-0.4)
    t1 = math.log(1.5 / 0.5)  # |x0| = 0.5 grows as e^t to the radius
    assert crossing_time(p) == pytest.approx(t1, rel=1e-15)
    run = nsbench.simulate(p, "reference", 2.0)
    assert abs(run.events["t"].iloc[0] - t1) <= BOUND
    assert np.abs(run.y_final - closed_form(p, 2.0)).max() <= BOUND * math.exp(2.0)


def test_every_crossing_is_outwards():
    # x . A x = |x|^2 on both sides: the radius grows whichever field acts, so a start outside never returns
    p = nsbench.get_problem("circle-oscillator", x1_0=1.2)
    run = nsbench.simulate(p, "reference", 1.0)
    assert len(run.events) == 0
    assert np.abs(run.y_final - closed_form(p, 1.0)).max() <= BOUND * math.e


@pytest.mark.parametrize("name", ["exact", "exact-mp"])
def test_the_closed_form_solvers_refuse_the_quadratic_guard(name):
    integ = get_integrator(name)
    with pytest.raises(UnsupportedProblemError, match="circular switching surface"):
        integ.setup(nsbench.get_problem("circle-oscillator"))


def test_bad_values_are_refused():
    with pytest.raises(ConfigError, match="equilibrium"):
        nsbench.get_problem("circle-oscillator", x1_0=0.0, x2_0=0.0)
    with pytest.raises(ConfigError, match="radius"):
        nsbench.get_problem("circle-oscillator", radius=0.0)


@parametrize_with_checks(["reference", "ofapi", "scipy-radau", "heyoka", "exact"], problem="circle-oscillator")
def test_conformance_on_the_circle_oscillator(integrator, check):
    check(integrator)


@pytest.mark.slow
@parametrize_with_checks(BUILTINS, problem="circle-oscillator")
def test_builtin_conformance_on_the_circle_oscillator(integrator, check):
    """Every built-in integrator: runs the checks, or is refused at setup with its reason."""
    check(integrator)


def test_the_kit_runs_it_to_e_cubed_past_the_crossing_and_other_problems_sixty_time_scales():
    """The radius grows as e^t: the kit's span ends where it is e^3 times the circle's (from the closed
    form), not at the default 60 time scales (e^59)."""
    from nsbench.problems.base import CHECK_TIME_SCALES

    p = nsbench.get_problem("circle-oscillator")
    assert p.check_span == pytest.approx(crossing_time(p) + 3.0, abs=1e-15) and p.check_span == pytest.approx(4.0)
    radius = float(np.hypot(*closed_form(p, p.check_span)))
    assert radius == pytest.approx(math.exp(3.0) * p.radius, rel=1e-13)
    outside = nsbench.get_problem("circle-oscillator", x1_0=1.2)  # no crossing: three time units
    assert outside.check_span == 3.0
    for name in ("casella-sliding", "bouncing-ball", "relay-feedback"):
        other = nsbench.get_problem(name)
        assert other.check_span == CHECK_TIME_SCALES * other.time_scale


def test_the_kit_takes_the_span_the_problem_declares():
    from nsbench.testing._checks import _span, checking_on

    with checking_on("circle-oscillator"):
        assert _span(nsbench.get_problem("circle-oscillator"), 60.0) == pytest.approx(4.0)
    with checking_on("two-dof"):  # on the belt's presets the check's own span
        assert _span(nsbench.get_problem("two-dof"), 60.0) == 60.0
