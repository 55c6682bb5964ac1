"""Suites: TOML and dict forms, expansion into cases, grids, data-driven skips, bad input."""

from __future__ import annotations

import pytest

from nsbench.bench.suite import Suite, default_suite, load_suite
from nsbench.errors import ConfigError

TOML = """
name = "tiny"
t_span = [0, 50]
repeats = 3

[[problems]]
name = "one-dof"
case = 1

[[problems]]
name = "two-dof"
cases = [1, 2]
params = { v0 = 0.1 }

[integrators]
only = ["exact", "henon-rk4", "scipy-dop853"]

[integrators.grids.scipy-dop853]
grid = { rtol = [1e-4, 1e-8, 1e-12] }
fixed = { atol = 1e-14 }

[integrators.grids.henon-rk4]
options = [{ h = 0.05 }, { h = 0.02 }]

[integrators.skip_levels.henon-rk4]
levels = [0]
reason = "test"
"""


def test_toml_and_dict_give_the_same_cases(tmp_path):
    import tomllib

    path = tmp_path / "s.toml"
    path.write_text(TOML)
    a, b = Suite.from_toml(path), Suite.from_dict(tomllib.loads(TOML))
    assert [c.case_id for c in a.cases()] == [c.case_id for c in b.cases()]
    cases = a.cases()
    # 3 problems x (exact 1 + henon-rk4 2-1 skipped + dop853 3)
    assert len(cases) == 3 * 5
    henon = [c for c in cases if c.integrator == "henon-rk4"]
    assert {c.options["h"] for c in henon} == {0.02} and {c.level for c in henon} == {1}
    dop = [c.options for c in cases if c.integrator == "scipy-dop853" and c.problem["name"] == "one-dof"]
    assert dop == [{"atol": 1e-14, "rtol": r} for r in (1e-4, 1e-8, 1e-12)]
    two = [c.problem for c in cases if c.problem["name"] == "two-dof"]
    assert {p["case"] for p in two} == {1, 2} and all(p["params"] == {"v0": 0.1} for p in two)


def test_default_suite_is_packaged_and_keeps_every_class_and_family_at_accuracy_levels():
    """The quick default (issue 49): every class of problem and every family of methods, the bifurcation
    targets, each method at its accuracy levels minus the levels the data skips."""
    from nsbench.bench.classes import CLASS_ORDER
    from nsbench.bench.families import FAMILY_ORDER
    from nsbench.integrators import integrator_class
    from nsbench.problems import problem_from_config

    suite = load_suite("default")
    assert suite.targets == (1e-3, 1e-6, 1e-9, 1e-12) and suite.target_list()
    classes = {problem_from_config(p).behaviour() for p in suite.problem_configs()}
    assert classes == set(CLASS_ORDER)
    names = {c.integrator for c in suite.cases()}
    assert {integrator_class(n).capabilities.family for n in names} == set(FAMILY_ORDER)
    assert names == set(suite.integrators["only"])
    for name in names:  # every level of every integrator, minus the ones the data skips
        levels = integrator_class(name).accuracy_levels or ({},)
        skip = suite.integrators.get("skip_levels", {}).get(name, {}).get("levels", [])
        got = [c.options for c in suite.cases() if c.integrator == name and c.problem["name"] == "one-dof"]
        assert got == [dict(o) for i, o in enumerate(levels) if i not in skip]
    assert default_suite().to_dict() == suite.to_dict()


def test_full_suite_is_the_earlier_default_at_every_level():
    """``--suite full``: every registered event-driven integrator at every level (scipy-radau's slowest apart) on the
    paper's five cases over [0, 300], as the default of earlier releases ran them, and the same targets."""
    from nsbench.integrators import integrator_class, list_integrators

    suite = load_suite("full")
    assert suite.t_span == (0.0, 300.0) and suite.targets == (1e-6, 1e-9, 1e-12)
    labels = {(p["name"], p["case"]) for p in suite.problem_configs()}
    assert labels == {("one-dof", 1), ("two-dof", 1), ("two-dof", 2), ("two-dof", 3), ("two-dof", 4)}
    names = {c.integrator for c in suite.cases()}
    # the whole-system families are graded by the families suite; the engines whose extra is not installed
    # here are left out (and named by suite.unavailable())
    assert names == set(list_integrators()) - set(suite.unavailable()) - {
        "moreau-jean",
        "switch-model",
        "smoothing",
        "lugre",
        "siconos-moreau-jean",
        "siconos-event-driven",
        "fesd",
    }
    for name in names:
        levels = integrator_class(name).accuracy_levels or ({},)
        got = [c.options for c in suite.cases() if c.integrator == name and c.problem["name"] == "one-dof"]
        expected = [dict(o) for i, o in enumerate(levels) if not (name == "scipy-radau" and i == 2)]
        assert got == expected
    assert [t.name for t in suite.target_list()] == [t.name for t in default_suite().target_list()]


