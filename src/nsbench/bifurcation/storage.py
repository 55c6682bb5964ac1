"""Incremental, resumable storage of a sweep: a folder of atomically written chunk files.

``meta.json`` holds the sweep specification and the provenance of the first
run; ``points/`` holds one Parquet file per finished chunk of parameter values,
written to a temporary name and renamed, so a killed run leaves only whole
chunks. Parquet keeps each column's type and writes a thousand values in
milliseconds (a CSV formatted every float as text, seconds per sweep); chunks
of stores written as CSV before are still read.
Rerunning with the same specification computes only the missing values; a
different specification in the same folder is refused.

A chunk's name says what it holds and proves it:
``chunk-<first index>-<last index>-n<rows>-<sha256 prefix>-s<sweep key>.parquet``.
Every chunk is checked when the store is read: its checksum (the file's bytes),
row count, columns and their types, index range, and for every value its
``n_points`` rows numbered ``k = 0, 1, ...`` (checked for all values at once,
with array operations). A damaged chunk (truncated, edited, another sweep's) is
named in one line; a rerun (:meth:`SweepStore.discard_damaged`) deletes it and
computes its values again, a reader (:meth:`SweepStore.load`) refuses it.
Chunks of stores written before checksums were kept pass the other checks.
"""

from __future__ import annotations

import hashlib
import io
import json
import os
import re
from pathlib import Path
from typing import Any, TextIO

import numpy as np
import pandas as pd

from nsbench.bifurcation.sweep import Columns, SweepSpec, column_kinds, counter_columns
from nsbench.errors import ConfigError
from nsbench.files import STALE_AFTER, refuse_links, remove_stale_temporaries, write_atomic


