"""Sweeps and Lyapunov runs on supervised workers: hard limits, crash isolation, a damaged store."""

from __future__ import annotations

import hashlib
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from nsbench import registry
from nsbench.bifurcation.lyapunov import largest_exponent
from nsbench.bifurcation.parallel import run_sweep
from nsbench.bifurcation.storage import SweepStore
from nsbench.bifurcation.sweep import SweepSpec
from nsbench.errors import ConfigError
from tests.bench import _integrators as faulty
from tests.procs import kill_leaves_no_workers

# v0 = 0.06, 0.08, ..., 0.20: value 5 (v0 = 0.16) lies in faulty.BAD_V0
SPEC = dict(problem="two-dof", case=1, name="v0", start=0.06, stop=0.2, count=8, transient=50.0, record=5)
BAD = 5


@pytest.fixture(scope="module")
def clean(tmp_path_factory):
    """The same sweep with the well-behaved integrator the faulty ones wrap."""
    return run_sweep(
        SweepSpec(integrator="scipy-rk45", **SPEC), tmp_path_factory.mktemp("clean"), workers=0, progress=False
    )


@pytest.fixture
def faulty_registered():
    classes = (faulty.HangingAt, faulty.ExitingAt, faulty.SegfaultingAt, faulty.HangingSetup)
    for cls in classes:
        registry.register("integrators", cls.name, cls)
    yield
    for cls in classes:
        registry.unregister("integrators", cls.name)


@pytest.mark.parametrize(
    "name, status, reason",
    [
        ("hanging-at-test", "time limit", "ran past its limit of 4 s"),
        ("exiting-at-test", "crashed", "exit code 7"),
        ("segfaulting-at-test", "crashed", "signal 11 (SIGSEGV)"),
    ],
)
@pytest.mark.parametrize("workers", [1, 2])
def test_a_bad_value_costs_only_itself(tmp_path, clean, faulty_registered, name, status, reason, workers):
    frame = run_sweep(
        SweepSpec(integrator=name, **SPEC),
        tmp_path / "s",
        workers=workers,
        progress=False,
        point_limit=4.0,
        chunk_size=3,
    )
    first = frame.groupby("index").first()
    assert first.loc[BAD, "status"] == status and reason in first.loc[BAD, "message"]
    assert f"value {BAD} (v0 = 0.16)" in first.loc[BAD, "message"]
    good = frame[frame["index"] != BAD].reset_index(drop=True)
    ref = clean[clean["index"] != BAD].reset_index(drop=True)
    assert (good["status"] == "success").all()
    # the other values are those of the undisturbed integrator, chunk-mates of the bad value included
    np.testing.assert_allclose(
        good[["t", "x1", "v1", "x2", "v2"]], ref[["t", "x1", "v1", "x2", "v2"]], rtol=1e-12, atol=1e-12
    )
    # a rerun keeps the recorded failure (it is a result, not a missing value)
    assert SweepStore(tmp_path / "s").missing() == []


def test_the_point_limit_bounds_a_workers_first_run_too(tmp_path, faulty_registered):
    # every value hangs: the first short run of each worker is a value's run, under --point-limit
    # (it was under the 1800 s set-up limit), and the set-up itself is not blamed
    spec = SweepSpec(integrator="hanging-at-test", **{**SPEC, "start": 0.155, "stop": 0.165, "count": 3})
    frame = run_sweep(spec, tmp_path / "s", workers=2, progress=False, point_limit=2.0, chunk_size=3)
    assert (frame["status"] == "time limit").all() and len(frame) == 3
    assert frame["message"].str.contains("ran past its limit of 2 s").all()
    assert not frame["message"].str.contains("could not be set up").any()


def test_a_setup_that_never_ends_fails_the_sweep_within_its_limit(tmp_path, faulty_registered, capsys):

    # in the command's own process too: the sweep's early check never runs a plug-in's setup
    frame = run_sweep(
        SweepSpec(integrator="hanging-setup-test", **SPEC),
        tmp_path / "s",
        workers=2,
        progress=False,
        setup_limit=2.0,
        chunk_size=1,
    )
    assert (frame["status"] == "time limit").all() and len(frame) == 8
    assert frame["message"].str.contains("integrator set-up ran past its limit of 2 s").all()
    assert frame["message"].str.contains("could not be set up; no value was run").all()