def test_case_ids_are_stable_and_distinct():
    suite = Suite.from_dict({"problems": [{"name": "one-dof", "case": 1}], "integrators": {"only": ["scipy-rk45"]}})
    ids = [c.case_id for c in suite.cases()]
    assert len(set(ids)) == 3 and ids == [c.case_id for c in suite.cases()]
    longer = Suite.from_dict(
        {"problems": [{"name": "one-dof"}], "integrators": {"only": ["scipy-rk45"]}, "t_span": [0, 100]}
    )
    assert set(ids).isdisjoint(c.case_id for c in longer.cases())


def test_repeats_are_at_least_three_and_repeat_budget_is_ignored():
    base = {"problems": [{"name": "one-dof", "case": 1}], "integrators": {"only": ["scipy-rk45"]}}
    for few in (1, 2):  # a spread needs three runs: fewer is refused, not raised to 3 in silence
        with pytest.raises(ConfigError, match=rf"repeats = {few} must be an integer >= 3 .*three timed runs"):
            Suite.from_dict({**base, "repeats": few})
    assert Suite.from_dict({**base, "repeats": 3}).repeats == 3
    assert {c.repeats for c in Suite.from_dict({**base, "repeats": 5}).cases()} == {5}
    old = Suite.from_dict({**base, "repeat_budget": 0.5})  # an older suite file still loads
    assert old.cases() == Suite.from_dict(base).cases()  # ... and times the same way
    assert not hasattr(old.cases()[0], "repeat_budget")


def test_max_repeats_defaults_to_twice_repeats_and_is_checked():
    base = {"problems": [{"name": "one-dof", "case": 1}], "integrators": {"only": ["scipy-rk45"]}}
    assert Suite.from_dict(base).max_repeats == 10 and Suite.from_dict({**base, "repeats": 3}).max_repeats == 6
    assert {c.max_repeats for c in Suite.from_dict({**base, "max_repeats": 5}).cases()} == {5}
    for bad in (4, 10**9, 2.5, True, "7"):
        with pytest.raises(ConfigError, match="max_repeats = .* must be an integer >= repeats"):
            Suite.from_dict({**base, "max_repeats": bad})
    for bad in (-1, float("nan"), float("inf"), 30.0, "0.05"):
        with pytest.raises(ConfigError, match="min_sample_time = .* must be a number of seconds >= 0"):
            Suite.from_dict({**base, "min_sample_time": bad})


@pytest.mark.parametrize(
    "data, fragment",
    [
        ({"problems": []}, "at least one entry in problems"),
        ({"problems": [{"name": "one-dof"}], "colour": 1}, "unknown key(s) colour"),
        ({"problems": [{"name": "one-dof", "cas": 1}]}, "unknown key(s) cas"),
        ({"problems": [{"name": "three-dof"}]}, "unknown problem 'three-dof'"),
        ({"problems": [{"name": "one-dof", "params": {"c": -1}}]}, "out of range"),
        ({"problems": [{"name": "one-dof"}], "t_span": [5, 1]}, "t_end > t0"),
        ({"problems": [{"name": "chain", "params": {"n": []}}]}, "params.n is an empty list"),
        ({"problems": [{"name": "chain", "params": {"n": [2, 100]}}]}, "n = 100 is not allowed"),
        ({"problems": [{"name": "one-dof"}], "repeats": 0}, "repeats = 0"),
        ({"problems": [{"name": "one-dof"}], "time_limit": -1}, "time_limit = -1"),
        ({"problems": [{"name": "one-dof"}], "repeat_budget": "x"}, "repeat_budget = 'x'"),
        ({"problems": [{"name": "one-dof"}], "targets": [0]}, "must be positive"),
        ({"problems": [{"name": "one-dof"}], "integrators": {"only": ["rk99"]}}, "unknown integrator(s) rk99"),
        (
            {"problems": [{"name": "one-dof"}], "integrators": {"grids": {"scipy-rk45": {"grid": {"rtol": [-1]}}}}},
            "rtol = -1",
        ),
        (
            {"problems": [{"name": "one-dof"}], "integrators": {"grids": {"henon-rk4": {"grid": {"k": [1]}}}}},
            "unknown option 'k'",
        ),
    ],
)
def test_bad_suites_raise_config_error(data, fragment):
    with pytest.raises(ConfigError, match=None) as info:
        Suite.from_dict(data).cases()
    assert fragment in str(info.value)