class SweepStore:
    """The results folder of one sweep.

    Parameters
    ----------
    directory
        Folder (created if needed).
    spec
        The sweep; if the folder already holds another sweep, ``ConfigError``.
        ``None`` opens an existing folder read-only (its spec from ``meta.json``).
    """

    def __init__(self, directory: str | os.PathLike, spec: SweepSpec | None = None) -> None:
        self.directory = Path(directory)
        self.points_dir = self.directory / "points"
        # chunk -> (size and time stamp, its rows or None, why not): a Parquet chunk's rows are kept as
        # the Arrow table read, converted to pandas once for the whole store (a conversion per chunk
        # cost a third of reading a 1000-value sweep back)
        self._checked: dict[Path, tuple[tuple[int, int], Any, str]] = {}
        refuse_links(self.directory, ("meta.json", "points", "*.tmp"), ("points",))
        meta_path = self.directory / "meta.json"
        meta = None
        if meta_path.exists() or meta_path.is_symlink():
            try:
                meta = _read_meta(meta_path)
            except _Damaged as exc:
                if spec is None:
                    raise ConfigError(
                        f"{meta_path} is damaged ({exc}); rerun the sweep into {self.directory} to rebuild it"
                    ) from None
                import sys

                print(
                    f"nsbench: warning: {meta_path} is damaged ({exc}); it is written again for this sweep, "
                    "and only stored values that prove to be of this sweep are kept",
                    file=sys.stderr,
                )
        if meta is not None:
            stored = SweepSpec.from_dict(meta["spec"])
            self._columns: tuple[str, ...] | None = tuple(meta.get("columns", ())) or None
            if spec is not None and _canonical(stored) != _canonical(spec):
                raise ConfigError(
                    f"{self.directory} holds a different sweep ({_describe(stored)}); "
                    f"use another --out for {_describe(spec)}"
                )
            self.spec = stored
            self.meta = meta
        else:
            if spec is None:
                raise ConfigError(f"{self.directory} holds no sweep (no meta.json)")
            from nsbench.provenance import provenance

            self.spec = spec
            self._columns = spec.columns
            self.meta = {
                "spec": spec.to_dict(),
                "spec_key": spec_key(spec),
                "columns": list(self._columns),
                "provenance": provenance(),
            }
            self.points_dir.mkdir(parents=True, exist_ok=True)
            write_atomic(meta_path, json.dumps(self.meta, indent=2, default=str))
        self.points_dir.mkdir(parents=True, exist_ok=True)
        self.spec_key = spec_key(self.spec)
        # a store written before chunks named their sweep trusts chunks without that name; a store
        # whose meta.json records its key (every new one) does not: they may be another sweep's
        self._keyed = "spec_key" in self.meta

    @property
    def columns(self) -> tuple[str, ...]:
        """The tidy columns of this sweep (the problem's state names and per-block counters)."""
        if self._columns is None:  # a store written before the columns were kept in meta.json
            self._columns = self.spec.columns
        return self._columns

    @property
    def state_names(self) -> tuple[str, ...]:
        """``x1, v1, ..., xn, vn`` of the swept problem."""
        cols = self.columns
        return tuple(cols[cols.index("t") + 1 : cols.index("event_block")])

    def write(self, frame: "pd.DataFrame | Columns") -> Path:
        """Store the rows of some finished parameter values (one chunk file, named by what it holds).

        ``frame``: a table, or columns as a sweep's workers send them
        (:func:`~nsbench.bifurcation.sweep.join_columns`), written without a pandas table.
        """
        table = _arrow_table(frame, self.columns)
        data = _parquet_bytes(table)
        index = np.asarray(frame["index"])
        first, last, rows = int(index.min()), int(index.max()), len(index)
        name = f"chunk-{first:06d}-{last:06d}-n{rows}-{_digest(data)}-s{self.spec_key}.parquet"
        path = write_atomic(self.points_dir / name, data)
        # The rows as written, checked as a read would check them but for the file's bytes (those are
        # ``data``, which its name's checksum was taken of): the final table of a run is then not read
        # back from its own chunks (a fifth of a second of a 1000-value sweep). A chunk replaced
        # since (another size or time stamp) is read again.
        try:
            stat = path.stat()
            seen = ((stat.st_size, stat.st_mtime_ns), self._rows_checked(path, table), "")
        except (OSError, _Damaged):  # read it as any other chunk when asked
            return path
        self._checked[path] = seen
        return path

    def _files(self) -> list[Path]:
        return sorted(p for p in self.points_dir.glob("chunk-*") if p.suffix in (".parquet", ".csv"))

    def check(self) -> tuple[list[tuple[Path, pd.DataFrame]], list[tuple[Path, str]]]:
        """Every chunk, read and checked: ``(path, rows)`` of the sound ones, ``(path, reason)`` of the others.

        A run asks several times (damaged chunks, missing values, the final
        table); a chunk is read again only if its size or time stamp changed.
        """
        good, bad = self._check()
        return [(f, _frame(rows)) for f, rows in good], bad

    def _check(self) -> tuple[list[tuple[Path, Any]], list[tuple[Path, str]]]:
        """:meth:`check`, with each sound chunk's rows as read (an Arrow table, or a frame from a CSV)."""
        good, bad = [], []
        for f in self._files():
            try:
                stat = f.stat()
            except FileNotFoundError:  # removed meanwhile (a racing run's rename)
                continue
            signature = (stat.st_size, stat.st_mtime_ns)
            seen = self._checked.get(f)
            if seen is None or seen[0] != signature:
                try:
                    seen = (signature, self._read_checked(f), "")
                except _Damaged as exc:
                    seen = (signature, None, str(exc))
                self._checked[f] = seen
            if seen[1] is not None:
                good.append((f, seen[1]))
            else:
                bad.append((f, seen[2]))
        return good, bad

    def discard_damaged(self, stream: TextIO | None = None, stale_after: float = STALE_AFTER) -> list[Path]:
        """Delete damaged chunks (their values are computed again) and temporary files a killed run left.

        Each damaged chunk is named in one warning line on ``stream``.
        Temporary files younger than ``stale_after`` seconds may belong to a
        run writing into this folder right now and are left alone.
        """
        import sys

        _, bad = self._check()
        for f, reason in bad:
            print(
                f"nsbench: warning: {f} is damaged ({reason}); its values are computed again", file=stream or sys.stderr
            )
            f.unlink(missing_ok=True)
        remove_stale_temporaries([(self.points_dir, "chunk-*.tmp")], stale_after)
        return [f for f, _ in bad]

    def load(self) -> pd.DataFrame:
        """All stored rows, sorted by parameter index and point index (one row per value kept once).

        Raises ``ConfigError`` naming the first damaged chunk, if any (rerun the
        sweep to compute its values again).
        """
        good, bad = self._check()
        if bad:
            f, reason = bad[0]
            more = f" (and {len(bad) - 1} more)" if len(bad) > 1 else ""
            raise ConfigError(
                f"{f} is damaged ({reason}){more}; rerun the sweep into {self.directory} to compute its values again"
            )
        if not good:
            return _typed_empty(self.columns)
        tables = [rows for _, rows in good]
        if all(not isinstance(rows, pd.DataFrame) and rows.schema == tables[0].schema for rows in tables):
            import pyarrow as pa

            frame = pa.concat_tables(tables).to_pandas()  # Parquet chunks of one schema: one conversion
        else:  # chunks written as CSV, or text stored as both Arrow string types
            frame = pd.concat([_frame(rows) for rows in tables], ignore_index=True)
        # a value computed twice (two runs racing on one folder) keeps its first copy
        frame = frame.drop_duplicates(subset=["index", "k"], keep="first")
        return frame.sort_values(["index", "k"], kind="stable").reset_index(drop=True)

    def done(self) -> set[int]:
        """Indices of the parameter values stored in sound chunks."""
        good, _ = self._check()
        return {int(i) for _, rows in good for i in np.unique(np.asarray(rows["index"]))}

    def missing(self) -> list[int]:
        done = self.done()
        return [i for i in range(self.spec.count) if i not in done]

    def _read_checked(self, path: Path) -> Any:
        data = path.read_bytes()
        named = _CHUNK.fullmatch(path.name)
        if named and named["sha"] and _digest(data) != named["sha"]:
            raise _Damaged("its checksum does not match its content")
        key = named["spec"] if named else None
        if key is None and self._keyed:
            raise _Damaged("its name does not say which sweep it belongs to")
        if key is not None and key != self.spec_key:
            raise _Damaged("it holds values of another sweep (other settings)")
        kinds = column_kinds(self.columns)
        frame = _read_parquet(data, kinds) if path.suffix == ".parquet" else _read_csv(data, kinds)
        return self._rows_checked(path, frame)

    def _rows_checked(self, path: Path, frame: Any) -> Any:
        """The rows of chunk ``path`` (an Arrow table, or a frame from a CSV) if they hold what its
        name says, values of this sweep in its grid; else :class:`_Damaged` with the reason."""
        named = _CHUNK.fullmatch(path.name)
        if list(frame.column_names if path.suffix == ".parquet" else frame.columns) != list(self.columns):
            raise _Damaged("its columns are not this sweep's")
        if named and named["rows"] and len(frame) != int(named["rows"]):
            raise _Damaged(f"{len(frame)} rows where its name says {named['rows']}")
        if len(frame) == 0:
            raise _Damaged("no rows")
        idx = np.asarray(frame["index"])
        if idx.min() < 0 or idx.max() >= self.spec.count:
            raise _Damaged(f"indices outside 0..{self.spec.count - 1}")
        if named and named["last"] and (idx.min() != int(named["first"]) or idx.max() != int(named["last"])):
            raise _Damaged("its indices are not those in its name")
        _check_values(frame, self.spec)
        return frame


