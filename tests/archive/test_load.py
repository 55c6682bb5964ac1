"""``nsbench.archive.load``: an archive as pandas tables, ready to set a notebook's own run beside."""

from __future__ import annotations

import pandas as pd
import pytest

import nsbench.archive
from nsbench.archive import layout
from nsbench.bench import storage
from nsbench.errors import ConfigError
from tests.archive.conftest import copy


def test_load_gives_rows_events_and_runs_in_the_bench_dtypes(archive, runs):
    rows, events, runs_table = nsbench.archive.load(archive)
    assert list(rows.columns)[-len(layout.ARCHIVE_COLUMNS) :] == list(layout.ARCHIVE_COLUMNS)
    mine = storage.load_results(runs["a"])
    for name in mine.columns:  # the bench's columns keep the bench's dtypes
        assert rows[name].dtype == mine[name].dtype, name
    assert events["event"].dtype == "int64" and events["abs_dt"].dtype == "float64"
    assert set(runs_table["run_id"]) == set(rows["run_id"]) == set(events["run_id"])
    assert {"machine", "environment", "commit", "suite", "added", "n_rows", "n_graded", "marks"} <= set(runs_table)
    assert (runs_table["suite"] == "tiny").all()


def test_a_notebooks_own_run_goes_beside_the_archived_ones_in_two_lines(archive, runs):
    # what docs/how-to/archive.md shows: the archive's rows and one's own results in one frame
    rows = nsbench.archive.load(archive).rows
    both = pd.concat([rows, storage.load_results(runs["a"]).assign(run_id="mine")], ignore_index=True)
    assert len(both) == len(rows) + 4 and (both["run_id"] == "mine").sum() == 4


def test_an_empty_archive_loads_as_empty_tables(tmp_path):
    layout.create(tmp_path / "empty")
    tables = nsbench.archive.load(tmp_path / "empty")
    assert tables.rows.empty and tables.events.empty and tables.runs.empty
    assert "switch_err_max" in tables.rows and list(tables.events.columns) == list(layout.EVENT_COLUMNS)
    assert nsbench.archive.leaderboard(tables).empty


def test_without_events_the_event_tables_are_checked_not_read(archive, tmp_path):
    tables = nsbench.archive.load(archive, events=False)
    assert tables.events.empty and len(tables.rows) == 11
    path = copy(archive, tmp_path / "arch")
    events = sorted((path / layout.RUNS).iterdir())[0] / layout.EVENTS
    events.write_bytes(events.read_bytes()[:-1] + b"\x00")
    with pytest.raises(ConfigError, match="events.parquet is damaged"):
        nsbench.archive.load(path, events=False)


def test_the_rows_are_converted_column_by_column_into_the_frame_to_frame_makes_of_their_records(archive):
    # load converts the stored rows column by column (storage.frame_of_table), not by a dict per row:
    # the same frame, value for value and dtype for dtype, also for nulls, a missing column and a text
    # column stored as another type (those take to_frame's own conversion)
    import json

    import pyarrow as pa
    import pyarrow.parquet as pq

    from nsbench.bench.schema import LIST_COLUMNS

    tables = [pq.read_table(f) for f in sorted((archive / layout.RUNS).glob(f"*/{layout.ROWS}"))]
    whole = pa.concat_tables([t.replace_schema_metadata(None) for t in tables])
    odd = whole.slice(0, 4)
    odd = odd.set_column(
        odd.column_names.index("event_t"),
        "event_t",
        pa.array([[1.0, None], None, [], [float("nan"), 2.5]], pa.list_(pa.float64())),
    )
    odd = odd.set_column(odd.column_names.index("integrator"), "integrator", pa.array([1, None, 3, 4]))
    odd = odd.set_column(odd.column_names.index("switch_err_max"), "switch_err_max", pa.nulls(4, pa.float64()))
    odd = odd.drop_columns(["dense_states"])
    for table in (whole, odd):
        mine, theirs = storage.frame_of_table(table), storage.to_frame(table.to_pandas().to_dict("records"))
        assert list(mine.columns) == list(theirs.columns)
        assert (mine.dtypes == theirs.dtypes).all()
        for name in LIST_COLUMNS:  # lists of Python floats, NaN where Arrow holds a null
            assert json.dumps(mine[name].tolist()) == json.dumps(theirs[name].tolist()), name
            assert all(type(x) is float for cell in mine[name] for x in cell), name
        pd.testing.assert_frame_equal(mine.drop(columns=list(LIST_COLUMNS)), theirs.drop(columns=list(LIST_COLUMNS)))
    assert mine["event_t"].iloc[1] == [] and mine["event_t"].iloc[0][0] == 1.0  # a null cell: no values


def test_without_the_bulky_columns_the_rows_are_the_same_less_them_and_still_checked(archive, tmp_path):
    import hashlib
    import json

    import pyarrow as pa
    import pyarrow.parquet as pq

    from nsbench.archive.load import BULKY

    full, lean = nsbench.archive.load(archive), nsbench.archive.load(archive, events=False, bulky=False)
    assert not set(BULKY) & set(lean.rows.columns) and set(BULKY) <= set(full.rows.columns)
    pd.testing.assert_frame_equal(lean.rows, full.rows.drop(columns=list(BULKY)))
    # a dense state changed, the manifest brought up to date: the values' checksum still covers the column
    path = copy(archive, tmp_path / "arch")
    folder = sorted((path / layout.RUNS).iterdir())[0]
    table = pq.read_table(folder / layout.ROWS)
    cells = table.column("dense_states").to_pylist()
    cells[0] = cells[0] + " "
    i = table.column_names.index("dense_states")
    pq.write_table(table.set_column(i, "dense_states", pa.array(cells, pa.large_string())), folder / layout.ROWS)
    manifest = json.loads((folder / layout.MANIFEST).read_text())
    manifest["sha256"][layout.ROWS] = hashlib.sha256((folder / layout.ROWS).read_bytes()).hexdigest()
    (folder / layout.MANIFEST).write_text(json.dumps(manifest))
    with pytest.raises(ConfigError, match="rows.parquet is damaged .*do not match the checksum"):
        nsbench.archive.load(path, events=False, bulky=False)
