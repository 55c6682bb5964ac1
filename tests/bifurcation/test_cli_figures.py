"""``nsbench bifurcation`` end to end: diagram, locus and portrait figures, candidates, comparison."""

from __future__ import annotations

import re

import pandas as pd

from nsbench.cli import main


def test_bifurcation_command_writes_figures(tmp_path, capsys):
    out = tmp_path / "b"
    code = main(
        [
            "bifurcation",
            "two-dof",
            "--case",
            "1",
            "--sweep",
            "v0=0.1:0.2:6",
            "--transient",
            "300",
            "--record",
            "20",
            "--workers",
            "1",
            "--out",
            str(out),
            "--portrait",
            "0.1",
            "--no-progress",
        ]
    )
    assert code == 0
    for stem in ("diagram", "locus_v0_0.1", "portrait_v0_0.1"):
        for fmt in ("png", "svg", "pdf"):
            path = out / f"{stem}.{fmt}"
            assert path.exists() and path.stat().st_size > 1000, path
    feats = pd.read_csv(out / "features.csv")
    assert len(feats) == 6 and {"period", "pure_sliding", "block1_sticks"} <= set(feats.columns)
    assert "diagram ->" in capsys.readouterr().out


def test_several_integrators_are_compared(tmp_path):
    out = tmp_path / "c"
    code = main(
        [
            "bifurcation",
            "two-dof",
            "--case",
            "2",
            "--sweep",
            "F=0.2:0.4:3",
            "--transient",
            "200",
            "--record",
            "8",
            "--workers",
            "1",
            "--out",
            str(out),
            "--integrator",
            "exact",
            "--integrator",
            "ofapi",
            "--formats",
            "png",
            "--no-progress",
        ]
    )
    assert code == 0
    text = (out / "compare.md").read_text()
    assert "ofapi" in text and "Hausdorff" in text
    agree = pd.read_csv(out / "agreement.csv")
    # OFAPI at its default tolerance (1e-13) on periodic stroboscopic points: within 1e-9 of the closed form
    assert (agree["ofapi"] < 1e-9).all()


def test_bad_input_exits_2(tmp_path, capsys):
    assert main(["bifurcation", "two-dof", "--sweep", "v0=0.1:0.2", "--out", str(tmp_path / "x")]) == 2
    assert main(["bifurcation", "two-dof", "--sweep", "nope=0.1:0.2:3", "--out", str(tmp_path / "y")]) == 2
    assert (
        main(
            [
                "bifurcation",
                "two-dof",
                "--case",
                "3",
                "--sweep",
                "v0=0.1:0.2:3",
                "--integrator",
                "exact",
                "--out",
                str(tmp_path / "z"),
                "--no-progress",
            ]
        )
        == 2
    )
    err = capsys.readouterr().err
    assert err.count("nsbench: error:") == 3


def test_a_chain_sweeps_with_its_own_columns(tmp_path, monkeypatch):
    """``nsbench bifurcation chain --n 4``: columns x1..x4, v1..v4, per-block counters, locus of a chosen pair."""
    monkeypatch.chdir(tmp_path)
    code = main(
        [
            "bifurcation",
            "chain",
            "--n",
            "4",
            "--case",
            "1",
            "--sweep",
            "v0=0.06:0.2:4",
            "--transient",
            "200",
            "--record",
            "10",
            "--workers",
            "1",
            "--portrait",
            "0.1",
            "--pair",
            "2,4",
            "--formats",
            "png",
            "--no-progress",
        ]
    )
    assert code == 0
    out = tmp_path / "bifurcation" / "chain-n4-case1-v0"  # the default folder names n
    points = pd.concat([pd.read_parquet(f) for f in (out / "points").glob("*.parquet")])
    assert {f"{q}{i}" for i in range(1, 5) for q in "xv"} <= set(points.columns)
    assert {"sticks4", "slips4", "reverses4"} <= set(points.columns) and "x5" not in points.columns
    assert (points["status"] == "success").all() and points["index"].nunique() == 4
    assert (out / "locus_v0_0.1.png").stat().st_size > 1000


def test_chain_block_count_errors_exit_2(tmp_path, capsys):
    assert main(["bifurcation", "chain", "--n", "0", "--sweep", "v0=0.1:0.2:3", "--out", str(tmp_path / "a")]) == 2
    assert main(["bifurcation", "chain", "--n", "4", "--sweep", "n=2:4:3", "--out", str(tmp_path / "b")]) == 2
    assert (
        main(
            [
                "bifurcation",
                "chain",
                "--n",
                "3",
                "--param",
                "n=4",
                "--sweep",
                "v0=0.1:0.2:3",
                "--out",
                str(tmp_path / "c"),
            ]
        )
        == 2
    )
    assert main(["simulate", "two-dof", "--n", "3"]) == 2
    err = capsys.readouterr().err
    assert "integer from 1 to 64" in err and "cannot be swept" in err and "once" in err
    assert "unknown parameter 'n'" in err


