"""``archive show``: a leaderboard per (problem, target) over every archived run, with the report's ties."""

from __future__ import annotations

import pandas as pd
import pytest

from nsbench.archive import add_run, leaderboard, load
from nsbench.archive.show import TARGETS, render
from nsbench.bench import storage
from nsbench.bench.stats import median_interval, tied_with
from nsbench.bench.summary import samples_of
from nsbench.bench.tables import fixed_target
from tests.archive.conftest import edited_run


@pytest.fixture(scope="module")
def board(archive) -> pd.DataFrame:
    return leaderboard(load(archive))


def _samples(tables, entry) -> list[float]:
    rows = tables.rows
    method = rows[(rows["run_id"] == entry["run_id"]) & (rows["integrator"] == entry["method"])]
    return samples_of(method[method["level"] == entry["level"]].iloc[0])


def test_the_leaderboard_lists_both_runs_methods_under_test(board, archive):
    tables = load(archive)
    assert set(board["run_id"]) == set(tables.runs["run_id"])
    assert set(board["method"]) == {"scipy-rk45", "ofapi", "henon-rk4"}  # exact, the reference, is not ranked
    assert set(board["target"]) <= set(TARGETS) and set(board["problem"]) == {"one-dof/1"}


def test_each_entry_is_the_cheapest_configuration_reaching_the_target_as_the_report_finds_it(board, archive):
    rows = load(archive).rows
    long = fixed_target(rows, TARGETS)
    for _, e in board.iterrows():
        cell = long[(long["integrator"] == e["method"]) & (long["target"] == e["target"])].iloc[0]
        assert cell["outcome"] == "reached" and cell["wall_time"] == e["wall_time"] and cell["level"] == e["level"]
        assert e["switch_err_max"] <= e["target"]


def test_ties_are_where_the_timings_cannot_be_told_apart(board, archive):
    tables = load(archive)
    for _, block in board.groupby(["problem", "target", "machine", "environment"]):
        block = block.sort_values("wall_time")
        fastest = _samples(tables, block.iloc[0])
        assert block.iloc[0]["rank"] == 1
        for _, e in block.iloc[1:].iterrows():
            own = _samples(tables, e)
            # the report's rule: overlapping median intervals, or a cost ratio whose interval holds 1
            assert (e["rank"] == 1) == tied_with(fastest, own)
            if median_interval(fastest).overlaps(median_interval(own)):
                assert e["rank"] == 1 and e["tie"]
            low, high = median_interval(own).low, median_interval(own).high
            assert (e["wall_low"], e["wall_high"]) == (low, high) and low <= e["wall_time"] <= high
        assert block["tie"].tolist() == [bool((block["rank"] == r).sum() > 1) for r in block["rank"]]


def test_runs_of_another_machine_are_ranked_apart(runs, tmp_path):
    add_run(runs["a"], tmp_path / "arch")
    add_run(runs["b"], tmp_path / "arch", machine="laptop")
    board = leaderboard(load(tmp_path / "arch"))
    assert len(set(board["machine"])) == 2
    for machine, block in board.groupby("machine"):
        expected = {"ofapi", "henon-rk4"} if machine == "laptop" else {"scipy-rk45"}
        assert set(block["method"]) == expected
        assert (block.groupby("target")["rank"].min() == 1).all()  # each machine has its own fastest


def test_a_method_whose_timings_match_the_fastests_is_tied_with_it(runs, tmp_path):
    # timings are the submitter's (only errors are re-graded): scipy-rk45's samples made those of run
    # b's fastest entry at 1e-4 cannot be told from them (the same samples: equal medians and intervals)
    add_run(runs["b"], tmp_path / "arch")
    head = leaderboard(load(tmp_path / "arch"), targets=(1e-4,)).sort_values("wall_time").iloc[0]
    b = storage.load_results(runs["b"])
    fast = b[(b["integrator"] == head["method"]) & (b["level"] == head["level"])].iloc[0]

    def edit(frame: pd.DataFrame) -> None:
        i = frame.index[(frame["integrator"] == "scipy-rk45") & (frame["level"] == 0)][0]
        frame.at[i, "wall_times"] = list(fast["wall_times"])
        frame.at[i, "wall_time"] = fast["wall_time"]

    add_run(edited_run(runs["a"], tmp_path / "a", edit), tmp_path / "arch")
    board = leaderboard(load(tmp_path / "arch"), targets=(1e-4,))
    top = board[board["rank"] == 1]
    assert {head["method"], "scipy-rk45"} <= set(top["method"]) and top["tie"].all()
    assert "   1 =" in render(board) and "= tied" in render(board)


def test_the_text_says_how_costs_are_compared_and_marks_ties(board):
    text = render(board)
    assert text.startswith("Costs are compared only within one machine and environment")
    assert "one-dof/1, switching-time error <= 0.0001" in text
    assert any(line[4:6] == " =" for line in text.splitlines()) == bool(board["tie"].any())
    assert "no graded run" in render(board.iloc[0:0])
