"""Bifurcation targets (issue 12, item 5): suite checks, the integrators' own location, stored rows, report."""

from __future__ import annotations

import math

import pytest

from nsbench.bench.suite import Suite
from nsbench.bench.targets import (
    BifurcationTarget,
    Location,
    TargetReference,
    compute_row,
    compute_target_reference,
    load_rows,
    locate_with,
    near_side,
    run_targets,
    save_target_reference,
)
from nsbench.bench.target_spec import parse_target
from nsbench.errors import ConfigError

#: Case 1, block 1 starts sticking as v0 decreases (v0 ~ 0.10042); cheap (about 1 s) on the reference flow.
STICK1 = dict(
    name="stick1", problem="two-dof", case=1, param="v0", origin=0.16, bracket=[0.0995, 0.101], kind="grazing-sliding"
)


def _suite(targets, **integrators):
    return Suite.from_dict(
        {
            "problems": [{"name": "one-dof", "case": 1}],
            "t_span": [0.0, 5.0],
            "integrators": integrators or {"only": ["henon-rk4"]},
            "bifurcation_targets": targets,
        }
    )


# ---------------------------------------------------------------------- validation
@pytest.mark.parametrize(
    "change, words",
    [
        ({"bracket": [0.101, 0.0995]}, "low < high"),
        ({"bracket": [0.1]}, "must be [low, high]"),
        ({"bracket": [0.09, "x"]}, "must be [low, high]"),
        ({"origin": 0.1}, "lies in the bracket"),
        ({"problem": "three-body"}, "three-body"),
        ({"param": "warp"}, "warp"),
        ({"kind": "hopf"}, "kind"),
        ({"colour": "red"}, "unknown key(s) colour"),
        ({"periods": 1}, "periods"),
        ({"max_probes": 2.5}, "max_probes"),
        ({"xtol": -1.0}, "xtol"),
        ({"exclude": ["no-such-integrator"]}, "no-such-integrator"),
        ({"params": {"v0": 0.1}}, "also fixed in params"),
    ],
)
def test_bad_target_is_refused_when_the_suite_loads(change, words):
    with pytest.raises(ConfigError) as info:
        _suite([{**STICK1, **change}])
    assert words in str(info.value)


def test_missing_keys_and_duplicate_names_are_refused():
    with pytest.raises(ConfigError, match="missing key"):
        _suite([{k: v for k, v in STICK1.items() if k != "bracket"}])
    with pytest.raises(ConfigError, match="used more than once"):
        _suite([STICK1, STICK1])
    with pytest.raises(ConfigError, match="must be a table"):
        _suite(["stick1"])


def test_default_suite_names_two_case1_targets():
    from nsbench.bench import default_suite

    targets = default_suite().target_list()
    assert len(targets) >= 2
    assert all(t.problem == "two-dof" and t.case == 1 and t.param == "v0" for t in targets)
    assert Suite.from_dict(default_suite().to_dict()).target_list() == targets  # round trip


def test_near_side_needs_the_pattern_repeated_over_the_last_periods():
    pattern = ("slip2", "stick2")
    assert near_side(["slip1", "stick2", "slip2", "stick2", "slip2"], pattern)
    assert not near_side(["stick2", "slip2", "stick1", "slip1"], pattern)  # an extra event per period
    assert not near_side([], pattern)  # steady sliding: no events
    assert not near_side(["stick2", "slip2"], pattern)  # one period only


# ---------------------------------------------------------------------- the location
@pytest.fixture(scope="module")
def stick1():
    target = parse_target(STICK1, 0)
    ref = compute_target_reference(target)
    assert ref.ok, ref.status
    assert ref.kind == "grazing-sliding" and ref.pattern == ("slip2", "stick2")
    assert abs(ref.value - 0.1004208377) < 1e-8
    return target, ref


def test_exact_flow_locates_the_reference_value(stick1):
    """The exact flow is the reference flow: the only differences are the two bisections' resolutions
    (1e-10 here, 1e-11 for the reference), so the error is below 1e-9."""
    target, ref = stick1
    out = locate_with(target, ref, "exact", {})
    assert out["status"] == "success", out["message"]
    assert out["bracket_width"] <= target.xtol
    assert out["bifurcation_error"] < 1e-9
    assert out["n_probes"] <= target.max_probes


