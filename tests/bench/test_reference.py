"""The conditioning of a case, measured by the reference, checked with an independent integrator."""

from __future__ import annotations

import math

import pytest

from nsbench.bench.reference import DOUBLE_GRADABLE, conditioning
from nsbench.engine import simulate
from nsbench.problems import get_problem

# A forced linear point that amplifies a change of its start strongly (found in a reliability study)
STIFF = dict(F=0.517, Omega=0.767, omega_r=7.2, v0=0.314, r_f=0.81)
HEYOKA_Q = {"name": "heyoka-q", "options": {"tol": 1e-25}}


def _cond(problem, config):
    events = simulate(problem, config["name"], 300.0, options=config.get("options")).events
    return conditioning(problem, config, 0.0, 300.0, events)


@pytest.mark.parametrize("params", [{}, STIFF])
def test_exact_and_quad_taylor_measure_the_same_conditioning(params):
    # two independent solvers (closed form in double, Taylor series in quad precision) of the same
    # perturbed problem: their amplification factors agree to well within the 1e-9 perturbation's
    # nonlinearity (relative 1e-3)
    problem = get_problem("two-dof", case=2, **params)
    a, note_a = _cond(problem, {"name": "exact", "options": {}})
    b, note_b = _cond(problem, HEYOKA_Q)
    assert note_a == note_b == "" and math.isfinite(a) and math.isfinite(b)
    assert abs(a - b) <= 1e-3 * b


def test_the_stiff_point_cannot_be_graded_in_double_and_the_standard_case_can():
    eps = 2.220446049250313e-16
    standard, _ = _cond(get_problem("two-dof", case=2), {"name": "exact", "options": {}})
    stiff, _ = _cond(get_problem("two-dof", case=2, **STIFF), {"name": "exact", "options": {}})
    assert standard * eps < 1e-13 < DOUBLE_GRADABLE < stiff * eps


def test_a_changed_event_sequence_is_infinite_conditioning():
    # moving the start by 1e-9 cannot change the sequence of a well-conditioned case; the check
    # must report a sequence change, so feed it a log that differs from the rerun
    problem = get_problem("two-dof", case=1)
    events = simulate(problem, "exact", 50.0).events
    cond, note = conditioning(problem, {"name": "exact", "options": {}}, 0.0, 50.0, events.iloc[:-1])
    assert math.isinf(cond) and "changes the event sequence" in note


def test_simulate_reference_prints_and_writes_its_certified_error(tmp_path, capsys):
    """The reference's log carries its error against an independent quad-precision check.

    Case 2 (linear, forced): the reference is ``exact``; its event times are known to be
    within 7e-14 of a 32-digit closed form over [0, 300] (tests/integrators), so the
    check (heyoka-q, tol 1e-30) must certify every event and find differences of that size.
    """
    import pandas as pd

    from nsbench.cli import main

    out = tmp_path / "ev.csv"
    assert main(["simulate", "two-dof", "--case", "2", "--integrator", "reference", "--t-end", "100",
                 "--events-out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "certified error of this log" in text and "heyoka-q" in text
    events = pd.read_csv(out)
    err = events["certified_error"].to_numpy()
    assert len(err) > 20 and (err >= 0).all() and err.max() < 1e-12
