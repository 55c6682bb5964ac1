"""The archive's layout and schema ``nsbench-results/1``: its folders, manifests and checksums.

An archive is a folder::

    ARCHIVE/archive.json                       {"schema": "nsbench-results/1", "created": ...}
    ARCHIVE/runs/<run id>/rows.parquet         the run's tidy rows, re-graded, plus run_id, graded, mark
    ARCHIVE/runs/<run id>/events.parquet       one row per graded event of the matched prefix
    ARCHIVE/runs/<run id>/provenance.json      the run's provenance, as its results folder recorded it
    ARCHIVE/runs/<run id>/bifurcations.parquet the run's bifurcation-target rows as submitted (only if it has any)
    ARCHIVE/runs/<run id>/run.json             the run's manifest: identity, marks, SHA-256 of its files
    ARCHIVE/references/<key>.json ...          the archive's own certified references (the bench's cache format)

A run's id is a hash of its rows' content (:func:`run_id`), so the same run added twice, or
found in both archives of a merge, has the same folder. The manifest is written last: a run
folder without one was never completely added and is ignored on read. Every read checks each
file against the SHA-256 its manifest records (as the history store does,
:func:`nsbench.bench.history.verify`), and the Parquet files carry the checksum of their values
as every nsbench table does (:func:`nsbench.bench.storage.content_digest`) and the same values'
checksum in binary (:func:`values_digest`), the one a read checks where a table has it.
"""

from __future__ import annotations

import datetime as _dt
import hashlib
import json
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

from nsbench.bench import storage
from nsbench.errors import ConfigError
from nsbench.files import refuse_links, write_atomic

#: The schema this version of nsbench writes and reads.
SCHEMA = "nsbench-results/1"
ARCHIVE_FILE = "archive.json"
RUNS = "runs"
REFERENCES = "references"
MANIFEST = "run.json"
ROWS, EVENTS, PROVENANCE = "rows.parquet", "events.parquet", "provenance.json"
#: The bifurcation-target rows of a run (optional: written only for a run that has some).
BIFURCATIONS = "bifurcations.parquet"
#: The files every run has, whose checksums its manifest records.
CHECKED = (ROWS, EVENTS, PROVENANCE)
#: The optional files of a run, checked when its manifest records them.
OPTIONAL = (BIFURCATIONS,)
#: The columns the archive adds to the bench's tidy rows (:mod:`nsbench.bench.schema`). ``states_graded``
#: came later (an optional column of the schema): a rows table without it is read as all false (its
#: state errors were not re-graded).
ARCHIVE_COLUMNS = ("run_id", "graded", "mark", "states_graded")
#: The bench's column added after archives were first written (left out of an id when empty: :func:`run_id`).
NEWER_COLUMN = "dense_states"
#: The columns of the event table, in order.
EVENT_COLUMNS = ("run_id", "case_id", "event", "kind", "block", "t", "t_ref", "abs_dt", "certified_error")


@dataclass(frozen=True)
class Run:
    """One run in an archive: what its manifest ``run.json`` records."""

    run_id: str
    machine: str
    environment: str
    commit: str
    suite: str
    added: str
    source: str
    n_rows: int
    n_graded: int
    marks: list[str] = field(default_factory=list)
    versions: dict[str, Any] = field(default_factory=dict)
    sha256: dict[str, str] = field(default_factory=dict)
    schema: str = SCHEMA


def digest(path: Path) -> str:
    """SHA-256 of a file's bytes."""
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def run_id(rows: pd.DataFrame) -> str:
    """A run's id: the first 16 hex digits of the checksum of its tidy rows' values (case ids and
    timestamps included), so two additions of one run have one id.

    A run without dense states (made before the bench kept them) is hashed without that column, as
    it was before the column existed: its id is the one an earlier nsbench gave it, so adding it
    again to an archive made then finds it there."""
    frame = storage.to_frame(rows.to_dict("records"))
    if (frame[NEWER_COLUMN].fillna("") == "").all():
        frame = frame.drop(columns=NEWER_COLUMN)
    table = pa.Table.from_pandas(frame, preserve_index=False)
    return storage.content_digest(table)[:16]


def run_folder(archive: Path, rid: str) -> Path:
    return archive / RUNS / storage.file_name(rid, "run id")


def check_target(archive: Path, flag: str = "ARCHIVE") -> None:
    """``ConfigError`` (naming ``flag``) unless ``archive`` is an archive of :data:`SCHEMA` or can be made
    one: a folder that does not exist yet or is empty. Nothing is written."""
    from nsbench.inputs import check_output_dir

    check_output_dir(archive, flag)
    if (archive / ARCHIVE_FILE).exists():
        check_schema(archive)
    elif archive.is_dir() and any(archive.iterdir()):
        raise ConfigError(
            f"{flag} {str(archive)!r} is not empty and holds no {ARCHIVE_FILE}: it is no nsbench archive; "
            "give an archive or a new folder"
        )