def test_the_command_bounds_a_setup_that_never_ends_by_its_setup_limit(tmp_path):
    # from the command line the set-up limit was fixed at 1800 s (--point-limit does not cover the
    # set-up): a plug-in whose setup loops held the sweep for half an hour
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([os.getcwd(), *sys.path])}
    code = (
        "import sys; from nsbench import registry; from tests.bench import _integrators as f; "
        "registry.register('integrators', f.HangingSetup.name, f.HangingSetup); "
        "from nsbench.cli import main; sys.exit(main(sys.argv[1:]))"
    )
    out = tmp_path / "s"
    tic = time.monotonic()
    done = subprocess.run(
        [
            sys.executable,
            "-c",
            code,
            "bifurcation",
            "two-dof",
            "--case",
            "1",
            "--sweep",
            "v0=0.06:0.2:3",
            "--integrator",
            faulty.HangingSetup.name,
            "--transient",
            "10",
            "--record",
            "2",
            "--workers",
            "1",
            "--setup-limit",
            "3",
            "--formats",
            "png",
            "--out",
            str(out),
            "--no-progress",
        ],
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
    )
    # every value stopped at the set-up limit: the diagram is written, and the exit status says it fell short
    assert done.returncode == 1, done.stderr
    assert (
        done.stderr.strip()
        .splitlines()[-1]
        .startswith(f"nsbench: bifurcation: values failed or incomplete ({faulty.HangingSetup.name} 3 of 3)")
    ), done.stderr
    assert time.monotonic() - tic < 300  # the limit, a worker's start and the import: far below 1800 s
    frame = SweepStore(out).load()
    assert (frame["status"] == "time limit").all() and len(frame) == 3
    assert frame["message"].str.contains("integrator set-up ran past its limit of 3 s").all()


@pytest.mark.parametrize("text", ["0", "-1", "nan", "inf", "soon"])
def test_a_bad_setup_limit_is_refused_with_one_line(tmp_path, text, capsys):
    from nsbench.cli import main

    assert (
        main(["bifurcation", "two-dof", "--sweep", "v0=0.1:0.2:2", "--setup-limit", text, "--out", str(tmp_path / "s")])
        == 2
    )
    assert "--setup-limit" in capsys.readouterr().err
    assert not (tmp_path / "s").exists()


