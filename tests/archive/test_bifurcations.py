"""The bifurcation targets in the archive: a real ``nsbench bench`` run of a suite with one target,
its rows kept by ``add`` (as submitted, checksummed), returned by ``load``, ranked by cost by ``show``
and ``site`` (the configurations that did not locate it listed after, with the reason), carried by
``merge``; a damaged file refused on read."""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd
import pytest

from nsbench.archive import add_run, layout, load, merge_archives
from nsbench.archive.show import bifurcation_board, render_bifurcations
from nsbench.bench import targets
from nsbench.cli import main
from nsbench.errors import ConfigError
from tests.archive.conftest import copy

#: One problem, the reference and two cheap methods under test at one level each, one bifurcation
#: target (the default suite's case1-stick1-starts, with a coarse xtol and few periods: 6 probes each).
SUITE = """
name = "tinybif"
t_span = [0, 5]
repeats = 3
min_sample_time = 0
problems = [{ name = "two-dof", case = 1 }]
[integrators]
only = ["exact", "ofapi", "henon-rk4"]
[integrators.grids.ofapi]
options = [{}]
[integrators.grids.henon-rk4]
options = [{ h = 0.01 }]

[[bifurcation_targets]]
name = "stick1"
problem = "two-dof"
case = 1
param = "v0"
origin = 0.16
bracket = [0.0995, 0.101]
kind = "grazing-sliding"
periods = 3
max_probes = 12
xtol = 1e-4
"""


