"""``nsbench.archive.load(PATH)``: an archive as pandas tables, every file checked on read."""

from __future__ import annotations

import json
from dataclasses import asdict
from pathlib import Path
from typing import NamedTuple

import pandas as pd
import pyarrow as pa

from nsbench.archive import layout
from nsbench.bench import storage
from nsbench.bench.schema import COLUMN_NAMES


class _Three(NamedTuple):
    rows: pd.DataFrame
    events: pd.DataFrame
    runs: pd.DataFrame


class Tables(_Three):
    """An archive's tables: ``rows`` (the tidy rows of every run, re-graded, with ``run_id``,
    ``graded``, ``mark`` and ``states_graded``), ``events`` (one row per graded event) and ``runs`` (one per run:
    machine, environment, commit, suite, added, source, counts, marks); and, as an attribute
    outside the tuple (so that ``rows, events, runs = load(path)`` keeps working),
    ``bifurcations``: the bifurcation-target rows of every run that has some, as submitted (the
    bench's columns, :data:`nsbench.bench.targets.COLUMNS`, then ``run_id``)."""

    bifurcations: pd.DataFrame

    def __new__(
        cls,
        rows: pd.DataFrame,
        events: pd.DataFrame,
        runs: pd.DataFrame,
        bifurcations: pd.DataFrame | None = None,
    ) -> "Tables":
        self = super().__new__(cls, rows, events, runs)
        self.bifurcations = bifurcation_frame([]) if bifurcations is None else bifurcations
        return self


def bifurcation_frame(tables: list[pa.Table]) -> pd.DataFrame:
    """Stored bifurcation-target tables as one, in the bench's dtypes, ``run_id`` last: the frame
    :func:`nsbench.bench.targets.to_frame` makes of their rows, made column by column (each column's
    kind, float, integer or text, taken from that function's own empty frame)."""
    from nsbench.bench import targets

    if not tables:
        frame = targets.to_frame([])
        frame["run_id"] = pd.array([], dtype="string")
        return frame
    stored = _concat(tables).to_pandas()
    kinds = targets.to_frame([{}]).dtypes  # one row of nothing: each column in its dtype
    frame = pd.DataFrame(index=stored.index)
    for name in targets.COLUMN_NAMES:
        cells = stored[name] if name in stored else pd.Series(None, index=stored.index, dtype=object)
        if kinds[name] == "float64":
            frame[name] = pd.to_numeric(cells, errors="coerce").astype("float64")
        elif kinds[name] == "Int64":
            frame[name] = pd.to_numeric(cells, errors="coerce").astype("Int64")
        else:  # as targets.to_frame writes a text cell: '' for a missing one
            text = ["" if v is None or (isinstance(v, float) and v != v) else str(v) for v in cells.tolist()]
            frame[name] = pd.Series(text, index=stored.index)  # the dtype pandas infers, as for the rows' dicts
    ids = stored["run_id"].tolist() if "run_id" in stored else [""] * len(stored)
    frame["run_id"] = pd.array([str(v) for v in ids], dtype="string")
    return frame


def _concat(tables: list[pa.Table]) -> pa.Table:
    """Tables of one kind (from runs added by different nsbench versions: a newer column missing in an
    older one's table reads as nulls) as one; of their metadata only the first's pandas dtypes are kept
    (what ``to_pandas`` restores, as it did table by table), not their provenance and checksums."""
    pandas_meta = {k: v for k, v in (tables[0].schema.metadata or {}).items() if k == b"pandas"}
    tables = [t.replace_schema_metadata(None) for t in tables]
    return pa.concat_tables(tables, promote_options="permissive").replace_schema_metadata(pandas_meta or None)


def _events(tables: list[pa.Table]) -> pd.DataFrame:
    """Stored event tables as one, their text columns in the ``string`` dtype ``archive add`` writes them in
    (whatever pandas dtype the first table's metadata names)."""
    frame = _concat(tables).to_pandas()
    return frame.astype({name: "string" for name in ("run_id", "case_id", "kind") if name in frame})