def test_a_failing_member_of_several_integrators_is_compared(tmp_path, capsys):
    """A member with failed values: its stored wall times stay numbers, and compare.md is written."""
    from nsbench import registry
    from nsbench.bifurcation.storage import SweepStore
    from tests.bench import _integrators as faulty

    registry.register("integrators", faulty.ExitingAt.name, faulty.ExitingAt)
    try:
        out = tmp_path / "m"
        code = main(
            [
                "bifurcation",
                "two-dof",
                "--case",
                "1",
                "--sweep",
                "v0=0.06:0.2:8",
                "--transient",
                "50",
                "--record",
                "5",
                "--workers",
                "1",
                "--out",
                str(out),
                "--integrator",
                "exact",
                "--integrator",
                "ofapi",
                "--integrator",
                faulty.ExitingAt.name,
                "--formats",
                "png",
                "--no-progress",
            ]
        )
    finally:
        registry.unregister("integrators", faulty.ExitingAt.name)
    err = capsys.readouterr().err
    assert code == 1, err  # a value failed: the folders and the comparison are written, the exit status says so
    assert (
        err.strip()
        .splitlines()[-1]
        .startswith(f"nsbench: bifurcation: values failed or incomplete ({faulty.ExitingAt.name} 1 of 8)")
    ), err
    stored = SweepStore(out / faulty.ExitingAt.name).load()
    assert stored["wall_time"].dtype == float and (stored["status"] == "crashed").sum() == 1  # v0 = 0.16
    text = (out / "compare.md").read_text()
    rows = re.sub(" +", " ", text).splitlines()  # tables are padded to their columns
    row = next(line for line in rows if line.startswith(f"| {faulty.ExitingAt.name} | 8 | 1 |"))
    assert row.count("|") > 5
    agree = pd.read_csv(out / "agreement.csv")
    assert agree[faulty.ExitingAt.name].isna().sum() == 1 and (agree["ofapi"] < 1e-9).all()


def test_a_portrait_whose_plugin_hangs_costs_only_the_portrait(tmp_path, capsys):
    """The locus run of --portrait runs in a supervised worker under --point-limit, not in the command."""
    from nsbench import registry
    from tests.bench import _integrators as faulty

    registry.register("integrators", faulty.HangingAt.name, faulty.HangingAt)
    try:
        out = tmp_path / "p"
        code = main(
            [
                "bifurcation",
                "two-dof",
                "--case",
                "1",
                "--sweep",
                "v0=0.06:0.2:8",
                "--transient",
                "50",
                "--record",
                "5",
                "--workers",
                "1",
                "--out",
                str(out),
                "--integrator",
                faulty.HangingAt.name,
                "--portrait",
                "0.16",
                "--portrait",
                "0.1",
                "--point-limit",
                "3",
                "--formats",
                "png",
                "--no-progress",
            ]
        )
    finally:
        registry.unregister("integrators", faulty.HangingAt.name)
    printed = capsys.readouterr().out
    assert code == 1  # the value at 0.16 hangs in the sweep too: kept with status 'time limit'
    assert "locus and portrait at v0_0.16 failed: time limit" in printed and "ran past its limit of 3 s" in printed
    assert (out / "diagram.png").exists() and (out / "locus_v0_0.1.png").exists()
    assert not (out / "locus_v0_0.16.png").exists()


def test_a_problem_without_presets_is_named_without_a_case(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)  # the default output folder lands here
    argv = ["bifurcation", "bouncing-ball", "--sweep", "e=0.5:0.6:2", "--transient", "1", "--record", "2"]
    assert main([*argv, "--no-progress", "--formats", "png", "--workers", "1"]) == 0
    # the folder and the diagram's title name no case the bouncing ball does not have
    assert [p.name for p in (tmp_path / "bifurcation").iterdir()] == ["bouncing-ball-e"]
    from nsbench.bifurcation.sweep_command import case_text as _case_text

    class Spec:  # the two things _case_text reads of a sweep's spec
        case, start = 1, 0.5

        @staticmethod
        def problem_at(value):
            from nsbench.problems import get_problem

            return get_problem("bouncing-ball", e=value)

    assert _case_text(Spec) == ""
    Spec.problem_at = staticmethod(lambda value: __import__("nsbench").get_problem("one-dof", case=1, v0=value))
    assert _case_text(Spec) == " case 1"
