"""``nsbench.archive.load(PATH)``: an archive as pandas tables, every file checked on read."""

from __future__ import annotations

import json
from dataclasses import asdict
from pathlib import Path
from typing import NamedTuple

import pandas as pd

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


def bifurcation_frame(tables: list[pd.DataFrame]) -> pd.DataFrame:
    """Stored bifurcation-target tables as one, in the bench's dtypes, ``run_id`` last."""
    from nsbench.bench import targets

    records = [r for t in tables for r in t.to_dict("records")]
    frame = targets.to_frame(records)
    frame["run_id"] = pd.array([str(r.get("run_id", "")) for r in records], dtype="string")
    return frame


def _rows(table: pd.DataFrame) -> pd.DataFrame:
    """A stored rows table in the bench's dtypes, with the archive's columns after them."""
    frame = storage.to_frame(table.to_dict("records"))
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


def load(path: str | Path, events: bool = True) -> Tables:
    """The archive at ``path`` as :class:`Tables`.

    Every run's files are checked against the SHA-256 its manifest records and each table read
    against the checksum of its values: a damaged file is a ``ConfigError`` naming it, never read as
    data. With ``events=False`` the event tables are checked by their SHA-256 alone and not read
    (``events`` is then empty): the leaderboard needs only the rows, and the events are most of a
    large archive's values. The bifurcation-target rows (``Tables.bifurcations``) are always read.
    """
    archive = Path(path)
    found = layout.runs(archive)
    rows, tables, bifurcations = [], [], []
    for run in found:
        layout.verify(archive, run)
        folder = layout.run_folder(archive, run.run_id)
        rows.append(layout.read_table(folder / layout.ROWS))
        if events:
            tables.append(layout.read_table(folder / layout.EVENTS))
        if layout.BIFURCATIONS in run.sha256:
            bifurcations.append(layout.read_table(folder / layout.BIFURCATIONS))
    # one conversion to the bench's dtypes for all runs: per run it cost 40 ms, most of a large load
    table = (
        pd.concat(rows, ignore_index=True) if rows else pd.DataFrame(columns=[*COLUMN_NAMES, *layout.ARCHIVE_COLUMNS])
    )
    all_events = pd.concat(tables, ignore_index=True) if tables else pd.DataFrame(columns=list(layout.EVENT_COLUMNS))
    return Tables(_rows(table), all_events, run_frame(found), bifurcation_frame(bifurcations))