def test_missing_and_invalid_files(tmp_path):
    with pytest.raises(ConfigError, match="does not exist"):
        load_suite(tmp_path / "nope.toml")
    bad = tmp_path / "bad.toml"
    bad.write_text("name = [")
    with pytest.raises(ConfigError, match="not valid TOML"):
        load_suite(bad)


def test_list_valued_params_are_a_grid_of_problems():
    suite = Suite.from_dict(
        {
            "problems": [{"name": "chain", "cases": [1, 2], "params": {"n": [2, 8], "mu": 0.5}}],
            "integrators": {"only": ["exact"]},
        }
    )
    configs = suite.problem_configs()
    assert [(c["case"], c["params"]["n"]) for c in configs] == [(1, 2), (1, 8), (2, 2), (2, 8)]
    assert all(c["params"]["mu"] == 0.5 for c in configs)
    assert len({case.case_id for case in suite.cases()}) == 4


def test_families_suite_runs_the_relay_and_its_refusals_are_setup_refusals():
    """The families suite (issue 51): four problems, the relay feedback system the one fesd maps; on the relay
    the methods written for blocks on a belt refuse at setup (a row with the reason), they do not crash."""
    from nsbench.errors import UnsupportedProblemError
    from nsbench.integrators import integrator_class
    from nsbench.problems import problem_from_config

    suite = load_suite("families")
    spans = [((c["name"], c["case"]), span) for c, span in suite.problem_spans()]
    assert spans == [
        (("one-dof", 1), (0.0, 100.0)),
        (("two-dof", 1), (0.0, 100.0)),
        (("one-dof", "leine"), (0.0, 100.0)),
        (("relay-feedback", "piiroinen-kuznetsov"), (0.0, 2.0)),
    ]
    # configurations per problem, counted from the ladders in families.toml: henon-rk4 5 h, moreau-jean 11 h,
    # switch-model 4 eta, smoothing 4 eps, lugre 2 tolerances, and the optional engines installed here
    # (fesd 3 h, cyrk-vern7 4 and diffrax-tsit5 4 tolerances)
    ladders = {"henon-rk4": 5, "moreau-jean": 11, "switch-model": 4, "smoothing": 4, "lugre": 2}
    ladders.update(
        {k: v for k, v in {"fesd": 3, "cyrk-vern7": 4, "diffrax-tsit5": 4}.items() if k not in suite.unavailable()}
    )
    assert len(suite.cases()) == 4 * sum(ladders.values())
    relay = problem_from_config(suite.problem_configs()[-1])
    runs = set()
    for name in ladders:
        try:
            integrator_class(name)().setup(relay)
        except UnsupportedProblemError as exc:
            assert name in str(exc) and "relay-feedback" in str(exc)
        else:
            runs.add(name)
    assert runs == {"henon-rk4"} | ({"fesd", "cyrk-vern7", "diffrax-tsit5"} & set(ladders))


def test_packaged_suites_by_name():
    from nsbench.bench.suite import packaged_suites

    assert {"default", "chain-scaling", "families"} <= set(packaged_suites())
    scaling = load_suite("chain-scaling")
    ns = sorted({c["params"]["n"] for c in scaling.problem_configs()})
    assert ns == [2, 4, 8, 16, 32, 64] and scaling.name == "chain-scaling"
    with pytest.raises(ConfigError, match="neither a file nor a packaged suite; packaged: chain-scaling, default"):
        load_suite("chain-scalin")