def _rows(tables: list[pa.Table], skip: tuple[str, ...] = ()) -> pd.DataFrame:
    """Stored rows tables as one, in the bench's dtypes, with the archive's columns after them (those
    named in ``skip`` left out)."""
    if tables:
        whole = _concat(tables)
        frame = storage.frame_of_table(whole.drop_columns([c for c in skip if c in whole.column_names]))
        table = whole.select([c for c in layout.ARCHIVE_COLUMNS if c in whole.column_names]).to_pandas()
    else:
        table = pd.DataFrame(columns=[*COLUMN_NAMES, *layout.ARCHIVE_COLUMNS])
        frame = storage.to_frame(table.to_dict("records"))
    frame = frame.drop(columns=list(skip))  # frame_of_table gave them as empty text
    frame["run_id"] = table["run_id"].astype("string").to_numpy()
    frame["graded"] = table["graded"].astype("boolean").to_numpy()
    frame["mark"] = table["mark"].astype("string").to_numpy()
    # an archive written before the state errors were re-graded has no such column: none of them was
    states = table["states_graded"] if "states_graded" in table else pd.Series(False, index=table.index)
    frame["states_graded"] = pd.array(states.astype("boolean").fillna(False).to_numpy(dtype=bool), dtype="boolean")
    return frame


def run_frame(found: list[layout.Run]) -> pd.DataFrame:
    """The runs' manifests as one table (checksums left out; marks joined by ' | ')."""
    records = []
    for run in found:
        record = asdict(run)
        del record["sha256"]
        record["marks"] = " | ".join(run.marks)
        record["versions"] = json.dumps(run.versions, sort_keys=True)
        records.append(record)
    columns = [f for f in layout.Run.__dataclass_fields__ if f != "sha256"]
    return pd.DataFrame(records, columns=columns)


#: The rows' columns of bulk (the dense states and event log of each case: most of a rows table's bytes)
#: that the leaderboard and the site do not read: ``load(..., bulky=False)`` leaves them out of ``rows``.
BULKY = ("dense_states", "event_log")


def load(path: str | Path, events: bool = True, bulky: bool = True) -> Tables:
    """The archive at ``path`` as :class:`Tables`.

    Every run's files are checked against the SHA-256 its manifest records and each table read
    against the checksum of its values: a damaged file is a ``ConfigError`` naming it, never read as
    data. With ``events=False`` the event tables are checked by their SHA-256 alone and not read
    (``events`` is then empty): the leaderboard needs only the rows, and the events are most of a
    large archive's values. With ``bulky=False`` the rows' columns :data:`BULKY` are checked (as part of
    their table's checksums) but left out of ``rows``: ``show`` and ``site`` do not read them, and
    every selection of rows would carry their hundreds of megabytes along. The bifurcation-target rows
    (``Tables.bifurcations``) are always read.
    """
    archive = Path(path)
    found = layout.runs(archive)
    rows, tables, bifurcations = [], [], []
    for run in found:
        checked = layout.verify(archive, run)  # the bytes whose SHA-256 matched: parsed, not read again
        folder = layout.run_folder(archive, run.run_id)
        rows.append(layout.read_arrow(folder / layout.ROWS, checked[layout.ROWS]))
        if events:
            tables.append(layout.read_arrow(folder / layout.EVENTS, checked[layout.EVENTS]))
        if layout.BIFURCATIONS in run.sha256:
            bifurcations.append(layout.read_arrow(folder / layout.BIFURCATIONS, checked[layout.BIFURCATIONS]))
    # one conversion to the bench's dtypes for all runs, column by column: per run it cost 40 ms, and a
    # Python dict per row most of a large load
    all_events = _events(tables) if tables else pd.DataFrame(columns=list(layout.EVENT_COLUMNS))
    table = _rows(rows, skip=() if bulky else BULKY)
    return Tables(table, all_events, run_frame(found), bifurcation_frame(bifurcations))