def _typed_empty(columns: tuple[str, ...]) -> pd.DataFrame:
    """A sweep table without rows, with the column types of one that has some."""
    dtypes = {"text": str, "int": "int64", "float": "float64"}
    return pd.DataFrame({c: pd.Series(dtype=dtypes[k]) for c, k in column_kinds(columns).items()})


class _Damaged(Exception):
    """A chunk file that cannot be used (the message says why)."""


_CHUNK = re.compile(
    r"chunk-(?P<first>\d+)(?:-(?P<last>\d+)-n(?P<rows>\d+)-(?P<sha>[0-9a-f]{16})"
    r"(?:-s(?P<spec>[0-9a-f]{16}))?)?(?:-[0-9a-f]{8})?\.(?:csv|parquet)"
)

#: The Arrow type of each kind of column (strings read back as either string type).
_ARROW_KINDS = {"int": ("int64",), "float": ("double",), "text": ("string", "large_string")}


def _parquet_bytes(table: Any) -> bytes:
    """An Arrow table as one Parquet file (the column types survive it)."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    sink = pa.BufferOutputStream()
    pq.write_table(table, sink)
    return sink.getvalue().to_pybytes()


def _arrow_table(frame: "pd.DataFrame | Columns", columns: tuple[str, ...]) -> Any:
    """The rows (a table, or columns) as an Arrow table, each column of its kind's type."""
    import pyarrow as pa

    kinds = column_kinds(columns)
    arrays = []
    for c, kind in kinds.items():
        values = frame[c]
        if kind == "text":
            texts = [str(v) for v in values] if isinstance(values, list) else values.astype(str)
            arrays.append(pa.array(texts, type=pa.large_string()))
        else:
            arrays.append(pa.array(np.asarray(values, dtype="int64" if kind == "int" else "float64")))
    return pa.Table.from_arrays(arrays, names=list(kinds))