@pytest.fixture(scope="module")
def bif_run(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("bifrun")
    (d / "bif.toml").write_text(SUITE)
    argv = ["bench", str(d / "bif.toml"), "--out", str(d / "out"), "--workers", "1", "--no-progress", "--no-report"]
    assert main(argv) == 0
    return d / "out"


@pytest.fixture(scope="module")
def bif_archive(bif_run, tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("bifarch") / "arch"
    outcome = add_run(bif_run, path)
    assert outcome.run is not None and not outcome.refused, outcome
    return path


def _folder(archive: Path) -> Path:
    (folder,) = sorted((archive / layout.RUNS).iterdir())
    return folder


def test_the_run_located_the_target_near_the_default_suites_value(bif_run):
    rows = targets.load_rows(bif_run)
    assert sorted(rows["integrator"]) == ["henon-rk4", "ofapi"] and (rows["status"] == "success").all()
    # the default suite's comment: block 1 starts sticking at v0 ~ 0.10042 (located there independently)
    assert (abs(rows["reference_value"] - 0.10042) < 1e-5).all()
    assert ((rows["bifurcation_value"] - rows["reference_value"]).abs() == rows["bifurcation_error"]).all()
    assert (rows["bifurcation_error"] <= rows["xtol"]).all()  # the bisection's resolution, 1e-4


def test_add_keeps_the_rows_as_submitted_under_the_manifests_checksum(bif_archive, bif_run):
    folder = _folder(bif_archive)
    manifest = json.loads((folder / layout.MANIFEST).read_text())
    assert manifest["sha256"][layout.BIFURCATIONS] == layout.digest(folder / layout.BIFURCATIONS)
    kept = layout.read_table(folder / layout.BIFURCATIONS)  # checked against its values' checksum
    sent = targets.load_rows(bif_run)
    assert list(kept.columns) == [*targets.COLUMN_NAMES, "run_id"] and set(kept["run_id"]) == {folder.name}
    for name in ("row_id", "integrator", "bifurcation_value", "bifurcation_error", "integrator_time", "n_probes"):
        assert kept[name].tolist() == sent[name].tolist(), name


def test_a_run_without_targets_has_no_bifurcation_file_and_loads_none(archive):
    for folder in (archive / layout.RUNS).iterdir():
        assert not (folder / layout.BIFURCATIONS).exists()
        assert layout.BIFURCATIONS not in json.loads((folder / layout.MANIFEST).read_text())["sha256"]
    tables = load(archive)
    assert tables.bifurcations.empty and "bifurcation_error" in tables.bifurcations
    assert bifurcation_board(tables).empty


def test_load_returns_them_beside_the_three_tables(bif_archive, bif_run):
    rows, events, runs = load(bif_archive)  # the three-table shape still unpacks
    tables = load(bif_archive, events=False)
    bif = tables.bifurcations
    sent = targets.load_rows(bif_run)
    for name in sent.columns:  # the bench's dtypes
        assert bif[name].dtype == sent[name].dtype, name
    assert len(bif) == 2 and set(bif["run_id"]) == set(runs["run_id"]) == set(rows["run_id"])
    assert len(rows) == 3  # the suite's three cases


def test_show_lists_them_with_the_reports_table_per_machine(bif_archive, bif_run, tmp_path, capsys):
    board = bifurcation_board(load(bif_archive))
    report = targets.report_table(targets.load_rows(bif_run))
    assert report["integrator"].tolist() == ["henon-rk4", "ofapi"]
    in_report_order = board.sort_values(["integrator", "level"], ignore_index=True)
    for name in report.columns:  # the report's own table, value for value
        assert in_report_order[name].tolist() == report[name].tolist(), name
    assert set(board["problem"]) == {"two-dof/1"} and len(set(board["machine"])) == 1
    assert main(["archive", "show", str(bif_archive), "--problem", "two-dof/1"]) == 0
    out = capsys.readouterr().out
    assert "two-dof/1, bifurcation target stick1 (" in out and "not re-graded" in out and "no interval" in out
    for _, e in board.iterrows():
        assert f"{e['integrator']:<22}" in out and e["bifurcation_value"] in out
    assert "Each method's cheapest configuration" in out and "located/of" in out
    assert main(["archive", "show", str(bif_archive), "--every-configuration"]) == 0
    assert "Every configuration of every run" in capsys.readouterr().out
    # a second machine's copy of the run is listed in a block of its own
    two = copy(bif_archive, tmp_path / "two")
    edited = tmp_path / "b"
    edited.mkdir()
    for name in ("provenance.json", "bifurcation_targets.parquet"):
        (edited / name).write_bytes((bif_run / name).read_bytes())
    frame = pd.read_parquet(bif_run / "results.parquet")
    frame["timestamp"] = "2026-01-01T00:00:00+00:00"  # another run: other rows, another id
    frame.to_parquet(edited / "results.parquet", index=False)
    assert add_run(edited, two, machine="laptop").run is not None
    blocks = bifurcation_board(load(two)).groupby("machine")["integrator"].apply(sorted)
    assert blocks.to_dict() == {m: ["henon-rk4", "ofapi"] for m in blocks.index} and "laptop" in blocks.index


#: The suite above with two more henon-rk4 steps, too coarse to locate the bifurcation within xtol
#: (h = 0.3: located 2.2e-4 away; h = 1.0: its far end still repeats the near-side pattern, no bracket).
COARSE = SUITE.replace("options = [{ h = 0.01 }]", "options = [{ h = 0.01 }, { h = 0.3 }, { h = 1.0 }]")


@pytest.fixture(scope="module")
def coarse_run(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("coarse")
    (d / "bif.toml").write_text(COARSE)
    argv = ["bench", str(d / "bif.toml"), "--out", str(d / "out"), "--workers", "1", "--no-progress", "--no-report"]
    assert main(argv) == 0
    return d / "out"


def _again(run: Path, to: Path, when: str) -> Path:
    """The run's results as another run (another timestamp: another id), its bifurcation rows the same."""
    to.mkdir()
    for name in ("provenance.json", "bifurcation_targets.parquet"):
        (to / name).write_bytes((run / name).read_bytes())
    frame = pd.read_parquet(run / "results.parquet")
    frame["timestamp"] = when
    frame.to_parquet(to / "results.parquet", index=False)
    return to


def test_the_configurations_that_located_it_are_ranked_by_cost_the_others_listed_after(coarse_run, tmp_path):
    assert add_run(coarse_run, tmp_path / "arch").run is not None
    board = bifurcation_board(load(tmp_path / "arch"), per="configuration")
    sent = targets.load_rows(coarse_run)
    assert len(board) == len(sent) == 4 and len(set(board["run_id"])) == 1
    # located within xtol: success and an error within it (by the rows themselves, not the board's code)
    located = sent[(sent["status"] == "success") & (sent["bifurcation_error"] <= sent["xtol"])]
    assert sorted(located["options"]) == ['{"h": 0.01}', "{}"]  # henon-rk4 h = 0.01 and ofapi
    ranked = board[board["rank"].notna()]
    assert len(ranked) == len(located) and (ranked["reason"] == "").all()
    costs = ranked["cost (s)"].tolist()
    for rank, cost in zip(ranked["rank"], costs):  # 1 + the located configurations strictly cheaper
        assert rank == 1 + sum(c < cost for c in costs)
    assert board.index[board["rank"].notna()].tolist() == [0, 1]  # ranked first, cheapest first
    after = board[board["rank"].isna()]
    assert after["options"].tolist() == ["h=0.3", "h=1"] and not after["tie"].any()
    assert after["reason"].iloc[0].startswith("located 0.000218 from the reference's location, beyond its xtol 0.0001")
    assert after["reason"].iloc[1].startswith("no bracket: at the far end v0 = 0.0995")
    assert board["located"].tolist() == [1, 1, 0, 0] and (board["configurations"] == 1).all()
    text = render_bifurcations(board, per="configuration")
    assert "   -  henon-rk4" in text and "(not ranked: no bracket" in text and "no interval" in text
    assert "Every configuration of every run" in text


def test_one_entry_per_method_its_cheapest_located_configuration(coarse_run, tmp_path):
    assert add_run(coarse_run, tmp_path / "arch").run is not None
    tables = load(tmp_path / "arch")
    every = bifurcation_board(tables, per="configuration")
    board = bifurcation_board(tables)  # per method, what show and site list
    assert sorted(board["integrator"]) == ["henon-rk4", "ofapi"] and (board["reason"] == "").all()
    henon = board[board["integrator"] == "henon-rk4"].iloc[0]
    assert henon["options"] == "h=0.01" and (henon["located"], henon["configurations"]) == (1, 3)
    # the ranks are those of the located configurations: here one per method
    located = every[every["reason"] == ""]
    assert board.set_index("integrator")["rank"].to_dict() == located.set_index("integrator")["rank"].to_dict()
    # a method none of whose configurations located it: its closest one (a finite error before none), unranked
    without = tables.bifurcations[tables.bifurcations["options"] != '{"h": 0.01}']
    tables.bifurcations = without
    board = bifurcation_board(tables)
    henon = board[board["integrator"] == "henon-rk4"].iloc[0]
    assert (
        pd.isna(henon["rank"]) and henon["options"] == "h=0.3" and (henon["located"], henon["configurations"]) == (0, 2)
    )
    assert henon["reason"].startswith("located 0.000218 from the reference's location")
    assert board["rank"].dropna().tolist() == [1]  # ofapi alone ranked
    text = render_bifurcations(board)
    assert "0/2" in text and "1/1" in text and "its closest configuration" in text
    with pytest.raises(ConfigError, match="per = 'run'"):
        bifurcation_board(tables, per="run")


def test_equal_costs_tie_and_another_machine_is_ranked_apart(coarse_run, tmp_path):
    # the same submission added again as another run (another id): each configuration's recorded cost
    # equals its copy's, so the two share a rank; a third copy, of another machine, is ranked on its own
    arch = tmp_path / "arch"
    assert add_run(coarse_run, arch).run is not None
    assert add_run(_again(coarse_run, tmp_path / "b", "2026-01-01T00:00:00+00:00"), arch).run is not None
    laptop = _again(coarse_run, tmp_path / "c", "2026-01-02T00:00:00+00:00")
    assert add_run(laptop, arch, machine="laptop").run is not None
    board = bifurcation_board(load(arch), per="configuration")
    here = board[board["machine"] != "laptop"]
    ranked = here[here["rank"].notna()]
    assert ranked["rank"].tolist() == [1, 1, 3, 3] and ranked["tie"].all()
    for _, pair in ranked.groupby("rank"):
        assert len(set(pair["run_id"])) == 2 and len(set(pair["cost (s)"])) == 1
    other = board[board["machine"] == "laptop"]
    assert other["rank"].dropna().tolist() == [1, 2] and not other["tie"].any()
    assert "= tied: equal costs" in render_bifurcations(board, per="configuration")
    assert board["rank"].tolist() == _ranking_ranks(board).tolist()  # ties included
    # one entry per method and block: the two copies' equal costs are one method's, so no tie
    methods = bifurcation_board(load(arch))
    for _, block in methods.groupby("machine"):
        assert sorted(block["integrator"]) == ["henon-rk4", "ofapi"] and block["rank"].tolist() == [1, 2]
        assert not block["tie"].any() and methods["rank"].tolist() == _ranking_ranks(methods).tolist()
    counts = methods[methods["machine"] != "laptop"].set_index("integrator")[["located", "configurations"]]
    assert counts.to_dict("index") == {
        "henon-rk4": {"located": 2, "configurations": 6},
        "ofapi": {"located": 2, "configurations": 2},
    }


def _ranking_ranks(board: pd.DataFrame) -> pd.Series:
    """The board's ranks as the leaderboard's ranking code (``tables.ranking``) gives them, block by block, one
    entry per configuration (its row as the "integrator" ranked), without timing samples: what ``show``
    computes at once with pandas' min-rank."""
    from nsbench.bench.tables import ranking
    from nsbench.status import TargetOutcome

    ranks = pd.Series(pd.NA, index=board.index, dtype="Int64")
    located = board[board["reason"] == ""]
    for _, block in located.groupby(["problem", "target", "machine", "environment"], sort=False):
        key = pd.Series([f"row{i}" for i in block.index], index=block.index)
        long = pd.DataFrame(
            {
                "problem_label": block["problem"].astype(str),
                "target": block["target"].astype(str),
                "integrator": key,
                "case_id": key,
                "outcome": TargetOutcome.REACHED,
                "wall_time": block["cost (s)"].astype(float),
            }
        )
        rank = ranking(long).set_index("integrator")["rank"]
        ranks.loc[block.index] = [int(rank[k]) for k in key]
    return ranks


def test_site_shows_them(bif_archive, tmp_path):
    assert main(["archive", "site", str(bif_archive), "--out", str(tmp_path / "site")]) == 0
    text = (tmp_path / "site" / "index.html").read_text()
    assert "<h2>Bifurcation targets</h2>" in text and "two-dof/1, bifurcation target stick1" in text
    assert "no interval" in text and "<th>rank</th>" in text
    for value in bifurcation_board(load(bif_archive))["bifurcation_value"]:
        assert value in text


def test_merge_carries_them(bif_archive, archive, tmp_path):
    outcome = merge_archives((bif_archive, archive), tmp_path / "merged")
    assert outcome.copied == 3
    merged = load(tmp_path / "merged")
    assert merged.bifurcations.drop(columns="run_id").equals(load(bif_archive).bifurcations.drop(columns="run_id"))
    assert (tmp_path / "merged" / layout.RUNS / _folder(bif_archive).name / layout.BIFURCATIONS).is_file()


@pytest.mark.parametrize("how", ["flip", "delete"])
def test_a_damaged_bifurcation_file_is_refused_on_read(bif_archive, tmp_path, how):
    path = copy(bif_archive, tmp_path / "arch")
    target = _folder(path) / layout.BIFURCATIONS
    if how == "flip":
        data = bytearray(target.read_bytes())
        data[len(data) // 2] ^= 0x01
        target.write_bytes(bytes(data))
    else:
        target.unlink()
    with pytest.raises(ConfigError, match="bifurcations.parquet"):
        load(path, events=False)
    with pytest.raises(ConfigError, match="bifurcations.parquet"):
        merge_archives((path, bif_archive), tmp_path / "merged")
