"""``casella-sliding``: Casella's two-state test against its exact Filippov solution (hand-derived numbers)."""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest

import nsbench
from nsbench.errors import ConfigError
from nsbench.problems.casella_sliding import CASELLA_T_END, closed_form, filippov_weight
from nsbench.testing import parametrize_with_checks
from tests.testing.test_conformance import BUILTINS

# Casella's model by hand: s = x - y, s' = -2 - 1.5 = -7/2 where x > y and 2 + 3 = 5 where x < y, so from
# (3/2, 1) the surface is reached at t1 = (1/2) / (7/2) = 1/7 in x = y = 3/2 - 2/7 = 17/14. Filippov's weight
# of the side x > y keeps s' = 0: lam (-7/2) + (1 - lam) 5 = 0, lam = 10/17, so x' = y' = lam (-2) + (1 -
# lam) 2 = -6/17 and at t = 1: 17/14 - (6/17)(6/7) = 31/34.
T1 = Fraction(1, 7)
X1 = Fraction(17, 14)
SLIDE_RATE = Fraction(-6, 17)
X_END = X1 + SLIDE_RATE * (1 - T1)
#: exact's arcs are straight lines evaluated at their ends (a few ulps); 1e-10 is the issue's bound.
BOUND = 1e-10


def test_the_hand_derivation_is_consistent():
    assert X_END == Fraction(31, 34)
    assert filippov_weight(-2.0, 2.0, -3.0, 1.5) == pytest.approx(10 / 17, rel=1e-15)


@pytest.mark.parametrize("integrator", ["exact", "reference", "exact-mp"])
def test_the_exact_solvers_meet_the_filippov_solution(integrator):
    p = nsbench.get_problem("casella-sliding")
    run = nsbench.simulate(p, integrator, CASELLA_T_END)
    assert list(run.events["kind"]) == ["slide"] and run.events["mode"].iloc[0] == "slide"
    assert abs(run.events["t"].iloc[0] - float(T1)) <= BOUND
    assert np.abs(run.events[["x", "y"]].to_numpy()[0] - float(X1)).max() <= BOUND
    assert np.abs(run.y_final - float(X_END)).max() <= BOUND


def test_the_sliding_field_is_filippovs():
    p = nsbench.get_problem("casella-sliding")
    slide = p.rhs((2,), 0.0, np.array([0.3, 0.3]))
    assert np.abs(slide - float(SLIDE_RATE)).max() <= 4 * np.finfo(float).eps
    assert p.guards((2,)) == ()  # constant fields: a trajectory that slides slides for ever


def test_a_crossing_against_the_closed_form():
    # b1 = 3: where x < y the field (2, 3) carries s on downwards (s' = -1), so the trajectory crosses
    p = nsbench.get_problem("casella-sliding", b1=3.0, x0=0.7, y0=-0.2)
    run = nsbench.simulate(p, "exact", 2.0)
    events, y_end = closed_form(p, 2.0)
    assert [k for _, k in events] == ["cross"] == list(run.events["kind"])
    assert abs(run.events["t"].iloc[0] - 0.9 / 3.5) <= BOUND and abs(events[0][0] - 0.9 / 3.5) <= 1e-15
    assert np.abs(run.y_final - y_end).max() <= BOUND


def test_bad_rates_and_starts_are_refused():
    with pytest.raises(ConfigError, match="tangent to x = y"):
        nsbench.get_problem("casella-sliding", a1=1.5)  # a1 = b2
    with pytest.raises(ConfigError, match="repelling surface"):
        nsbench.get_problem("casella-sliding", a1=2.0, a2=-2.0, b1=3.0, b2=-1.5, x0=1.0, y0=1.0)
    with pytest.raises(ConfigError, match="no cases"):
        nsbench.get_problem("casella-sliding", case=2)
    with pytest.raises(ConfigError, match="unknown parameter"):
        nsbench.get_problem("casella-sliding", z0=1.0)


@parametrize_with_checks(["exact", "reference", "ofapi", "scipy-radau", "heyoka"], problem="casella-sliding")
def test_conformance_on_casellas_sliding_test(integrator, check):
    check(integrator)


@pytest.mark.slow
@parametrize_with_checks(BUILTINS, problem="casella-sliding")
def test_builtin_conformance_on_casellas_sliding_test(integrator, check):
    """Every built-in integrator: runs the checks, or is refused at setup with its reason."""
    check(integrator)