def _frame(rows: Any) -> pd.DataFrame:
    """A chunk's rows as a pandas table (they are kept as read: an Arrow table, or a frame from a CSV)."""
    return rows if isinstance(rows, pd.DataFrame) else rows.to_pandas()


def _read_parquet(data: bytes, kinds: dict[str, str]) -> Any:
    """A Parquet chunk as an Arrow table, its column types checked against the sweep's (no value
    missing but a float's)."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    try:
        # the file reader itself, on this thread: read_table's dataset layer and thread pool cost
        # more than the decoding of a chunk this small
        table = pq.ParquetFile(pa.BufferReader(data)).read(use_threads=False)
    except (pa.ArrowException, OSError, ValueError) as exc:
        raise _Damaged(f"not a readable Parquet table: {' '.join(str(exc).split())}") from None
    if table.column_names != list(kinds):
        raise _Damaged("its columns are not this sweep's")
    for name, column in zip(table.column_names, table.columns):
        kind = kinds[name]
        if str(column.type) not in _ARROW_KINDS[kind]:
            raise _Damaged(f"column {name!r} holds {column.type} values where the sweep stores {kind}")
        if kind != "float" and column.null_count:
            raise _Damaged(f"a value of column {name!r} is missing")
    return table


def _read_csv(data: bytes, kinds: dict[str, str]) -> pd.DataFrame:
    """A chunk of a store written as CSV (before Parquet), with the types the rows were computed with."""
    numeric = [c for c, kind in kinds.items() if kind != "text"]
    try:  # text stays text ('' is an empty message); an empty number is a missing one (NaN)
        frame = pd.read_csv(
            io.BytesIO(data),
            dtype={c: str for c, k in kinds.items() if k == "text"},
            keep_default_na=False,
            na_values={c: [""] for c in numeric},
        )
    except (ValueError, UnicodeDecodeError, pd.errors.ParserError) as exc:
        raise _Damaged(f"not a readable CSV table: {exc}") from None
    if list(frame.columns) != list(kinds):
        raise _Damaged("its columns are not this sweep's")
    for col in numeric:  # the types the rows were computed with: a CSV keeps only text
        try:
            values = pd.to_numeric(frame[col], errors="raise")
        except (ValueError, TypeError):
            raise _Damaged(f"a value of column {col!r} is not a number") from None
        if kinds[col] == "int":
            if values.isna().any() or (values != values.round()).any():
                raise _Damaged(f"a value of column {col!r} is not a whole number")
            values = values.astype("int64")
        frame[col] = values.astype("int64") if kinds[col] == "int" else values.astype("float64")
    return frame


def _check_values(frame: Any, spec: SweepSpec) -> None:
    """Every value's rows: ``n_points`` of them (one if none), numbered ``k = 0, 1, ...`` (``-1`` if none),
    all at the value the grid gives. Checked for all values at once; the first bad value is named.
    ``frame``: a pandas or an Arrow table."""
    idx = np.asarray(frame["index"])
    order = np.argsort(idx, kind="stable")  # a value's rows keep their order
    idx, k = idx[order], np.asarray(frame["k"])[order]
    n_points, value = np.asarray(frame["n_points"])[order], np.asarray(frame["value"], dtype=float)[order]
    starts = np.flatnonzero(np.r_[True, idx[1:] != idx[:-1]])
    counts = np.diff(np.r_[starts, len(idx)])
    n = n_points[starts]
    n_rep = np.repeat(n, counts)
    position = np.arange(len(idx)) - np.repeat(starts, counts)
    row_bad = (n_points != n_rep) | (k != np.where(n_rep > 0, position, -1))
    group_bad = (counts != np.maximum(n, 1)) | np.logical_or.reduceat(row_bad, starts)
    if group_bad.any():
        j = int(np.flatnonzero(group_bad)[0])
        raise _Damaged(f"value {idx[starts[j]]} has {counts[j]} rows where n_points says {n[j]}")
    want = spec.values[idx[starts]]
    first = value[starts]
    value_bad = np.logical_or.reduceat(value != np.repeat(first, counts), starts) | ~(
        np.abs(first - want) <= 1e-12 * np.maximum(1.0, np.abs(want))
    )
    if value_bad.any():
        j = int(np.flatnonzero(value_bad)[0])
        raise _Damaged(f"value {idx[starts[j]]} is not {spec.name} = {want[j]:.17g}")


def spec_key(spec: SweepSpec) -> str:
    """A checksum of everything that defines a sweep's values (aliases of an integrator agree)."""
    return _digest(_canonical(spec).encode())