@pytest.mark.parametrize(
    "data, fragment",
    [
        ({"problems": 5}, "suite field 'problems' must be a list of tables (each with a 'name'), got int 5"),
        ({"problems": [{"name": 5}]}, "suite field 'problems[0].name' must be a registered problem name"),
        ({"problems": [{"name": "one-dof", "params": 5}]}, "'problems[0].params' must be a table"),
        ({"problems": [{"name": "one-dof", "params": {"c": "abc"}}]}, "'problems[0].params.c' must be a number"),
        ({"problems": [{"name": "one-dof", "dimensional": "yes"}]}, "'problems[0].dimensional' must be true or false"),
        ({"problems": [{"name": "one-dof"}], "t_span": [0, float("inf")]}, "finite numbers only"),
        ({"problems": [{"name": "one-dof"}], "reference": ["nope"]}, "unknown integrator(s) nope; registered: "),
        ({"problems": [{"name": "one-dof"}], "reference": 5}, "suite field 'reference' must be a list"),
        ({"problems": [{"name": "one-dof"}], "repeats": 10**12}, "MAX_REPEATS"),
        ({"problems": [{"name": "one-dof"}], "dense_points": 10**12}, "MAX_DENSE_POINTS"),
        ({"problems": [{"name": "one-dof"}], "time_limit": float("inf")}, "positive, finite number of seconds"),
        ({"problems": [{"name": "one-dof"}], "name": 5}, "suite field 'name' must be a non-empty string, got int 5"),
        ({"problems": [{"name": "one-dof"}], "integrators": {"only": "exact"}}, "'integrators.only' must be a list"),
        ({"problems": [{"name": "one-dof"}], "integrators": {"grids": 5}}, "'integrators.grids' must be a table"),
        (
            {"problems": [{"name": "one-dof"}], "integrators": {"skip_levels": {"exact": 5}}},
            "'integrators.skip_levels.exact' must be a table",
        ),
    ],
)
def test_suite_fields_are_type_checked_with_their_path(data, fragment):
    with pytest.raises(ConfigError) as info:
        Suite.from_dict(data)
    assert fragment in str(info.value)


def test_a_huge_grid_is_refused_before_it_is_expanded():
    from nsbench.bench.suite import MAX_CASES

    values = [0.1 * (i + 1) for i in range(1000)]
    suite = Suite.from_dict(
        {
            "problems": [{"name": "one-dof", "params": {"c": values, "h": values, "F": values}}],
            "integrators": {"only": ["exact"]},
        }
    )
    assert suite.n_problems() == 10**9
    with pytest.raises(ConfigError, match=f"more than the {MAX_CASES} cases"):
        suite.cases()
    grid = {"rtol": [1e-6] * 1000, "atol": [1e-8] * 1000, "first_step": [0.1] * 1000}
    suite = Suite.from_dict(
        {
            "problems": [{"name": "one-dof"}],
            "integrators": {"only": ["scipy-rk45"], "grids": {"scipy-rk45": {"grid": grid}}},
        }
    )
    assert suite.n_cases() == 10**9
    with pytest.raises(ConfigError, match="expands to 1000000000 cases"):
        suite.cases()


def test_binary_and_folder_suite_files_are_refused(tmp_path):
    (tmp_path / "bin.toml").write_bytes(bytes(range(256)))
    with pytest.raises(ConfigError, match="not UTF-8 text"):
        load_suite(tmp_path / "bin.toml")
    (tmp_path / "dir.toml").mkdir()
    with pytest.raises(ConfigError, match="is a folder"):
        load_suite(tmp_path / "dir.toml")


def test_a_henon_grid_with_an_infinite_step_is_refused_when_expanded():
    suite = Suite.from_dict(
        {
            "problems": [{"name": "one-dof"}],
            "integrators": {"grids": {"henon-rk4": {"grid": {"h": [0.01, float("inf")]}}}, "only": ["henon-rk4"]},
        }
    )
    with pytest.raises(ConfigError, match="h = inf must be a finite"):
        suite.cases()


def test_a_friction_law_is_a_name_in_a_suite_and_in_the_labels():
    from nsbench.bench.keys import problem_label

    suite = Suite(
        problems=[
            {"name": "two-dof", "case": 2, "params": {"law": "stribeck", "fk": 0.5, "vs": 0.2}},
            {"name": "one-dof", "case": "leine"},
        ],
        t_span=(0, 60),
    )
    assert suite.problems[0]["params"]["law"] == "stribeck"
    assert problem_label(suite.problems[0]) == "two-dof/2 fk=0.5 law=stribeck vs=0.2"
    assert problem_label(suite.problems[1]) == "one-dof/leine"
    with pytest.raises(ConfigError, match=r"params.fk' must be a number or a list of numbers \(law: a name\)"):
        Suite(problems=[{"name": "two-dof", "params": {"law": "stribeck", "fk": "half", "vs": 0.2}}], t_span=(0, 60))


