"""The conditioning of a case, measured by the reference, checked with an independent integrator."""

from __future__ import annotations

import math
import re

import numpy as np
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
    check (exact-mp, 40 digits) must certify every event and find differences of that size.
    """
    import pandas as pd

    from nsbench.cli import main

    out = tmp_path / "ev.csv"
    assert (
        main(
            [
                "simulate",
                "two-dof",
                "--case",
                "2",
                "--integrator",
                "reference",
                "--t-end",
                "100",
                "--events-out",
                str(out),
            ]
        )
        == 0
    )
    text = capsys.readouterr().out
    assert "certified error of this log" in text and "exact-mp" in text
    events = pd.read_csv(out)
    err = events["certified_error"].to_numpy()
    assert len(err) > 20 and (err >= 0).all() and err.max() < 1e-12


def _true_errors(events, case):
    """|t - t_true| per event against the 30-digit closed form of tests/mp_reference (same sequence)."""
    import mpmath as mp

    from tests.mp_reference import stored_events

    truth = stored_events(case)
    assert list(events["kind"]) == list(truth["kind"]) and list(events["block"]) == list(truth["block"])
    with mp.workdps(32):
        return np.array([float(abs(mp.mpf(float(t)) - mp.mpf(r))) for t, r in zip(events["t"], truth["t"])])


@pytest.mark.parametrize("case", [1, 2])
def test_every_reference_log_carries_a_certified_error_that_bounds_its_true_error(case):
    # the bench's reference of a linear case is exact (double); its certified error comes from an
    # independent 40-digit run (exact-mp), and must bound the true error (30-digit closed form, an
    # independent solver written in the tests) at every event, while staying tight: exact is within
    # 7e-14 of it, and the bound adds one ulp of t (5.7e-14 near t = 300), so at most about 1.3e-13
    from nsbench.bench.reference import candidates, compute_reference

    ref = compute_reference(
        get_problem("two-dof", case=case).config(), candidates(["exact", "reference"]), 0.0, 300.0, 20
    )
    assert ref.ok and ref.name == "exact" and "exact-mp" in ref.certify_note
    cert = ref.events["certified_error"].to_numpy()
    t = ref.events["t"].to_numpy()
    assert np.isfinite(cert).all() and (cert >= np.spacing(t)).all() and cert.max() < 1.5e-13
    assert (_true_errors(ref.events, case) <= cert).all()
    assert ref.certainty == cert.max() == ref.columns()["ref_certainty"]


def test_the_ill_conditioned_point_is_flagged_and_not_graded_below_its_certainty(tmp_path):
    # at STIFF, exact's own rounding is amplified: the 40-digit check finds it off by far more than 1e-10
    # (exact-mp finds it 3.4e-9 off near t = 300), the double floor exceeds 1e-10; the report says so and grades
    # no target below them
    from nsbench.bench import run_suite
    from nsbench.bench.report import write_report
    from nsbench.bench.suite import Suite

    suite = Suite.from_dict(
        {
            "name": "stiff",
            "t_span": [0.0, 300.0],
            "repeats": 3,
            "reference": ["exact"],
            "targets": [1e-6, 1e-9],
            "problems": [{"name": "two-dof", "case": 2, "params": STIFF}],
            "integrators": {"only": ["henon-rk4"]},
        }
    )
    summary = run_suite(suite, tmp_path, workers=1, progress=False)
    frame = summary.results
    cert, floor = float(frame["ref_certainty"].iloc[0]), float(frame["ref_double_floor"].iloc[0])
    assert cert > DOUBLE_GRADABLE and floor > DOUBLE_GRADABLE
    report = write_report(tmp_path)
    text = report.markdown.read_text()
    assert "is not graded below that: its reference's event times are certified to" in text
    assert "not graded at this target" in text
    long = report.fixed_target
    assert (long[long["target"] == 1e-9]["outcome"] == "not graded").all()
    assert (long[long["target"] == 1e-6]["outcome"] != "not graded").all()


def test_the_cache_keeps_the_certified_errors_and_their_note(tmp_path):
    from nsbench.bench.reference import candidates, compute_reference, load_reference, save_reference

    ref = compute_reference(get_problem("one-dof", case=1).config(), candidates(["exact"]), 0.0, 30.0, 10)
    save_reference(tmp_path, ref)
    back = load_reference(tmp_path, ref.key)
    assert back is not None and back.certify_note == ref.certify_note != ""
    assert np.array_equal(back.events["certified_error"].to_numpy(), ref.events["certified_error"].to_numpy())
    assert back.certainty == ref.certainty > 0


def test_a_reference_is_never_certified_by_itself():
    # exact-mp as a suite's reference (to grade an ill-conditioned linear case finer than exact can)
    # is checked by the quad Taylor method, not by a second exact-mp run
    from nsbench.bench.reference import candidates, compute_reference

    ref = compute_reference(get_problem("two-dof", case=1).config(), candidates(["exact-mp"]), 0.0, 30.0, 10)
    assert ref.ok and ref.name == "exact-mp" and "heyoka-q" in ref.certify_note
    assert np.isfinite(ref.events["certified_error"]).all() and ref.certainty < 1e-13


def test_a_check_that_cannot_be_imported_hands_over_to_the_next(monkeypatch):
    # a plain install without exact-mp's dependency must still certify (the main job ran into this)
    import nsbench.integrators as integrators
    from nsbench.bench.reference import certified_errors
    from nsbench.errors import PluginLoadError

    real = integrators.integrator_from_config

    def without_mp(config):
        if config["name"] == "exact-mp":
            raise PluginLoadError("integrator 'exact-mp' failed to import: No module named 'mpmath'")
        return real(config)

    monkeypatch.setattr(integrators, "integrator_from_config", without_mp)
    problem = get_problem("two-dof", case=1)
    events = simulate(problem, "exact", 30.0).events
    cert, note = certified_errors(problem, events, 0.0, 30.0, reference="exact")
    assert "heyoka-q" in note and np.isfinite(cert).all() and cert.max() < 1e-13


def test_a_reference_its_check_contradicts_grades_nothing_and_says_so(register, tmp_path):
    # exact-mp (the certification of a linear problem) logs another event sequence than this
    # reference: the bench used to grade exact against it and report exact's sequence as wrong
    import pandas as pd

    from nsbench.bench import Suite, run_suite
    from tests.bench import _integrators as ti

    register(ti.CoarseReference.name, ti.CoarseReference)
    suite = Suite.from_dict(
        {
            "t_span": [0.0, 50.0],
            "repeats": 3,
            "reference": [ti.CoarseReference.name],
            "problems": [{"name": "two-dof", "case": 1}],
            "integrators": {"only": ["exact"], "grids": {"exact": {"options": [{}]}}},
        }
    )
    summary = run_suite(suite, tmp_path, workers=1, progress=False)
    row = summary.results.iloc[0]
    assert row["status"] == "success"
    assert row["reference_status"].startswith(f"reference failed: {ti.CoarseReference.name} is not certified")
    assert "the event sequences differ from event" in row["reference_status"]
    assert pd.isna(row["n_matched"]) and pd.isna(row["switch_err_max"]) and pd.isna(row["sequence_ok"])
    assert not summary.ok and "nothing is graded against it" in summary.problems()[0]
    from nsbench.bench.report import write_report

    report = write_report(tmp_path).markdown.read_text()
    # (the tables are padded to their columns: compare with single spaces)
    assert "| two-dof/1 | exact | no ref | no ref | no ref |" in re.sub(" +", " ", report)  # not blamed, nor ranked
    assert "nothing is graded against it" in report
