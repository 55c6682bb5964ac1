"""The simulate command as a Python function: a request, checked once, and one call.

:func:`nsbench.simulation.run_simulation` is what ``nsbench simulate`` runs; here it runs without
the command line, and its outcome is read against :func:`nsbench.engine.simulate` called directly
and against the files it wrote.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pandas as pd
import pytest

from nsbench.errors import ConfigError
from nsbench.simulation import SimulationRequest, run_simulation


def test_a_run_from_python_is_the_engines_run_and_writes_what_it_says(tmp_path, capsys):
    from nsbench.engine import simulate
    from nsbench.integrators import get_integrator
    from nsbench.problems import get_problem

    events = tmp_path / "events.csv"
    request = SimulationRequest(problem="two-dof", case="1", t_end="50", samples=501, events_out=str(events))
    outcome = run_simulation(request)
    assert outcome.failure is None and outcome.exit_code == 0 and outcome.written == (events,)
    # the default integrator of a linear problem, and the engine's log, event for event
    direct = simulate(get_problem("two-dof", case=1), get_integrator("exact"), 50.0, check_points=501)
    assert outcome.result is not None and outcome.result.integrator == direct.integrator
    assert outcome.result.events["kind"].tolist() == direct.events["kind"].tolist()
    np.testing.assert_array_equal(outcome.result.events["t"].to_numpy(), direct.events["t"].to_numpy())
    written = pd.read_csv(events)
    np.testing.assert_array_equal(written["t"].to_numpy(), direct.events["t"].to_numpy())  # %.17g: every bit
    printed = capsys.readouterr().out
    assert outcome.result.summary() in printed and f"events      -> {events}" in printed


def test_a_run_that_ends_short_is_the_outcomes_failure():
    # an integrator whose guard fires at every step: the core ends the run as an event storm
    from nsbench import registry
    from tests.test_engine import _AlwaysFires

    registry.register("integrators", "test-always-fires", _AlwaysFires)
    try:
        outcome = run_simulation(SimulationRequest(problem="two-dof", case=1, t_end=5, integrator="test-always-fires"))
    finally:
        registry.unregister("integrators", "test-always-fires")
    assert outcome.exit_code == 1 and outcome.result is not None and not outcome.result.ok
    assert outcome.failure is not None and outcome.failure.startswith("the run ended at t = ")
    assert outcome.failure.endswith("of 5: event storm (Zeno)") or "of 5: event storm (Zeno): " in outcome.failure


def test_a_request_is_parsed_once_from_text_or_from_values():
    text = SimulationRequest(problem="two-dof", case="2", t_end="3e2", samples="11", rtol="1e-8", options=["tol=1e-9"])
    values = SimulationRequest(
        problem="two-dof", case="2", t_end=300.0, samples=11, options={"tol": 1e-9, "rtol": 1e-8}
    )
    assert text == values and text.rtol is None  # --rtol is folded into the options
    assert dataclasses.replace(text) == text
    assert text.problem_arguments == {"case": "2", "dimensional": False}


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"t_end": "inf"}, "--t-end = inf must be a finite number"),
        ({"samples": 1}, "--samples = 1 must be >= 2"),
        ({"rtol": 0}, "--rtol = 0"),
        ({"h": 0.1, "options": {"h": 0.1}}, "--h and --option h=... are both given"),
        ({"options": {"tol": float("nan")}}, "an option value must be a finite number"),
        ({"options": ["tol"]}, "--option"),
        ({"plot": "figure.bmpx"}, "--plot figure.bmpx: extension .bmpx is not a figure format"),
        ({"setup_limit": 0}, "--setup-limit = 0"),
    ],
)
def test_a_bad_request_is_refused_at_its_construction(kwargs, message):
    with pytest.raises(ConfigError) as info:
        SimulationRequest(**{"problem": "two-dof", **kwargs})
    assert message in str(info.value)


def test_the_command_lines_defaults_are_the_requests():
    from nsbench.cli import build_parser
    from nsbench.cli.simulate import request

    args = build_parser("simulate").parse_args(["simulate", "two-dof"])
    assert request(args) == SimulationRequest(problem="two-dof")
