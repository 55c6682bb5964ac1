"""``archive merge``: archives joined, each run once, references carried along, damage refused."""

from __future__ import annotations

import pytest

from nsbench.archive import add_run, layout, load, merge_archives
from nsbench.errors import ConfigError
from tests.archive.conftest import copy


@pytest.fixture(scope="module")
def halves(runs, tmp_path_factory):
    """Two archives: run a alone; runs a and b (a is in both)."""
    d = tmp_path_factory.mktemp("halves")
    add_run(runs["a"], d / "one")
    add_run(runs["a"], d / "two")
    add_run(runs["b"], d / "two")
    return d / "one", d / "two"


def test_two_archives_merge_into_a_new_one_without_duplicates(halves, archive, tmp_path):
    one, two = halves
    outcome = merge_archives((one, two), tmp_path / "merged")
    assert (outcome.copied, outcome.duplicates) == (2, 1)
    merged = load(tmp_path / "merged")
    assert sorted(merged.runs["run_id"]) == sorted(load(archive).runs["run_id"])
    assert len(merged.rows) == 11 and not merged.rows.duplicated(["run_id", "case_id"]).any()
    # the references came along: a run added to the merged archive is graded without computing one
    assert len(list((tmp_path / "merged" / layout.REFERENCES).glob("*.json"))) == 1
    again = merge_archives((one, two), tmp_path / "merged")
    assert (again.copied, again.duplicates) == (0, 3)


def test_an_archive_merges_into_one_of_its_sources(halves, tmp_path):
    one = copy(halves[0], tmp_path / "one")
    outcome = merge_archives((one, halves[1]), one)
    assert (outcome.copied, outcome.duplicates) == (1, 1)
    assert len(load(one).runs) == 2


def test_a_damaged_source_is_not_merged(halves, tmp_path):
    two = copy(halves[1], tmp_path / "two")
    rows = sorted((two / layout.RUNS).iterdir())[-1] / layout.ROWS
    rows.write_bytes(rows.read_bytes()[:-10])
    with pytest.raises(ConfigError, match="rows.parquet is damaged"):
        merge_archives((halves[0], two), tmp_path / "merged")
    assert not (tmp_path / "merged").exists()  # checked before anything is written