def create(archive: Path) -> None:
    """Make ``archive`` an archive (its ``archive.json``) if it is not one yet (:func:`check_target` first)."""
    check_target(archive)
    if (archive / ARCHIVE_FILE).exists():
        return
    try:
        archive.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ConfigError(f"archive {str(archive)!r} cannot be created: {exc.strerror or exc}") from None
    created = _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds")
    write_atomic(archive / ARCHIVE_FILE, json.dumps({"schema": SCHEMA, "created": created}, indent=1))


def check_schema(archive: Path) -> None:
    """``ConfigError`` unless ``archive`` is an archive of :data:`SCHEMA`."""
    path = archive / ARCHIVE_FILE
    if not path.is_file():
        raise ConfigError(
            f"{str(archive)!r} is no nsbench archive (no {ARCHIVE_FILE}; make one with nsbench archive add)"
        )
    try:
        schema = json.loads(path.read_text(encoding="utf-8")).get("schema")
    except (OSError, ValueError, AttributeError) as exc:
        raise ConfigError(f"{path} is damaged ({type(exc).__name__}: {exc})") from None
    if schema != SCHEMA:
        raise ConfigError(f"{path}: schema {schema!r}; this nsbench reads {SCHEMA!r}")


def runs(archive: Path) -> list[Run]:
    """The runs of ``archive`` (those whose manifest was written), by id."""
    check_schema(archive)
    found = []
    for path in sorted((archive / RUNS).glob(f"*/{MANIFEST}")):
        try:
            run = Run(**json.loads(path.read_text(encoding="utf-8")))
        except (OSError, ValueError, TypeError) as exc:
            raise ConfigError(f"{path} is damaged ({type(exc).__name__}: {exc}); delete its folder") from None
        if run.run_id != path.parent.name:
            raise ConfigError(f"{path} names run {run.run_id!r}, not its folder's {path.parent.name!r}")
        found.append(run)
    return found


def files_of(run: Run) -> tuple[str, ...]:
    """The files of ``run``: :data:`CHECKED` and the optional ones its manifest records."""
    return (*CHECKED, *(name for name in OPTIONAL if name in run.sha256))


def verify(archive: Path, run: Run) -> dict[str, bytes]:
    """``ConfigError`` naming the first file of ``run`` that is not the one it was added with; else the
    bytes of its files, by name, as checked (a reader parses these, not the file read again)."""
    folder = run_folder(archive, run.run_id)
    checked = {}
    for name in files_of(run):
        path = folder / name
        try:
            data = path.read_bytes()
        except OSError as exc:
            raise ConfigError(f"{path} cannot be read ({exc.strerror or exc}): the archive is damaged") from None
        checked[name] = data
        if hashlib.sha256(data).hexdigest() != run.sha256.get(name):
            raise ConfigError(
                f"{path} is damaged: its SHA-256 is not the one recorded in {folder / MANIFEST} (edited or "
                "corrupted since it was added); delete the run's folder and add the run again"
            )
    return checked


#: Schema metadata key of the SHA-256 of a table's values in binary (:func:`values_digest`): the checksum
#: nsbench checks on read where a table has it, the JSON one (``nsbench.sha256``) where it has not.
VALUES_KEY = b"nsbench.values-sha256"


def values_digest(table: pa.Table) -> str | None:
    """SHA-256 of every value of ``table`` in binary, column by column in name order (``None`` if a
    column is of a kind it does not cover: text, integers, floats, flags, lists of floats, nulls).

    The same values as :func:`nsbench.bench.storage.content_digest` covers (a float by its 8 bytes
    rather than its repr), without a Python object per value: hashing a large archive's rows by their
    JSON text cost most of reading them. ``docs/reference/archive-schema.md`` gives the rule for
    another tool: each column's name, then its parts (:func:`_parts`), each part prefixed with its
    length as 8 little-endian bytes."""
    h = hashlib.sha256()
    for name in sorted(table.column_names):
        parts = _parts(table.column(name))
        if parts is None:
            return None
        for part in (name.encode(), *parts):
            h.update(len(part).to_bytes(8, "little"))
            h.update(part)
    return h.hexdigest()