def test_killing_the_cli_ends_its_workers(tmp_path):
    # a sweep whose worker hangs (no limit in sight): kill the CLI, the worker must follow it
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([os.getcwd(), *sys.path])}
    code = (
        "import sys; from nsbench import registry; from tests.bench import _integrators as f; "
        "registry.register('integrators', f.HangingAt.name, f.HangingAt); "
        "from nsbench.cli import main; sys.exit(main(sys.argv[1:]))"
    )
    proc = subprocess.Popen(
        [
            sys.executable,
            "-c",
            code,
            "bifurcation",
            "two-dof",
            "--case",
            "1",
            "--sweep",
            "v0=0.16:0.161:2",
            "--integrator",
            "hanging-at-test",
            "--transient",
            "10",
            "--record",
            "2",
            "--workers",
            "2",
            "--out",
            str(tmp_path / "k"),
            "--no-progress",
        ],
        env=env,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    kill_leaves_no_workers(proc, 2)


def test_a_lyapunov_member_past_its_limit_fails_alone(faulty_registered):
    from nsbench.problems import get_problem

    problem = get_problem("two-dof", case=1, v0=0.16)  # every member hangs here
    res = largest_exponent(
        problem, "hanging-at-test", iterations=80, members=4, transient=10.0, workers=2, member_limit=2.0
    )
    assert res.status == "error" and not res.converged
    assert res.message.count("time limit") == 4 and "member 3" in res.message
    assert np.isnan(res.members).all()


def test_a_lyapunov_setup_that_never_ends_costs_its_members_within_their_limit(faulty_registered):
    # the plug-in's setup ran in the calling process first, with no limit: the command hung there
    from nsbench.problems import get_problem

    tic = time.monotonic()
    res = largest_exponent(
        get_problem("two-dof", case=1),
        faulty.HangingSetup.name,
        iterations=80,
        members=4,
        transient=10.0,
        workers=2,
        member_limit=2.0,
    )
    assert time.monotonic() - tic < 300
    assert res.status == "error" and not res.converged
    assert res.message.count("integrator set-up ran past its limit of 2 s") == 4, res.message


# ------------------------------------------------------------------------------- store integrity
SMALL = dict(
    problem="two-dof", case=1, name="v0", start=0.06, stop=0.2, count=6, transient=100.0, record=8, integrator="exact"
)


def _sweep(out):
    return run_sweep(SweepSpec(**SMALL), out, workers=0, progress=False, chunk_size=2)


def test_a_truncated_chunk_is_refused_then_recomputed(tmp_path, capsys):
    out = tmp_path / "s"
    before = _sweep(out)
    chunk = sorted((out / "points").glob("chunk-*.parquet"))[1]
    data = chunk.read_bytes()
    chunk.write_bytes(data[: int(0.55 * len(data))])  # cut mid-value, like a full disk
    with pytest.raises(ConfigError, match=f"{chunk.name} is damaged"):
        SweepStore(out).load()
    assert set(SweepStore(out).missing()) == {2, 3}
    after = _sweep(out)
    assert f"{chunk.name} is damaged" in capsys.readouterr().err
    assert after.drop(columns="wall_time").equals(before.drop(columns="wall_time"))


def test_a_chunk_under_another_name_or_edited_is_refused(tmp_path):
    out = tmp_path / "s"
    _sweep(out)
    a, b = sorted((out / "points").glob("chunk-*.parquet"))[:2]
    b.write_bytes(a.read_bytes())  # a chunk copied over another's name
    with pytest.raises(ConfigError, match="checksum"):
        SweepStore(out).load()
    _sweep(out)
    c = sorted((out / "points").glob("chunk-*.parquet"))[0]
    text = _csv_text(c)
    legacy = out / "points" / "chunk-000000-0badf00d.csv"  # the naming (and format) of stores without checksums
    c.unlink()
    legacy.write_text(text)
    with pytest.raises(ConfigError, match="does not say which sweep"):
        SweepStore(out).load()  # in a store whose chunks name their sweep, such a chunk is anyone's
    meta = json.loads((out / "meta.json").read_text())
    del meta["spec_key"]  # an old store: written before chunks named their sweep
    (out / "meta.json").write_text(json.dumps(meta))
    for f in (out / "points").glob("chunk-*-s*.parquet"):  # and before checksums: CSV files then
        f.with_name(f.name.rsplit("-", 2)[0] + "-0123456789abcdef.csv").write_text(_csv_text(f))
        f.unlink()
    with pytest.raises(ConfigError, match="checksum"):
        SweepStore(out).load()  # a CSV's checksum is that of its bytes too
    for f in (out / "points").glob("chunk-*-n*.csv"):
        f.rename(f.with_name(f.name.rsplit("-", 1)[0] + f"-{hashlib.sha256(f.read_bytes()).hexdigest()[:16]}.csv"))
    SweepStore(out).load()  # an old store still reads
    legacy.write_text("\n".join(text.splitlines()[:-1]) + "\n")  # one point of a value lost
    with pytest.raises(ConfigError, match="rows where n_points says 8"):
        SweepStore(out).load()


def test_a_parquet_chunk_of_wrong_types_or_missing_values_is_refused(tmp_path):
    """A chunk whose checksum and name hold but whose columns are not of the sweep's types (a counter
    stored as floats) or miss a value (a null status) is damaged: the types are checked, not trusted."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    out = tmp_path / "s"
    _sweep(out)
    for damage, match in (
        ("float counter", "'sticks1' holds double values where the sweep stores int"),
        ("null status", "a value of column 'status' is missing"),
    ):
        c = sorted((out / "points").glob("chunk-*.parquet"))[0]
        table = pq.read_table(c)
        i = table.column_names.index("sticks1" if damage == "float counter" else "status")
        column = table.column(i)
        changed = (
            column.cast(pa.float64())
            if damage == "float counter"
            else pa.array([None] + column.to_pylist()[1:], type=column.type)
        )
        sink = pa.BufferOutputStream()
        pq.write_table(table.set_column(i, table.field(i).name, changed), sink)
        data = sink.getvalue().to_pybytes()
        first, last, rows, _, key = c.stem.split("-")[1:]
        c.unlink()
        (
            out / "points" / f"chunk-{first}-{last}-{rows}-{hashlib.sha256(data).hexdigest()[:16]}-{key}.parquet"
        ).write_bytes(data)
        with pytest.raises(ConfigError, match=match):
            SweepStore(out).load()
        _sweep(out)  # a rerun replaces it


def _csv_text(chunk) -> str:
    """A Parquet chunk's rows as the CSV that stores written before Parquet held."""
    return pd.read_parquet(chunk).to_csv(index=False, float_format="%.17g")


def test_stale_temporary_files_are_removed_on_rerun(tmp_path):
    out = tmp_path / "s"
    _sweep(out)
    stale, fresh = out / "points" / "chunk-000004-x.tmp", out / "points" / "chunk-000005-y.tmp"
    for f in (stale, fresh):
        f.write_text("partial")
    os.utime(stale, (time.time() - 3600, time.time() - 3600))
    _sweep(out)
    assert not stale.exists() and fresh.exists()  # a young one may be another run's, being written


def test_fresh_starts_a_sweep_over_and_refuses_a_foreign_folder(tmp_path):
    out = tmp_path / "s"
    _sweep(out)
    before = {f.name for f in (out / "points").glob("chunk-*.parquet")}
    run_sweep(SweepSpec(**SMALL), out, workers=0, progress=False, chunk_size=2)  # resumes: nothing new
    assert {f.name for f in (out / "points").glob("chunk-*.parquet")} == before
    other = SweepSpec(**{**SMALL, "count": 4})
    with pytest.raises(ConfigError, match="different sweep"):
        run_sweep(other, out, workers=0, progress=False)
    frame = run_sweep(other, out, workers=0, progress=False, fresh=True)  # --fresh replaces it
    assert sorted(frame["index"].unique()) == [0, 1, 2, 3]
    foreign = tmp_path / "mine"
    foreign.mkdir()
    (foreign / "notes.txt").write_text("keep me")
    with pytest.raises(ConfigError, match="not an nsbench sweep folder"):
        run_sweep(other, foreign, workers=0, progress=False, fresh=True)
    assert (foreign / "notes.txt").exists()


def test_stored_columns_keep_their_types(tmp_path):
    """A CSV keeps only text: the reader gives back the types the rows were computed with."""
    from nsbench.bifurcation.sweep import compute_point, failure_rows

    spec = SweepSpec(**SMALL)
    store = SweepStore(tmp_path / "s", spec)
    computed = pd.concat([compute_point(spec, 0), failure_rows(spec, 1, "crashed", "worker ended")], ignore_index=True)
    store.write(computed)
    loaded = SweepStore(tmp_path / "s").load()
    assert loaded.dtypes.to_dict() == computed.dtypes.to_dict()
    assert loaded["wall_time"].dtype == float and np.isnan(loaded["wall_time"].iloc[-1])
    assert float(loaded["wall_time"].sum()) >= 0  # summed as numbers (compare.md's cost table)
    pd.testing.assert_frame_equal(loaded, computed)
    empty = SweepStore(tmp_path / "e", spec).load()
    assert empty.empty and empty.dtypes.to_dict() == computed.dtypes.to_dict()


def test_a_deleted_meta_json_never_lets_stale_values_in(tmp_path, capsys):
    out = tmp_path / "s"
    _sweep(out)
    (out / "meta.json").unlink()
    other = SweepSpec(**{**SMALL, "transient": 60.0})  # another transient: none of the stored points hold
    frame = run_sweep(other, out, workers=0, progress=False, chunk_size=2)
    err = capsys.readouterr().err
    assert err.count("holds values of another sweep") == 3  # each chunk named in one line
    fresh = run_sweep(other, tmp_path / "fresh", workers=0, progress=False, chunk_size=2)
    assert frame.drop(columns="wall_time").equals(fresh.drop(columns="wall_time"))


@pytest.mark.parametrize("damage", ["truncated", "edited", "not json"])
def test_a_damaged_meta_json_is_refused_by_readers_and_rebuilt_by_a_run(tmp_path, capsys, damage):
    out = tmp_path / "s"
    before = _sweep(out)
    meta = out / "meta.json"
    text = meta.read_text()
    meta.write_text(
        {
            "truncated": text[: len(text) // 2],
            "edited": text.replace('"transient": 100.0', '"transient": 60.0'),
            "not json": "\x00\x01",
        }[damage]
    )
    with pytest.raises(ConfigError, match="meta.json is damaged"):
        SweepStore(out).load()
    after = _sweep(out)  # the same sweep again: the stored chunks prove to be its own and are kept
    assert "meta.json is damaged" in capsys.readouterr().err
    assert after.drop(columns="wall_time").equals(before.drop(columns="wall_time"))
    SweepStore(out).load()


def test_a_sweep_never_writes_or_deletes_through_a_link(tmp_path, capsys):
    from nsbench.cli import main

    out = tmp_path / "s"
    _sweep(out)
    elsewhere = tmp_path / "elsewhere"
    (out / "points").rename(elsewhere)
    (out / "points").symlink_to(elsewhere)
    before = sorted(p.name for p in elsewhere.iterdir())
    with pytest.raises(ConfigError, match="points is a symbolic link"):
        run_sweep(SweepSpec(**SMALL), out, workers=0, progress=False, fresh=True)
    assert sorted(p.name for p in elsewhere.iterdir()) == before
    (out / "points").unlink()
    elsewhere.rename(out / "points")
    mine = tmp_path / "my-features.csv"
    mine.write_text("precious")
    (out / "features.csv").symlink_to(mine)
    argv = [
        "bifurcation",
        "two-dof",
        "--case",
        "1",
        "--sweep",
        "v0=0.06:0.2:6",
        "--transient",
        "100",
        "--record",
        "8",
        "--workers",
        "1",
        "--out",
        str(out),
        "--no-progress",
        "--formats",
        "png",
    ]
    assert main(argv) == 2 and "features.csv is a symbolic link" in capsys.readouterr().err
    assert mine.read_text() == "precious"


# ------------------------------------------------------------------------ a plug-in whose setup raises
@pytest.fixture
def broken_setup_registered():
    registry.register("integrators", faulty.BrokenSetup.name, faulty.BrokenSetup)
    yield
    registry.unregister("integrators", faulty.BrokenSetup.name)


def _stderr_lines(err: str) -> list[str]:
    return [line for line in err.splitlines() if line.strip()]


def test_a_setup_that_raises_leaves_its_tracebacks_in_a_log_and_one_line_on_stderr(
    tmp_path, broken_setup_registered, capfd
):
    # issue 52 item 6: each worker printed its traceback (3-4 of them) before the clean outcome
    from nsbench.cli import main

    out = tmp_path / "s"
    argv = ["bifurcation", "two-dof", "--sweep", "v0=0.1:0.2:3", "--integrator", faulty.BrokenSetup.name]
    argv += ["--transient", "10", "--record", "2", "--workers", "2", "--formats", "png", "--out", str(out)]
    assert main([*argv, "--no-progress"]) == 1  # every value failed: exit 1, the folder still written
    err = capfd.readouterr().err  # the file descriptor: the workers' own stderr is the command's
    assert "Traceback" not in err
    line, last = _stderr_lines(err)
    assert last == (
        f"nsbench: bifurcation: values failed or incomplete ({faulty.BrokenSetup.name} 3 of 3); each value's "
        "status is in the sweep's features.csv"
    )
    assert line.startswith("nsbench: warning: ") and "RuntimeError: plug-in bug in setup" in line
    assert str(out / "worker-errors.log") in line
    log = (out / "worker-errors.log").read_text()
    assert "Traceback (most recent call last)" in log and "plug-in bug in setup" in log
    frame = SweepStore(out).load()
    assert len(frame) == 3 and (frame["status"] == "error").all()


def test_a_lyapunov_setup_that_raises_logs_its_tracebacks(tmp_path, broken_setup_registered, capfd):
    from nsbench.cli import main

    out = tmp_path / "ly.csv"
    argv = ["lyapunov", "two-dof", "--case", "2", "--iterations", "80", "--members", "4", "--transient", "10"]
    assert main([*argv, "--integrator", faulty.BrokenSetup.name, "--workers", "2", "--out", str(out)]) == 1
    err = capfd.readouterr().err
    assert "Traceback" not in err
    lines = _stderr_lines(err)
    # the log's line, then the failed run's own line
    assert len(lines) == 2 and f"tracebacks in {out}.worker-errors.log" in lines[0], err
    assert lines[1].startswith("nsbench: lyapunov: no exponent")
    assert Path(f"{out}.worker-errors.log").read_text().count("plug-in bug in setup") >= 4
