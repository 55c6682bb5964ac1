"""The library suite and the answer by problem class (issue 27)."""

from __future__ import annotations

import json
import math

import pytest

from nsbench.bench import Suite, run_suite
from nsbench.bench.classes import class_findings, class_of, class_summary
from nsbench.bench.suite import packaged_suite
from nsbench.errors import ConfigError


def test_every_problem_declares_its_class():
    names = {
        "two-dof": "friction",
        "block-on-ground": "friction",
        "bouncing-ball": "impact",
        "impact-oscillator": "impact",
        "relay-feedback": "sliding",
        "henon-heiles": "smooth",
    }
    for name, klass in names.items():
        assert class_of(json.dumps({"name": name, "case": 2 if name == "two-dof" else None})) == klass


def test_the_library_suite_lists_one_problem_per_line_with_its_own_span():
    suite = packaged_suite("library")
    spans = {c.problem["name"]: (c.t0, c.t_end) for c in suite.cases()}
    assert spans["henon-heiles"] == (0.0, 2000.0) and spans["bouncing-ball"] == (0.0, 6.0)
    assert spans["two-dof"] == (0.0, 300.0)  # the suite's span where a problem gives none
    classes = {class_of(json.dumps(c.problem)) for c in suite.cases()}
    assert classes == {"friction", "impact", "sliding", "smooth"}


@pytest.mark.parametrize(
    "span, message",
    [
        ([1.0], r"t_span = \[1.0\] must be \[t0, t_end\]"),
        ([2.0, 1.0], "t_end > t0"),
        ("x", "non-empty list of numbers"),
    ],
)
def test_a_bad_problem_span_is_refused(span, message):
    with pytest.raises(ConfigError, match=message):
        Suite.from_dict({"name": "s", "problems": [{"name": "bouncing-ball", "t_span": span}]})


def test_a_tiny_library_run_answers_by_problem_class(tmp_path):
    """The library suite in small (seconds): one problem of three classes, two methods, short spans, every
    sample a single run; the report's opening (no figures) groups the answer by class."""
    from nsbench.bench import storage
    from nsbench.bench.report import _answer_blocks
    from nsbench.bench.summary import problem_summary

    suite = Suite.from_dict(
        {
            "name": "library-tiny",
            "t_span": [0.0, 30.0],
            "repeats": 3,
            "min_sample_time": 0.0,
            "reference": ["exact", "reference"],
            "targets": [1e-6, 1e-12],
            "problems": [
                {"name": "block-on-ground"},
                {"name": "bouncing-ball", "t_span": [0.0, 6.0]},
                {"name": "relay-feedback", "t_span": [0.0, 20.0]},
            ],
            "integrators": {"only": ["henon-rk4", "ofapi"], "grids": {"henon-rk4": {"options": [{"h": 0.01}]}}},
        }
    )
    run_suite(suite, tmp_path, workers=1, progress=False)
    frame = storage.load_results(tmp_path)
    assert set(frame["t_end"]) == {30.0, 6.0, 20.0}
    by_class = class_summary(frame, [1e-6, 1e-12])
    assert list(by_class["class"].unique()) == ["friction", "impact", "sliding"]
    # RK4 at h = 0.01 leaves event errors far above 1e-12 (1e-8 and more): ofapi is the only one there
    for _, row in by_class[by_class["target"] == "1e-12"].iterrows():
        assert row["cheapest"] == "ofapi" and row["wins"] == "1 of 1" and row["ratio"] == "1.00"
    blocks = _answer_blocks(frame, {}, problem_summary(frame, [1e-6, 1e-12]), None, by_class)
    heads = [b.text for b in blocks if b.kind == "h2"]
    assert heads.index("The answer by problem class") < heads.index("The answer")
    words = next(b.items for b in blocks if b.kind == "list" and any("**sliding**" in i for i in b.items))
    assert any(w.startswith("**friction** (block-on-ground)") for w in words)


def _planted(integrator: str, problem: str, wall: float, spread=(0.97, 0.99, 1.0, 1.01, 1.03)) -> dict:
    case = {"one-dof": 1, "two-dof": 2}[problem]
    return {
        "case_id": f"{problem}-{integrator}",
        "problem_label": f"{problem}/{case}",
        "integrator": integrator,
        "problem_config": json.dumps({"case": case, "dimensional": False, "name": problem, "params": {}}),
        "options": "{}",
        "level": 0,
        "status": "success",
        "reference": "exact",
        "reference_status": "ok",
        "sequence_ok": True,
        "switch_err_max": 1e-10,
        "wall_time": wall,
        "wall_spread": 0.06,
        "wall_times": [wall * f for f in spread],
        "n_missed": 0,
        "n_extra": 0,
        "n_ref": 100,
        "nfev": 1000,
    }


def test_the_class_answer_gives_intervals_and_names_tied_methods():
    """Planted samples (no clock): a and b trade places by 4-6 % within +-10 % noise on two friction problems,
    c is three times slower; a is 1 % cheaper by the geometric mean but not distinguishable from b."""
    from nsbench.bench.storage import to_frame

    noisy = (0.9, 0.95, 1.0, 1.05, 1.1)
    rows = [
        _planted("a", "one-dof", 0.100, noisy),
        _planted("b", "one-dof", 0.106, noisy),
        _planted("a", "two-dof", 0.200, noisy),
        _planted("b", "two-dof", 0.192, noisy),
        _planted("c", "one-dof", 0.300),
        _planted("c", "two-dof", 0.600),
    ]
    row = class_summary(to_frame(rows), [1e-9]).iloc[0]
    assert row["class"] == "friction" and row["cheapest"] == "tied: a, b"
    est, interval = row["ratio"].split(" ", 1)  # '1.02 [lo-hi]': a's ratio with its interval
    low, high = (float(v) for v in interval.strip("[]").split("-"))
    assert float(est) == pytest.approx(math.sqrt(1.0 * 0.2 / 0.192), abs=0.005) and low <= float(est) <= high
    assert row["runner_up"].startswith("b (") and row["runner_up"].endswith(", tied)")
    words = " ".join(class_findings(class_summary(to_frame(rows), [1e-9])))
    assert "no method is distinguishably the cheapest: a, b are tied" in words
    # without b, a is distinguishably cheaper than c (three times, +-3 %): named alone, c's ratio has its interval
    alone = class_summary(to_frame([r for r in rows if r["integrator"] != "b"]), [1e-9]).iloc[0]
    assert alone["cheapest"] == "a" and alone["ratio"] == "1.00"
    assert alone["runner_up"].startswith("c (3.00 [") and "tied" not in alone["runner_up"]
    c_low = float(alone["runner_up"].split("[")[1].split("-")[0])
    assert 2.7 < c_low < 3.0  # the samples' +-3 % noise, not more
    # one sample a side: nothing can be told apart
    bare = [dict(r, wall_times=[r["wall_time"]]) for r in rows if r["integrator"] != "b"]
    assert class_summary(to_frame(bare), [1e-9]).iloc[0]["cheapest"] == "tied: a, c"
