"""ingest: a real pytest-benchmark JSON (written by a pytest subprocess) into the tidy schema."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from nsbench.bench import Suite, run_suite
from nsbench.bench.ingest import ingest, read_benchmark_json
from nsbench.bench.report import write_report
from nsbench.errors import ConfigError
from tests.procs import inner_pytest_env

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def bench_json(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("pb")
    out = tmp / "bench.json"
    env = inner_pytest_env(NSBENCH_BENCH_T_END="30")
    cmd = [
        sys.executable,
        "-m",
        "pytest",
        str(ROOT / "benchmarks" / "test_registry.py"),
        "-q",
        "-p",
        "no:cacheprovider",
        "--benchmark-only",
        f"--benchmark-json={out}",
        "--benchmark-save-data",
        "-k",
        "one-dof-1 and (scipy-dop853 or exact) and not jit and not mp",
    ]
    done = subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stdout + done.stderr
    return out


def test_ingest_round_trips_a_pytest_benchmark_file(bench_json, tmp_path):
    raw = json.loads(bench_json.read_text())
    assert len(raw["benchmarks"]) == 2
    frame = ingest(bench_json, tmp_path / "ing")
    assert len(frame) == 2 and set(frame["integrator"]) == {"exact", "scipy-dop853"}
    for bench in raw["benchmarks"]:
        row = frame[frame["case_id"] == bench["extra_info"]["case_id"]].iloc[0]
        assert row["wall_time"] == bench["stats"]["median"]
        assert list(row["wall_times"]) == bench["stats"]["data"] and row["n_repeats"] == bench["stats"]["rounds"]
        for key in ("switch_err_max", "n_prefix", "n_missed", "nfev", "status", "problem_config"):
            assert row[key] == bench["extra_info"][key], key
        assert list(row["event_err"]) == bench["extra_info"]["event_err"]
    assert "machine_info" in json.loads((tmp_path / "ing" / "provenance.json").read_text())
    rep = write_report(tmp_path / "ing")
    # wall time, nfev and steps (no integrator time in a pytest-benchmark file), and the error along
    assert rep.html.exists() and [f.name.split("_")[1] for f in rep.figures] == [
        "distribution",
        "time",
        "nfev",
        "nsteps",
        "err",
    ]


def test_ingest_over_stored_cases_says_how_many_it_replaced(bench_json, tmp_path, capsys):
    from nsbench.cli import main

    out = tmp_path / "ing"
    assert main(["ingest", str(bench_json), "--out", str(out)]) == 0
    assert "held" not in capsys.readouterr().err  # nothing there before
    assert main(["ingest", str(bench_json), "--out", str(out)]) == 0
    assert f"nsbench: {out} held 2 stored case(s); ingest replaced them with the 2 of {bench_json}" in (
        capsys.readouterr().err
    )


def test_ingested_rows_match_the_runner_on_the_same_cases(bench_json, tmp_path):
    frame = ingest(bench_json, tmp_path / "ing")
    suite = Suite.from_dict(
        {
            "t_span": [0.0, 30.0],
            "problems": [{"name": "one-dof", "case": 1}],
            "repeats": 3,
            "integrators": {"only": ["exact", "scipy-dop853"], "grids": {"scipy-dop853": {"options": [{}]}}},
        }
    )
    runner = run_suite(suite, tmp_path / "run", workers=1, progress=False).results
    merged = frame.merge(runner, on="case_id", suffixes=("_bench", "_run"))
    assert len(merged) == 2  # same case ids
    for key in ("switch_err_max", "n_prefix", "nfev", "state_err_l2"):
        assert (merged[f"{key}_bench"] == merged[f"{key}_run"]).all(), key  # deterministic runs agree


def test_bad_files(tmp_path):
    with pytest.raises(ConfigError, match="does not exist"):
        read_benchmark_json(tmp_path / "nope.json")
    (tmp_path / "x.json").write_text('{"a": 1}')
    with pytest.raises(ConfigError, match="not a pytest-benchmark file"):
        read_benchmark_json(tmp_path / "x.json")


@pytest.mark.parametrize(
    "data, fragment",
    [
        ({"benchmarks": 5}, "'benchmarks' must be a list, got int 5"),
        ({"benchmarks": []}, "holds no benchmarks"),
        ({"benchmarks": [1]}, "benchmarks[0] must be a table"),
        ({"benchmarks": [{"name": "a", "stats": "x"}]}, "benchmarks[0].stats must be a table"),
        ({"benchmarks": [{"name": "a", "extra_info": 5}]}, "benchmarks[0].extra_info must be a table"),
        ({"benchmarks": [{"name": "a", "stats": {"median": "slow"}}]}, "benchmarks[0].stats.median must be a number"),
        ({"benchmarks": [{"name": "a", "stats": {"data": ["x"]}}]}, "stats.data must be a list of times"),
        # values that used to be stored as something else, or lost
        (
            {"benchmarks": [{"name": "a", "stats": {"median": float("inf")}}]},
            "stats.median must be a number of seconds (finite, >= 0), got float inf",
        ),
        ({"benchmarks": [{"name": "a", "stats": {"median": -0.1}}]}, "stats.median must be a number of seconds"),
        ({"benchmarks": [{"name": "a", "stats": {"rounds": -3}}]}, "stats.rounds must be a whole number >= 0"),
        ({"benchmarks": [{"name": "a", "stats": {"rounds": 2.5}}]}, "stats.rounds must be a whole number >= 0"),
        ({"benchmarks": [{"name": "a", "stats": {"data": [0.1, -1]}}]}, "stats.data must be a list of times"),
        (
            {"benchmarks": [{"name": "a", "extra_info": {"n_events": "abc"}}]},
            "benchmarks[0].extra_info.n_events must be a whole number, got str 'abc'",
        ),
        ({"benchmarks": [{"name": "a", "extra_info": {"nfev": -4}}]}, "extra_info.nfev counts something"),
        (
            {"benchmarks": [{"name": "a", "extra_info": {"status": {"a": 1}}}]},
            "extra_info.status must be a string, got dict",
        ),
        ({"benchmarks": [{"name": "a", "extra_info": {"status": "fine"}}]}, "'fine' is not a status"),
        (
            {"benchmarks": [{"name": "a", "extra_info": {"switch_err_max": "small"}}]},
            "extra_info.switch_err_max must be a number",
        ),
        (
            {"benchmarks": [{"name": "a", "extra_info": {"setup_time": float("inf")}}]},
            "extra_info.setup_time must be a number of seconds",
        ),
        ({"benchmarks": [{"name": "a", "extra_info": {"sequence_ok": "yes"}}]}, "sequence_ok must be true or false"),
        ({"benchmarks": [{"name": "a", "extra_info": {"event_err": [1, "x"]}}]}, "event_err must be a list of numbers"),
    ],
)
def test_json_of_the_wrong_shape_is_refused(tmp_path, data, fragment):
    (tmp_path / "x.json").write_text(json.dumps(data))  # inf is written as Infinity, which json reads back
    with pytest.raises(ConfigError) as info:
        read_benchmark_json(tmp_path / "x.json")
    assert fragment in str(info.value)


def test_binary_and_folder_files_are_refused(tmp_path):
    (tmp_path / "b.json").write_bytes(bytes(range(256)))
    with pytest.raises(ConfigError, match="not UTF-8 text"):
        read_benchmark_json(tmp_path / "b.json")
    with pytest.raises(ConfigError, match="is a folder"):
        read_benchmark_json(tmp_path)


@pytest.mark.parametrize("bad", ["../../escaped", "/tmp/nsbench-absolute-escape", "a/b", "..", ".hidden"])
def test_a_case_id_that_names_a_file_elsewhere_is_refused(tmp_path, bad):
    # extra_info comes from whoever wrote the JSON: its case id must not steer a write
    # outside --out (an absolute path, or ../ up from OUT/cases)
    data = {
        "version": "5.0",
        "benchmarks": [
            {
                "name": "b",
                "fullname": "b",
                "stats": {"median": 0.1, "min": 0.1, "max": 0.1, "rounds": 1},
                "extra_info": {"case_id": bad},
            }
        ],
    }
    src = tmp_path / "evil.json"
    src.write_text(json.dumps(data))
    out = tmp_path / "deep" / "out"
    with pytest.raises(ConfigError, match="cannot name a file"):
        ingest(src, out)
    assert not list(tmp_path.rglob("*.parquet")) and not Path("/tmp/nsbench-absolute-escape.parquet").exists()
    from nsbench.cli import main

    assert main(["ingest", str(src), "--out", str(out)]) == 2
    assert not list(tmp_path.rglob("*.parquet"))


def test_duplicate_case_ids_are_refused(tmp_path):
    bench = {
        "name": "b",
        "fullname": "b",
        "stats": {"median": 0.1, "min": 0.1, "max": 0.1, "rounds": 1},
        "extra_info": {"case_id": "same"},
    }
    src = tmp_path / "dup.json"
    src.write_text(json.dumps({"benchmarks": [bench, dict(bench, name="c", fullname="c")]}))
    with pytest.raises(ConfigError, match="more than once"):
        ingest(src, tmp_path / "out")


def test_a_folder_that_is_not_an_nsbench_store_is_not_cleared(bench_json, tmp_path):
    # ingest and `run` (without --resume) replace OUT/cases; a folder nsbench did not
    # write must survive a mistyped --out
    out = tmp_path / "someone-else"
    (out / "cases").mkdir(parents=True)
    keep = out / "cases" / "notes.txt"
    keep.write_text("precious")
    with pytest.raises(ConfigError, match="does not look like an nsbench results folder"):
        ingest(bench_json, out)
    assert keep.read_text() == "precious"


@pytest.fixture(scope="module")
def matched_json(tmp_path_factory):
    """The matched-accuracy module (several integrators, each timing its own call), case 1, over [0, 20]."""
    out = tmp_path_factory.mktemp("matched") / "matched.json"
    env = inner_pytest_env(NSBENCH_BENCH_T_END="20")
    module = "benchmarks/test_ofapi_matched_accuracy.py"
    ids = [f"{module}::test_matched_accuracy[1-{name}]" for name in ("henon-rk4", "ofapi", "mcpi")]
    cmd = [
        sys.executable,
        "-m",
        "pytest",
        *ids,
        "-q",
        "-p",
        "no:cacheprovider",
        "--benchmark-only",
        f"--benchmark-json={out}",
    ]
    done = subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stdout + done.stderr
    return out


def test_ingest_keeps_problem_integrator_span_and_accuracy_of_a_module_with_several_integrators(matched_json, tmp_path):
    frame = ingest(matched_json, tmp_path / "ing").set_index("integrator")
    assert sorted(frame.index) == ["henon-rk4", "mcpi", "ofapi"]
    assert set(frame["problem"]) == {"two-dof"} and set(frame["case"]) == {1}
    assert set(frame["problem_label"]) == {"two-dof/1"}
    assert set(frame["t0"]) == {0.0} and set(frame["t_end"]) == {20.0}
    assert frame.loc["henon-rk4", "step_value"] == 0.0019 and frame.loc["ofapi", "options"] != "{}"
    # the module's own target (1e-10): every event matched and within it
    assert frame["sequence_ok"].all() and (frame["switch_err_max"] <= 1e-10).all()
    assert (frame["n_prefix"] == frame["n_ref"]).all() and (frame["n_ref"] > 0).all()
    assert (frame["reference"] == "exact").all() and (frame["status"] == "success").all()
    rep = write_report(tmp_path / "ing")
    assert any(f.name.startswith("wp_time") for f in rep.figures), [f.name for f in rep.figures]
