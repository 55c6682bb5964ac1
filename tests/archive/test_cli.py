"""``nsbench archive add|show|merge``: exit codes and messages; bad input exits 2 before anything is written."""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

from nsbench.cli import main
from tests.archive.conftest import copy, edited_run


def test_add_show_merge_on_the_command_line(runs, tmp_path, capsys):
    arch = tmp_path / "arch"
    assert main(["archive", "add", str(runs["a"]), "--to", str(arch), "--machine", "ci"]) == 0
    out = capsys.readouterr().out
    assert f"{runs['a']} added to {arch} as run " in out and "machine ci" in out and "4 of 4 rows re-graded" in out
    assert main(["archive", "add", str(runs["a"]), "--to", str(arch)]) == 0
    assert "already in" in capsys.readouterr().out
    assert main(["archive", "add", str(runs["b"]), "--to", str(tmp_path / "other")]) == 0
    assert main(["archive", "merge", str(arch), str(tmp_path / "other"), "--to", str(arch)]) == 0
    assert "1 run(s) copied, 0 already there" in capsys.readouterr().out
    assert main(["archive", "show", str(arch), "--target", "1e-8"]) == 0
    out = capsys.readouterr().out
    assert "2 run(s) in" in out and "one-dof/1, switching-time error <= 1e-08" in out
    assert "<= 0.0001" not in out and "ofapi" in out and "scipy-rk45" in out


def test_a_refused_run_exits_1_naming_its_rows_on_stderr(runs, archive, tmp_path, capsys):
    def edit(frame):
        frame.loc[frame["integrator"] == "henon-rk4", "switch_err_max"] = 1e-13

    forged = edited_run(runs["b"], tmp_path / "forged", edit)
    arch = copy(archive, tmp_path / "arch")
    assert main(["archive", "add", str(forged), "--to", str(arch)]) == 1
    err = capsys.readouterr().err
    assert "refused: 4 row(s) disagree with the archive's re-grading" in err and "nothing was added" in err
    assert err.count("henon-rk4 level") == 4 and "switch_err_max 1e-13 submitted" in err


@pytest.mark.parametrize(
    "argv, message",
    [
        (["add", "{missing}", "--to", "{new}"], "RUN '.*missing' does not exist"),
        (["add", "{run}", "--to", "{file}"], "cannot write --to .*: it is a file, not a folder"),
        (["add", "{run}", "--to", "{foreign}"], "--to .* is not empty and holds no archive.json"),
        (["add", "{run}", "--to", "{new}", "--machine", "a\tb"], "--machine 'a\\\\tb': give a non-empty name"),
        (["show", "{new}"], "is no nsbench archive"),
        (["show", "{archive}", "--target", "-1"], "--target = '-1': give a positive, finite"),
        (["show", "{archive}", "--target", "fast"], "--target = 'fast' is not a number"),
        (["show", "{archive}", "--problem", "two-dof/9"], "--problem 'two-dof/9' is in no run"),
        (["merge", "{archive}", "--to", "{new}"], "archive merge takes two or more archives, got 1"),
        (["merge", "{archive}", "{foreign}", "--to", "{new}"], "no nsbench archive"),
        (["merge", "{archive}", "{archive}", "--to", "{foreign}"], "is not empty and holds no archive.json"),
        (["add", "{run}"], "the following arguments are required: --to"),
    ],
)
def test_bad_input_exits_2_with_one_line_before_anything_is_written(argv, message, runs, archive, tmp_path, capsys):
    (tmp_path / "file").write_text("x")
    (tmp_path / "foreign").mkdir()
    (tmp_path / "foreign" / "mine.txt").write_text("x")
    names = dict(
        missing=tmp_path / "missing", new=tmp_path / "new", file=tmp_path / "file", foreign=tmp_path / "foreign"
    )
    words = [w.format(run=runs["a"], archive=archive, **names) for w in argv]
    before = sorted(p.name for p in tmp_path.rglob("*"))
    assert main(["archive", *words]) == 2
    err = capsys.readouterr().err
    assert err.startswith("nsbench: error: ") and len(err.strip().splitlines()) == 1, err
    assert re.search(message, err), err
    assert sorted(p.name for p in tmp_path.rglob("*")) == before  # nothing written


def test_each_action_builds_one_request_and_calls_one_app_function():
    # the pattern tests/test_layers.py checks for single-action commands, action by action
    tree = ast.parse(Path(__file__).parents[2].joinpath("src/nsbench/cli/archive.py").read_text())
    functions = {node.name: node for node in tree.body if isinstance(node, ast.FunctionDef)}
    assert set(functions) == {"add_parser", "add", "show", "merge", "site"}
    for name in ("add", "show", "merge", "site"):
        imported = {
            a.asname or a.name for n in ast.walk(functions[name]) if isinstance(n, ast.ImportFrom) for a in n.names
        }
        calls = [ast.unparse(c.func) for c in ast.walk(functions[name]) if isinstance(c, ast.Call)]
        called = [c for c in calls if c in imported]
        assert len(called) == 2 and sum(c.endswith("Request") for c in called) == 1, (name, called)
