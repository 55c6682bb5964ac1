"""The archive's layout: a damaged file is detected on read, and the schema is readable with
pyarrow and the standard library alone (no nsbench import is used for the reading)."""

from __future__ import annotations

import hashlib
import json

import pytest

from nsbench.archive import layout, load, show
from nsbench.errors import ConfigError
from tests.archive.conftest import copy


def _flip(path, at: int = -40) -> None:
    data = bytearray(path.read_bytes())
    data[at] ^= 0x01
    path.write_bytes(bytes(data))


@pytest.mark.parametrize("name", [layout.ROWS, layout.EVENTS, layout.PROVENANCE])
def test_a_flipped_byte_in_any_file_of_a_run_is_detected_on_read(archive, tmp_path, name):
    path = copy(archive, tmp_path / "arch")
    target = sorted((path / layout.RUNS).iterdir())[0] / name
    _flip(target, len(target.read_bytes()) // 2)
    with pytest.raises(ConfigError, match=rf"{target.name} is damaged: its SHA-256 is not the one recorded"):
        load(path)


def test_a_value_changed_with_its_manifest_updated_is_still_caught_by_the_tables_checksum(archive, tmp_path):
    # a file re-written with another value and its manifest's SHA-256 brought up to date: the checksum of
    # the values stored in the Parquet metadata (as in every nsbench table) no longer matches them
    import pyarrow as pa
    import pyarrow.parquet as pq

    path = copy(archive, tmp_path / "arch")
    folder = sorted((path / layout.RUNS).iterdir())[0]
    table = pq.read_table(folder / layout.ROWS)
    column = table.column("switch_err_max").to_pylist()
    column[0] = column[0] / 10
    i = table.column_names.index("switch_err_max")
    pq.write_table(table.set_column(i, "switch_err_max", pa.array(column)), folder / layout.ROWS)
    manifest = json.loads((folder / layout.MANIFEST).read_text())
    manifest["sha256"][layout.ROWS] = hashlib.sha256((folder / layout.ROWS).read_bytes()).hexdigest()
    (folder / layout.MANIFEST).write_text(json.dumps(manifest))
    with pytest.raises(ConfigError, match="rows.parquet is damaged .*do not match the checksum"):
        load(path)


def test_a_table_without_the_binary_checksum_is_checked_by_its_json_one(archive, tmp_path):
    # a table written before the binary checksum (nsbench.values-sha256) existed carries only the JSON one:
    # a value changed there, the manifest brought up to date, is caught by that one
    import pyarrow as pa
    import pyarrow.parquet as pq

    path = copy(archive, tmp_path / "arch")
    folder = sorted((path / layout.RUNS).iterdir())[0]
    table = pq.read_table(folder / layout.ROWS)
    meta = {k: v for k, v in table.schema.metadata.items() if k != layout.VALUES_KEY}
    pq.write_table(table.replace_schema_metadata(meta), folder / layout.ROWS)
    manifest = json.loads((folder / layout.MANIFEST).read_text())
    manifest["sha256"][layout.ROWS] = hashlib.sha256((folder / layout.ROWS).read_bytes()).hexdigest()
    (folder / layout.MANIFEST).write_text(json.dumps(manifest))
    assert len(load(path).rows) == 11  # unchanged: read, its JSON checksum holds
    column = table.column("wall_time").to_pylist()
    column[0] = column[0] * 2
    i = table.column_names.index("wall_time")
    changed = table.set_column(i, "wall_time", pa.array(column)).replace_schema_metadata(meta)
    pq.write_table(changed, folder / layout.ROWS)
    manifest["sha256"][layout.ROWS] = hashlib.sha256((folder / layout.ROWS).read_bytes()).hexdigest()
    (folder / layout.MANIFEST).write_text(json.dumps(manifest))
    with pytest.raises(ConfigError, match="rows.parquet is damaged .*do not match the checksum"):
        load(path)


def _values_sha256(table) -> str:
    """The binary value checksum as docs/reference/archive-schema.md defines it, written apart from
    nsbench's (text by its Python strings, not Arrow's buffers): pyarrow, numpy and hashlib alone."""
    import numpy as np
    import pyarrow as pa
    import pyarrow.compute as pc

    def parts(column) -> list[bytes]:
        kind = column.type
        valid = bytes(int(v) for v in pc.is_valid(column).to_pylist())
        values = column.to_pylist()
        if pa.types.is_integer(kind):
            return [b"i", valid, np.array([v or 0 for v in values], "<i8").tobytes()]
        if pa.types.is_floating(kind):
            return [b"f", valid, np.array([0.0 if v is None else v for v in values], "<f8").tobytes()]
        if pa.types.is_boolean(kind):
            return [b"b", valid, bytes(int(bool(v)) for v in values)]
        if pa.types.is_string(kind) or pa.types.is_large_string(kind):
            text = [(v or "").encode() for v in values]
            return [b"s", valid, np.array([len(t) for t in text], "<i8").tobytes(), b"".join(text)]
        assert pa.types.is_list(kind) or pa.types.is_large_list(kind), kind
        flat = pa.array([x for v in values if v is not None for x in v], kind.value_type)
        return [b"l", valid, np.array([len(v or []) for v in values], "<i8").tobytes(), *parts(flat)]

    h = hashlib.sha256()
    for name in sorted(table.column_names):
        for part in (name.encode(), *parts(table.column(name))):
            h.update(len(part).to_bytes(8, "little") + part)
    return h.hexdigest()


def test_a_damaged_manifest_and_a_foreign_folder_are_refused(archive, tmp_path):
    path = copy(archive, tmp_path / "arch")
    manifest = sorted((path / layout.RUNS).iterdir())[0] / layout.MANIFEST
    manifest.write_text(manifest.read_text()[:-20])
    with pytest.raises(ConfigError, match="run.json is damaged"):
        load(path)
    (tmp_path / "other").mkdir()
    (tmp_path / "other" / "notes.txt").write_text("mine")
    with pytest.raises(ConfigError, match="no nsbench archive"):
        load(tmp_path / "other")
    with pytest.raises(ConfigError, match="is not empty and holds no archive.json"):
        layout.create(tmp_path / "other")
    (path / layout.ARCHIVE_FILE).write_text(json.dumps({"schema": "nsbench-results/99"}))
    with pytest.raises(ConfigError, match="schema 'nsbench-results/99'; this nsbench reads 'nsbench-results/1'"):
        show.leaderboard(load(path))


def test_a_run_folder_without_its_manifest_was_never_added_and_is_ignored(archive, tmp_path):
    path = copy(archive, tmp_path / "arch")
    (sorted((path / layout.RUNS).iterdir())[0] / layout.MANIFEST).unlink()
    assert len(load(path).runs) == 1


def test_an_archive_reads_with_pyarrow_and_the_standard_library_alone(archive):
    """What docs/reference/archive-schema.md tells another tool: no nsbench code is used below."""
    import pyarrow.parquet as pq

    meta = json.loads((archive / "archive.json").read_text())
    assert meta["schema"] == "nsbench-results/1"
    total_rows = total_events = 0
    for manifest in sorted((archive / "runs").glob("*/run.json")):
        run = json.loads(manifest.read_text())
        folder = manifest.parent
        assert run["run_id"] == folder.name
        for name, digest in run["sha256"].items():  # the checksum rule: SHA-256 of each file's bytes
            assert hashlib.sha256((folder / name).read_bytes()).hexdigest() == digest
        rows = pq.read_table(folder / "rows.parquet")
        events = pq.read_table(folder / "events.parquet")
        for table in (rows, events):  # and the SHA-256 of each table's values, in its metadata
            values = {name: table.column(name).to_pylist() for name in table.column_names}
            text = json.dumps(values, sort_keys=True, default=str).encode()
            assert hashlib.sha256(text).hexdigest() == table.schema.metadata[b"nsbench.sha256"].decode()
            # and in binary, the checksum nsbench checks on read
            assert _values_sha256(table) == table.schema.metadata[b"nsbench.values-sha256"].decode()
        assert set(rows.column("run_id").to_pylist()) == {run["run_id"]}
        assert rows.num_rows == run["n_rows"] and sum(rows.column("graded").to_pylist()) == run["n_graded"]
        for column in ("case_id", "problem_label", "integrator", "level", "status", "wall_time", "wall_times"):
            assert column in rows.column_names
        assert events.column_names == [
            "run_id", "case_id", "event", "kind", "block", "t", "t_ref", "abs_dt", "certified_error",
        ]  # fmt: skip
        # a row's switching-time error is its events' largest |dt|, each floored at the reference's
        # certified error there (no error is reported below what the reference can certify)
        by_case: dict[str, float] = {}
        cols = (events.column(n).to_pylist() for n in ("case_id", "abs_dt", "certified_error"))
        for case, dt, cert in zip(*cols):
            floored = max(dt, cert) if cert == cert else dt
            by_case[case] = max(by_case.get(case, 0.0), floored)
        for case, err in zip(rows.column("case_id").to_pylist(), rows.column("switch_err_max").to_pylist()):
            assert by_case[case] == err
        total_rows += rows.num_rows
        total_events += events.num_rows
        json.loads((folder / "provenance.json").read_text())
    assert total_rows == 11 and total_events > 0