def _read_meta(path: Path) -> dict:
    """``meta.json``, checked: readable JSON with a valid spec, and its recorded key that spec's."""
    try:
        meta = json.loads(path.read_text())
        stored = SweepSpec.from_dict(meta["spec"])
    except (OSError, ValueError, KeyError, TypeError, AttributeError) as exc:
        reason = f"{type(exc).__name__}: {exc}" if not isinstance(exc, KeyError) else f"no {exc} entry"
        raise _Damaged(" ".join(reason.split())) from None
    if "spec_key" in meta and meta["spec_key"] != spec_key(stored):
        raise _Damaged("its checksum does not match the sweep it describes")
    return meta


def _digest(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()[:16]


def clear_sweep(directory: str | os.PathLike) -> None:
    """Delete the stored sweep in ``directory`` (``--fresh``); refuse a folder that is not a sweep store."""
    d = Path(directory)
    if not d.exists():
        return
    refuse_links(d, ("meta.json", "points"), ("points",))
    meta = d / "meta.json"
    try:
        json.loads(meta.read_text())["spec"]
    except (OSError, ValueError, KeyError, TypeError):
        raise ConfigError(
            f"{str(d)!r} is not an nsbench sweep folder (no readable meta.json); refusing to "
            "clear it: choose another --out"
        ) from None
    points = d / "points"
    foreign = [p.name for p in points.iterdir() if not p.name.startswith("chunk-")] if points.is_dir() else []
    if foreign:
        raise ConfigError(f"{str(points)!r} holds {foreign[0]!r}, which nsbench did not write; refusing to clear it")
    for p in points.iterdir() if points.is_dir() else []:
        p.unlink()
    meta.unlink()


def points_summary(frame: pd.DataFrame) -> pd.DataFrame:
    """One row per parameter value: status, message, points and counters (of every block)."""
    cols = ["index", "value", "status", "message", "n_points", *counter_columns(n_blocks_of(frame)), "wall_time"]
    return frame.groupby("index", sort=True).first().reset_index()[cols]


def n_blocks_of(frame: pd.DataFrame) -> int:
    """Number of blocks whose counters a sweep table holds (its ``sticks1, sticks2, ...`` columns: half
    its state variables, :func:`~nsbench.bifurcation.sweep.sweep_columns`); a table without counters,
    its ``x1, x2, ...`` columns."""
    key = "sticks" if "sticks1" in frame.columns else "x"
    n = 0
    while f"{key}{n + 1}" in frame.columns:
        n += 1
    return n


def state_columns(frame: pd.DataFrame) -> list[str]:
    """The state variables of a sweep table (the problem's state names: ``x1, v1, ...`` of the friction
    problems, ``x, y, px, py`` of Henon-Heiles), between ``t`` and ``event_block``; a table without
    them, its ``x1, v1, x2, ...`` columns."""
    cols = list(frame.columns)
    if "t" in cols and "event_block" in cols and cols.index("t") < cols.index("event_block"):
        return cols[cols.index("t") + 1 : cols.index("event_block")]
    return [c for c in cols if re.fullmatch(r"[xv]\d+", c)]


def positions_of(frame: pd.DataFrame) -> list[str]:
    """The variables a sweep's diagram and point features use as positions: the first of each pair of
    state variables (``x1 .. xn`` of the friction problems, whose states are ``x1, v1, x2, v2, ...``);
    every state variable of a problem whose states do not come in pairs."""
    states = state_columns(frame)
    return states[0::2] if len(states) % 2 == 0 else states


def _canonical(spec: SweepSpec) -> str:
    from nsbench.integrators import canonical_name

    # an alias (exact-jit) names the same integrator: a store that recorded it resumes
    return json.dumps({**spec.to_dict(), "integrator": canonical_name(spec.integrator)}, sort_keys=True, default=str)


def _describe(spec: SweepSpec) -> str:
    return (
        f"{spec.problem} case {spec.case}, {spec.name} = {spec.start:g}:{spec.stop:g}:{spec.count}, "
        f"{spec.integrator}, {spec.section}"
    )
