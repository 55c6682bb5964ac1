"""Sections by the problem's own state names, declared rates and field (``nsbench.sections``)."""

from __future__ import annotations

import numpy as np
import pytest

import nsbench
from nsbench.errors import ConfigError
from nsbench.sections import peak_variables, peaks, rate_on_field, rate_state

# The positions whose rate is a state, read off each problem's equations (its problem sheet in
# docs/problems.md): x_i' = v_i for the blocks and the ball, q' = dq for the woodpecker's coordinates,
# x' = px and y' = py for Henon-Heiles' Hamiltonian. The relay and the sliding tests are first-order
# systems whose rates are no state of theirs.
PAIRS = {
    "two-dof": (("x1", "v1"), ("x2", "v2")),
    "one-dof": (("x1", "v1"),),
    "bouncing-ball": (("x", "v"),),
    "impact-oscillator": (("x", "v"),),
    "henon-heiles": (("x", "px"), ("y", "py")),
    "woodpecker": (("y", "dy"), ("phiM", "dphiM"), ("phiS", "dphiS")),
    "relay-feedback": (),
    "casella-sliding": (),
    "circle-oscillator": (),
}


@pytest.mark.parametrize("name", sorted(PAIRS))
def test_positions_and_rates_are_declared_and_found_on_the_field(name):
    problem = nsbench.get_problem(name)
    assert peak_variables(problem) == PAIRS[name]  # from the declaration
    on_field = tuple((n, r) for n in problem.state_names if (r := rate_on_field(problem, n)) is not None)
    assert on_field == PAIRS[name]


def test_a_problem_that_declares_nothing_has_its_rates_found_on_the_field(monkeypatch):
    # a plug-in that leaves position_rates None: the field decides, as before the declaration
    problem = nsbench.get_problem("henon-heiles")
    monkeypatch.setattr(problem, "position_rates", None)
    assert peak_variables(problem) == PAIRS["henon-heiles"]


def test_a_declaration_is_read_without_running_the_field(monkeypatch):
    problem = nsbench.get_problem("two-dof")

    def refuse(*args):
        raise AssertionError("the field ran")

    monkeypatch.setattr(problem, "rhs", refuse)
    assert peak_variables(problem) == PAIRS["two-dof"]


def test_a_name_alone_does_not_make_a_rate():
    # relay-feedback's x2 sits where a velocity would (index 1) but x1' = -(2 zeta omega + lambda) x1 + x2 + ...
    problem = nsbench.get_problem("relay-feedback")
    assert rate_state(problem, "x1") is None
    with pytest.raises(ConfigError, match="unknown state variable 'v1'; allowed: x1, x2, x3"):
        rate_state(problem, "v1")


def test_peaks_is_the_rate_of_the_position_crossing_zero_downward():
    hh = nsbench.get_problem("henon-heiles")
    section = peaks(hh)
    assert section.name == "peaks_x" and section.coeffs == (0.0, 0.0, 1.0, 0.0) and section.direction == -1
    assert peaks(hh, 2).name == "peaks_y"
    res = nsbench.simulate(hh, "henon-rk4", 60.0, sections=[section])
    hits = res.sections
    assert len(hits) >= 5 and np.abs(hits["px"]).max() <= 1e-8  # px = x' vanishes there
    # a maximum of x: x'' = px' = -x - 2 x y < 0 at every recorded point
    assert (-hits["x"] - 2 * hits["x"] * hits["y"] < 0).all()
    with pytest.raises(ConfigError, match="peaks of position 3: henon-heiles has 2 .x, y."):
        peaks(hh, 3)


def test_a_problem_without_a_position_is_refused_naming_its_states():
    with pytest.raises(ConfigError, match=r"no state of relay-feedback \(x1, x2, x3\) has its rate among the states"):
        peaks(nsbench.get_problem("relay-feedback"))
