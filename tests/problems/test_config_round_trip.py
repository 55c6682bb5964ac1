"""Every registered problem is rebuilt whole from its config, at every case it names (issue 48, item 1).

Bench workers, stored cases and references and resumed runs carry ``problem.config()`` and rebuild the
problem with ``problem_from_config``: a config that loses a case or an override runs another problem
under the same label (the relay's ``piiroinen-kuznetsov`` case came back as the default relay).
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

import nsbench
from nsbench.errors import ConfigError
from nsbench.problems import list_problems, problem_from_config


def _rebuilt(p):
    """The problem its config rebuilds, through JSON text (as the bench stores it)."""
    return problem_from_config(json.loads(json.dumps(p.config())))


def _same(p, q) -> None:
    assert q.name == p.name
    # equal_nan: the woodpecker marks its singular impulse matrices with NaN slots, rebuilt as NaN
    assert np.array_equal(np.asarray(q.packed, float), np.asarray(p.packed, float), equal_nan=True), (p, p.config())
    assert np.array_equal(np.asarray(q.initial_state(), float), np.asarray(p.initial_state(), float)), p
    assert q.config() == p.config()


def _variants():
    """Every registered problem at its default and at every case it names, in each unit system it accepts."""
    out = []
    for name in list_problems():
        first = nsbench.get_problem(name)
        for case in (None, *first.cases):
            for dimensional in (False, True):
                try:
                    nsbench.get_problem(name, case=case, dimensional=dimensional)
                except ConfigError:
                    continue
                out.append(pytest.param(name, case, dimensional, id=f"{name}-{case}-{'dim' if dimensional else 'nd'}"))
    return out


def test_the_problems_with_presets_name_them():
    # the list the round trip walks: a problem that names no case would be checked at its default only
    assert nsbench.get_problem("relay-feedback").cases == (
        1,
        "siconos-sliding",
        "siconos-multisliding",
        "piiroinen-kuznetsov",
    )
    assert nsbench.get_problem("one-dof").cases == (1, 2, 3, 4, "leine")
    assert nsbench.get_problem("two-dof").cases == (1, 2, 3, 4)
    assert nsbench.get_problem("chain", n=3).cases == (1, 2, 3, 4)
    assert nsbench.get_problem("bouncing-ball").cases == ()


@pytest.mark.parametrize("name, case, dimensional", _variants())
def test_every_case_of_every_problem_survives_its_config(name, case, dimensional):
    p = nsbench.get_problem(name, case=case, dimensional=dimensional)
    _same(p, _rebuilt(p))


def test_the_relay_case_that_was_lost():
    p = nsbench.get_problem("relay-feedback", case="piiroinen-kuznetsov")
    assert p.config() == {"name": "relay-feedback", "case": "piiroinen-kuznetsov", "dimensional": False, "params": {}}
    q = _rebuilt(p)
    assert q.parameters["omega"] == 25.0 and q.parameters["lam"] == 1.0  # the case's values, not the defaults
    assert q.parameters == p.parameters
    # an override on top of a case is kept with it
    p = nsbench.get_problem("relay-feedback", case="siconos-multisliding", lam=0.5, x2_0=0.25)
    q = _rebuilt(p)
    assert q.parameters["omega"] == 8.0 and q.parameters["lam"] == 0.5 and q.initial_state()[1] == 0.25


@st.composite
def _overridden(draw):
    """A registered problem at one of its cases with one of its numeric parameters scaled."""
    name = draw(st.sampled_from(list_problems()))
    first = nsbench.get_problem(name)
    case = draw(st.sampled_from((None, *first.cases)))
    base = nsbench.get_problem(name, case=case)
    names = sorted(
        k for k, v in base.parameters.items() if isinstance(v, float) and math.isfinite(v) and not isinstance(v, bool)
    )
    param = draw(st.sampled_from(names))
    factor = draw(st.floats(0.5, 1.5, allow_nan=False))
    return name, case, param, base.parameters[param] * factor


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(_overridden())
def test_a_parameter_override_on_any_case_survives_the_config(drawn):
    name, case, param, value = drawn
    try:
        p = nsbench.get_problem(name, case=case, **{param: value})
    except ConfigError:  # out of the parameter's range, or a derived value the factory takes no override of
        assume(False)
    _same(p, _rebuilt(p))
    assert _rebuilt(p).params == p.params


def test_the_conformance_kit_checks_it_for_any_problem():
    from nsbench.testing import check_problem
    from nsbench.testing._problem import config_round_trip, variants

    for name in list_problems():
        assert config_round_trip(name) == [], name
    check_problem({"name": "chain", "n": 3})
    # the kit walks every case the relay names, in both unit systems where accepted, with overrides
    labels = {(p.case, tuple(sorted(p.params))) for p in variants("relay-feedback")}
    assert {c for c, _ in labels} >= {None, 1, "siconos-sliding", "siconos-multisliding", "piiroinen-kuznetsov"}
    assert any(params for _, params in labels)


def test_the_kit_finds_a_problem_that_loses_its_case(monkeypatch):
    """The check can fail: a problem whose config drops its case (as the relay's did) is reported."""
    from nsbench.problems.relay_feedback import RelayFeedback
    from nsbench.testing import check_problem

    monkeypatch.setattr(RelayFeedback, "config", lambda self: {**_config_of(self), "case": None})
    with pytest.raises(AssertionError, match="piiroinen-kuznetsov.*parameter vector"):
        check_problem("relay-feedback")


def test_the_kit_finds_rates_its_field_contradicts(monkeypatch):
    """A declared rate the field does not confirm (v for x of the impact oscillator, swapped) is reported,
    and so is a position the field has that the declaration leaves out."""
    from nsbench.problems.impact_oscillator import ImpactOscillator
    from nsbench.testing import check_problem
    from nsbench.testing._problem import rates_failure

    assert rates_failure(nsbench.get_problem("impact-oscillator")) is None
    original = ImpactOscillator.__init__

    def init(self, *args, **kwargs):
        original(self, *args, **kwargs)
        self.position_rates = {"v": "x"}

    monkeypatch.setattr(ImpactOscillator, "__init__", init)
    with pytest.raises(AssertionError, match=r"position_rates declares \{'v': 'x'\}, its field gives \{'x': 'v'\}"):
        check_problem("impact-oscillator")
    problem = nsbench.get_problem("impact-oscillator")
    problem.position_rates = {}
    assert "its field gives {'x': 'v'}" in rates_failure(problem)
    problem.position_rates = {"x": "w"}
    assert "name w, not states (x, v)" in rates_failure(problem)


def _config_of(problem):
    from nsbench.problems.base import HybridProblem

    return HybridProblem.config(problem)