def _parts(column: pa.ChunkedArray | pa.Array) -> list[bytes] | None:
    """A column's values as bytes independent of how Arrow holds them (chunks, slices, the bytes under a
    null): its kind letter, one byte per value (1 valid, 0 null), then the values with each null as
    0, '' or [] (integers as int64, floats as float64, flags as one byte, all little-endian; text as
    the int64 UTF-8 lengths then the bytes; a list as its int64 lengths then its flat values' parts)."""
    import numpy as np
    import pyarrow.compute as pc

    kind = column.type
    whole = column.combine_chunks() if isinstance(column, pa.ChunkedArray) else column
    nulls = whole.null_count
    # without nulls (nearly every column) the validity is all ones and nothing needs filling
    valid = (
        b"\x01" * len(whole) if not nulls else pc.is_valid(whole).to_numpy(zero_copy_only=False).astype("u1").tobytes()
    )
    if pa.types.is_null(kind):
        return [b"n", valid]
    if pa.types.is_integer(kind) or pa.types.is_floating(kind) or pa.types.is_boolean(kind):
        letter, target, zero, dtype = (
            (b"i", pa.int64(), 0, "<i8")
            if pa.types.is_integer(kind)
            else (b"f", pa.float64(), 0.0, "<f8")
            if pa.types.is_floating(kind)
            else (b"b", pa.bool_(), False, "u1")
        )
        filled = pc.fill_null(whole.cast(target), zero) if nulls else whole.cast(target)
        return [letter, valid, filled.to_numpy(zero_copy_only=False).astype(dtype, copy=False).tobytes()]
    if pa.types.is_string(kind) or pa.types.is_large_string(kind) or pa.types.is_string_view(kind):
        text = whole if pa.types.is_large_string(kind) else whole.cast(pa.large_string())
        text = pc.fill_null(text, "") if nulls else text
        offsets = np.frombuffer(text.buffers()[1], "<i8")[text.offset : text.offset + len(text) + 1]
        data = text.buffers()[2]
        body = b"" if data is None or not len(text) else memoryview(data)[offsets[0] : offsets[-1]].tobytes()
        return [b"s", valid, np.diff(offsets).astype("<i8").tobytes(), body]
    if (pa.types.is_list(kind) or pa.types.is_large_list(kind)) and pa.types.is_floating(kind.value_type):
        lengths = pc.list_value_length(whole)
        lengths = pc.fill_null(lengths, 0) if nulls else lengths
        inner = _parts(pc.list_flatten(whole))  # a null list emits no values
        return None if inner is None else [b"l", valid, lengths.to_numpy().astype("<i8").tobytes(), *inner]
    return None


def write_table(frame: pd.DataFrame, path: Path, provenance: dict[str, Any]) -> None:
    """``frame`` as Parquet with nsbench's provenance and value checksums in its metadata, atomically:
    the JSON one every nsbench table carries (``nsbench.sha256``, what an older nsbench checks) and the
    binary one (:data:`VALUES_KEY`, what this one checks)."""
    table = pa.Table.from_pandas(frame, preserve_index=False)
    meta = dict(table.schema.metadata or {})
    meta[storage.PROVENANCE_KEY] = json.dumps(provenance, default=str).encode()
    meta[storage.CONTENT_KEY] = storage.content_digest(table).encode()
    binary = values_digest(table)
    if binary is not None:
        meta[VALUES_KEY] = binary.encode()
    tmp = path.with_name(path.name + ".tmp")
    pq.write_table(table.replace_schema_metadata(meta), tmp)
    tmp.replace(path)


def read_arrow(path: Path, source: Any = None) -> pa.Table:
    """A table of a run as Arrow (from ``source``, its bytes already read, if given), its values checked
    against their checksum: the binary one (:data:`VALUES_KEY`) where the table has it, else the JSON
    one (``ConfigError`` naming it if damaged)."""
    try:
        # one file on one thread, unbuffered: half read_table's time for a run's small table (the
        # threads and the dataset layer pay off for large files, not a thousand of a few hundred kB)
        with pq.ParquetFile(path if source is None else pa.BufferReader(source), pre_buffer=False) as file:
            table = file.read(use_threads=False)
    except (OSError, ValueError, pa.ArrowException) as exc:
        raise ConfigError(f"{path} is damaged (not a readable Parquet file: {exc})") from None
    meta = table.schema.metadata or {}
    if VALUES_KEY in meta:
        stored, got = meta[VALUES_KEY].decode(errors="replace"), values_digest(table)
    elif storage.CONTENT_KEY in meta:
        stored, got = meta[storage.CONTENT_KEY].decode(errors="replace"), storage.content_digest(table)
    else:
        return table
    if stored != got:
        raise ConfigError(
            f"{path} is damaged (its values do not match the checksum stored with them (changed since nsbench "
            "wrote it))"
        )
    return table


def read_table(path: Path) -> pd.DataFrame:
    """A table of a run, its values checked against their checksum (``ConfigError`` naming it if damaged)."""
    return read_arrow(path).to_pandas()


def write_run(
    archive: Path,
    run: Run,
    rows: pd.DataFrame,
    events: pd.DataFrame,
    prov: dict[str, Any],
    bifurcations: pd.DataFrame | None = None,
) -> Run:
    """Store one run's files (its bifurcation-target rows only if it has some) and then its manifest
    (the mark of a complete addition); the manifest as written, with the files' checksums."""
    folder = run_folder(archive, run.run_id)
    refuse_links(archive, (RUNS, REFERENCES), (RUNS, REFERENCES))
    folder.mkdir(parents=True, exist_ok=True)
    write_table(rows, folder / ROWS, prov)
    write_table(events, folder / EVENTS, prov)
    write_atomic(folder / PROVENANCE, json.dumps(prov, indent=1, sort_keys=True, default=str))
    names = list(CHECKED)
    if bifurcations is not None and len(bifurcations):
        write_table(bifurcations, folder / BIFURCATIONS, prov)
        names.append(BIFURCATIONS)
    done = Run(**{**asdict(run), "sha256": {name: digest(folder / name) for name in names}})
    write_atomic(folder / MANIFEST, json.dumps(asdict(done), indent=1, sort_keys=True))
    return done