_BASE = {"problems": [{"name": "one-dof", "case": 1}], "integrators": {"only": ["scipy-rk45"]}}


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"problems": [{"name": "one-dof", "case": 1, "cases": [2]}]}, r"both 'case' = 1 and 'cases' = \[2\]"),
        (
            {
                "integrators": {
                    "only": ["scipy-rk45"],
                    "grids": {"scipy-rk45": {"options": [{}], "grid": {"rtol": [1e-6]}}},
                }
            },
            r"grids.scipy-rk45 gives both 'options' and 'grid'",
        ),
        (
            {"integrators": {"only": ["scipy-rk45"], "grids": {"scipy-dop853": {"options": [{"rtol": 1e-6}]}}}},
            r"integrators.grids.scipy-dop853' names an integrator outside 'integrators.only'",
        ),
        (
            {"integrators": {"exclude": ["no-such-method"]}},
            r"integrators.exclude': unknown integrator\(s\) no-such-method",
        ),
        (
            {"integrators": {"only": ["scipy-rk45"], "skip_levels": {"no-such-method": {"levels": [0]}}}},
            r"integrators.skip_levels': unknown integrator\(s\) no-such-method",
        ),
        (
            {"integrators": {"only": ["scipy-rk45"], "skip_levels": {"scipy-rk45": {"levels": [99]}}}},
            r"skip_levels.scipy-rk45.levels' = \[99\]: level\(s\) 99 do not exist; scipy-rk45 has \d+ level",
        ),
        (
            {"integrators": {"exclude": ["scipy-rk45"], "grids": {"scipy-rk45": {"options": [{"rtol": 1e-6}]}}}},
            r"grids.scipy-rk45' names an integrator that 'integrators.exclude' leaves out",
        ),
        ({"integrators": {"only": []}}, r"'integrators.only' is empty: the suite would run no integrator"),
        ({"integrators": {"registered": False}}, r"registered = false with no 'only' and no 'grids' selects no"),
        ({"name": ""}, r"suite field 'name' must be a non-empty string"),
        ({"name": "  "}, r"suite field 'name' must be a non-empty string"),
    ],
)
def test_a_setting_that_would_be_dropped_in_silence_is_refused_at_load(change, message):
    with pytest.raises(ConfigError, match=message):
        Suite.from_dict({**_BASE, **change})


def test_a_skipped_level_is_counted_from_the_grid_when_there_is_one():
    grid = {"scipy-rk45": {"grid": {"rtol": [1e-4, 1e-6]}}}
    ok = Suite.from_dict(
        {
            **_BASE,
            "integrators": {"only": ["scipy-rk45"], "grids": grid, "skip_levels": {"scipy-rk45": {"levels": [1]}}},
        }
    )
    assert [c.options["rtol"] for c in ok.cases()] == [1e-4]
    with pytest.raises(ConfigError, match=r"level\(s\) 2 do not exist; scipy-rk45 has 2 level\(s\) here, 0..1"):
        Suite.from_dict(
            {
                **_BASE,
                "integrators": {"only": ["scipy-rk45"], "grids": grid, "skip_levels": {"scipy-rk45": {"levels": [2]}}},
            }
        )


def test_a_suite_with_no_case_to_run_is_refused_when_expanded():
    # issue 52 item 6: every level skipped ran nothing and ended in KeyError 'problem_label'
    suite = Suite.from_dict(
        {
            "t_span": [0.0, 1.0],
            "problems": [{"name": "one-dof", "case": 1}],
            "integrators": {
                "only": ["henon-rk4"],
                "grids": {"henon-rk4": {"grid": {"h": [0.01, 0.005]}}},
                "skip_levels": {"henon-rk4": {"levels": [0, 1], "reason": "both"}},
            },
        }
    )
    with pytest.raises(ConfigError, match="the suite has no case to run: integrators.skip_levels skips every level"):
        suite.cases()