def test_henon_rk4_converges_to_the_reference_value(stick1):
    """RK4's switching times err by O(h^4) (at h = 0.000625 about 1e-12 per unit time), so the grazing it sees
    is within 1e-6 of the reference at its finest level; its coarsest level is further off."""
    target, ref = stick1
    fine = locate_with(target, ref, "henon-rk4", {"h": 0.000625})
    coarse = locate_with(target, ref, "henon-rk4", {"h": 0.04})
    assert fine["status"] == coarse["status"] == "success"
    assert fine["bifurcation_error"] < 1e-6
    assert coarse["bifurcation_error"] > fine["bifurcation_error"]
    assert fine["integrator_time"] > coarse["integrator_time"] > 0  # the cost is the integrator's own time


def test_failing_probe_and_refusal_are_rows(stick1, register):
    from tests.bench._target_integrators import Refusing

    target, ref = stick1
    failed = compute_row(Location(target, "henon-rk4", {"h": 0.01}, 1), ref, "t", max_steps=10)
    assert failed["status"] == "step budget exhausted"
    assert "probe 1" in failed["message"] and math.isnan(failed["bifurcation_value"])
    register("refusing-test", Refusing)
    refused = compute_row(Location(target, "refusing-test", {}, 0), ref, "t")
    assert refused["status"] == "unsupported" and "refuses" in refused["message"]
    failed = TargetReference("k", "reference failed: ValueError: no orbit")  # as compute_target_reference writes it
    none = compute_row(Location(target, "henon-rk4", {}, 0), failed, "t")
    assert none["status"] == "no reference"
    assert none["message"] == "the target's reference failed: ValueError: no orbit"  # said once


def test_no_bracket_when_the_pattern_does_not_change(stick1):
    target, ref = stick1
    inside = BifurcationTarget(**{**target.as_dict(), "low": 0.105, "high": 0.11})  # both ends on the near side
    out = locate_with(inside, ref, "exact", {})
    assert out["status"] == "no bracket" and "far end" in out["message"]


# ---------------------------------------------------------------------- the runner's phase
def test_rows_are_stored_resumed_and_reported(stick1, tmp_path, register):
    """In process: every configuration's row is stored (also an unsupported one), a resumed run keeps them,
    a fresh one computes them again; the report gets the table and one figure per target."""
    from tests.bench._target_integrators import Refusing

    target, ref = stick1
    register("refusing-test", Refusing)
    suite = _suite(
        [STICK1], only=["exact", "henon-rk4", "refusing-test"], grids={"henon-rk4": {"options": [{"h": 0.01}]}}
    )
    save_target_reference(tmp_path, ref)  # the cached reference: not computed again
    rows = run_targets(suite, tmp_path, {"suite": suite.to_dict()}, in_process=True, progress=False)
    assert sorted(rows["integrator"]) == ["henon-rk4", "refusing-test"]  # exact is reference-grade
    by = dict(zip(rows["integrator"], rows["status"]))
    assert by == {"henon-rk4": "success", "refusing-test": "unsupported"}
    assert (tmp_path / "bifurcation_targets.csv").exists() and (tmp_path / "bifurcation_targets.parquet").exists()
    stamp = sorted(rows["timestamp"])
    again = run_targets(suite, tmp_path, {}, in_process=True, progress=False)
    assert sorted(again["timestamp"]) == stamp  # nothing recomputed
    assert load_rows(tmp_path)["reference_value"].iloc[0] == ref.value

    from nsbench.bench.report import markdown_table
    from nsbench.bench.targets import report_figures, report_table

    table = report_table(load_rows(tmp_path))
    assert {"bifurcation_error", "probes", "cost (s)"} <= set(table.columns)
    assert "henon-rk4" in markdown_table(table)
    figs = report_figures(load_rows(tmp_path), tmp_path / "figures")
    assert len(figs) == 1 and figs[0].png.exists()


def test_a_crashing_worker_leaves_a_row(stick1, tmp_path, register):
    """In worker processes: a location whose worker dies is a 'crashed' row, the others go on."""
    from tests.bench._integrators import Crashing

    target, ref = stick1
    register("crashing-test", Crashing)
    suite = _suite([STICK1], only=["crashing-test", "henon-rk4"], grids={"henon-rk4": {"options": [{"h": 0.04}]}})
    save_target_reference(tmp_path, ref)
    from nsbench.bench.runner import _components

    shareable, _ = _components(suite.cases(), suite)
    rows = run_targets(suite, tmp_path, {}, workers=1, components=shareable, progress=False)
    by = dict(zip(rows["integrator"], rows["status"]))
    assert by == {"crashing-test": "crashed", "henon-rk4": "success"}
    assert "probe 1" in rows.loc[rows["integrator"] == "crashing-test", "message"].iloc[0]
