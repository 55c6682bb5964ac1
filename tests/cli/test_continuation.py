"""``nsbench continuation``: the files a user gets, and one-line errors on bad input."""

from __future__ import annotations

import json

import pandas as pd
import pytest

from nsbench import get_problem
from nsbench.cli import main
from nsbench.periodic import locate_target


def test_continuation_writes_branch_bifurcations_and_figure(tmp_path, capsys):
    out = tmp_path / "cont"
    code = main(
        [
            "continuation",
            "two-dof",
            "--case",
            "1",
            "--sweep",
            "v0=0.2:0.28",
            "--steps",
            "16",
            "--origin",
            "0.16",
            "--out",
            str(out),
            "--formats",
            "png",
            "--no-progress",
        ]
    )
    assert code == 0
    text = capsys.readouterr().out
    assert "grazing-sliding (sliding)" in text
    branch = pd.read_csv(out / "branch.csv")
    assert {"value", "period", "stable", "multipliers", "pattern"} <= set(branch.columns)
    assert branch["value"].is_monotonic_increasing and branch["stable"].all()
    assert set(branch["pattern"]) == {"slip2 stick2"}
    bifs = pd.read_csv(out / "bifurcations.csv")
    assert {"param", "value", "kind", "category", "detail"} <= set(bifs.columns)
    row = bifs[bifs["kind"] == "grazing-sliding"].iloc[0]
    # the same point found through the API from another start and step: agree far below 1e-8
    ref, _ = locate_target(lambda v: get_problem("two-dof", case=1, v0=v), "v0", 0.16, 0.27, 0.28, steps=40)
    assert abs(row["value"] - ref.value) < 1e-9
    points = pd.read_csv(out / "points.csv")
    assert len(points) >= len(branch)  # at least one peak per orbit
    meta = json.loads((out / "meta.json").read_text())
    assert meta["integrator"] == "exact" and meta["param"] == "v0" and "provenance" in meta
    assert (out / "branches.png").stat().st_size > 0
    # beyond the end of the branch the motion settles to steady sliding: recorded as gaps
    gaps = pd.read_csv(out / "gaps.csv")
    assert (gaps["value"] > row["value"]).all() and gaps["reason"].str.contains("steady sliding").all()


@pytest.mark.parametrize(
    "argv, message",
    [
        (["--sweep", "v0=0.1"], "NAME=START:STOP"),
        (["--sweep", "v0=0.1:0.1"], "two different finite numbers"),
        (["--sweep", "v0=0.1:nan"], "two different finite numbers"),
        (["--sweep", "v0=abc:0.2"], "START"),
        (["--sweep", "v0=0.1:0.2", "--param", "v0=0.3"], "both continued"),
        (["--sweep", "v0=0.1:0.2", "--steps", "0"], "--steps"),
        (["--sweep", "v0=0.1:0.2", "--steps", "2.5"], "--steps"),
        (["--sweep", "v0=0.1:0.2", "--transient", "-1"], "--transient"),
        (["--sweep", "v0=0.1:0.2", "--integrator", "nope"], "nope"),
        (["--sweep", "v0=0.1:0.2", "--formats", "bmpx"], "--formats"),
        (["--sweep", "v0=0.1:0.2", "--section", "strobe"], "harmonic force"),
        (["--sweep", "bogus=0.1:0.2"], "bogus"),
        (["--sweep", "v0=-0.1:0.2"], "v0"),
        (["--sweep", "v0=0.1:0.2", "--diagram", "/nonexistent"], "--diagram"),
        (["--sweep", "v0=0.1:0.2", "--origin", "inf"], "--origin"),
    ],
)
def test_bad_input_is_one_line(argv, message, capsys, tmp_path):
    code = main(["continuation", "two-dof", "--case", "1", "--out", str(tmp_path / "x"), "--no-progress", *argv])
    err = capsys.readouterr().err
    assert code == 2
    assert message in err and "Traceback" not in err
    assert not (tmp_path / "x").exists()  # nothing written before the input is checked


def test_a_plugin_whose_setup_raises_is_one_line_not_a_traceback(tmp_path, capsys):
    # issue 52 item 6: the set-up's RuntimeError ended the command with a traceback
    from nsbench import registry
    from tests.bench import _integrators as faulty

    registry.register("integrators", faulty.BrokenSetup.name, faulty.BrokenSetup)
    try:
        argv = ["continuation", "two-dof", "--sweep", "v0=0.16:0.17", "--steps", "2"]
        code = main([*argv, "--integrator", faulty.BrokenSetup.name, "--out", str(tmp_path / "c"), "--no-progress"])
    finally:
        registry.unregister("integrators", faulty.BrokenSetup.name)
    assert code == 1  # a failed run (the plug-in's fault), not refused input
    err = capsys.readouterr().err
    assert "Traceback" not in err
    (line,) = [ln for ln in err.splitlines() if ln.strip()]
    assert line == (
        f"nsbench: continuation: {faulty.BrokenSetup.name} failed in its set-up on two-dof: "
        "RuntimeError: plug-in bug in setup"
    )
    assert not (tmp_path / "c").exists()  # nothing was written


def test_a_diagram_with_a_chunk_deleted_is_named_as_partial(tmp_path, capsys):
    from nsbench.bifurcation.continuation_command import _diagram

    sweep = tmp_path / "sweep"
    argv = ["bifurcation", "one-dof", "--sweep", "v0=0.5:1.0:4", "--transient", "10", "--record", "4"]
    argv += ["--no-progress", "--formats", "png", "--out", str(sweep), "--workers", "1", "--integrator", "exact"]
    assert main(argv) == 0
    whole = _diagram(str(sweep), "v0")
    assert "warning" not in capsys.readouterr().err
    chunks = sorted((sweep / "points").glob("chunk-*.parquet"))
    assert len(chunks) == 4
    chunks[1].unlink()
    part = _diagram(str(sweep), "v0")
    err = capsys.readouterr().err
    assert f"--diagram {sweep} holds 3 of its 4 values (1 missing" in err
    assert len(part) < len(whole) and set(part["index"]) == {0, 2, 3}


def test_a_link_inside_the_out_folder_is_not_followed(tmp_path, capsys):
    out, elsewhere = tmp_path / "cont", tmp_path / "elsewhere"
    out.mkdir()
    elsewhere.mkdir()
    (out / "branch.csv").symlink_to(elsewhere / "branch.csv")
    argv = ["continuation", "two-dof", "--case", "1", "--sweep", "v0=0.2:0.28", "--steps", "16"]
    assert main([*argv, "--origin", "0.16", "--out", str(out), "--formats", "png", "--no-progress"]) == 2
    assert "branch.csv is a symbolic link" in capsys.readouterr().err
    assert list(elsewhere.iterdir()) == []


def test_a_bad_out_is_refused_before_the_flow_is_built(tmp_path, capsys, monkeypatch):
    # building the flow sets its integrator up, which on a fresh install compiles for minutes and
    # announces it on stderr: a bad --out must be refused before (CI at 99cfdc8 met it so)
    import nsbench.periodic

    def built(*args, **kwargs):
        raise AssertionError("the flow was built before --out was checked")

    monkeypatch.setattr(nsbench.periodic, "HybridFlow", built)
    (tmp_path / "afile").write_text("x")
    argv = ["continuation", "two-dof", "--case", "1", "--sweep", "v0=0.2:0.28", "--out", str(tmp_path / "afile" / "c")]
    assert main(argv) == 2
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert "is a file, not a folder" in line
