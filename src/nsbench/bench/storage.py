"""Result storage: one Parquet file per finished case (append-only), a consolidated
Parquet file and a CSV export, every file carrying its provenance.

Layout of an output directory::

    cases/<case_id>.parquet     one row each, written atomically when the case ends
    references/                 cached reference runs (see nsbench.bench.reference)
    results.parquet             all rows (rewritten by the runner, report and ingest)
    results.csv                 the same, '#' comment lines of provenance first
    provenance.json             the provenance of the latest run into this directory
    timeline.csv                the worker tasks of the latest run (start, reference, warm-up, time)
"""

from __future__ import annotations

import io
import json
import math
import os
import re
from pathlib import Path
from typing import Any, Iterable

import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

from nsbench.bench import columns
from nsbench.bench.schema import COLUMN_NAMES, JSON_COLUMNS, LIST_COLUMNS
from nsbench.bench.tables import natural_key
from nsbench.errors import ConfigError
from nsbench.files import STALE_AFTER, fresh_temporary, refuse_links, remove_stale_temporaries, write_atomic
from nsbench.status import Status

PROVENANCE_KEY = b"nsbench.provenance"
#: What nsbench writes in an output directory (the runner, ingest, the report), and the folders
#: whose every entry it writes: none of them may be a symbolic link (:func:`check_no_links`).
WRITTEN = (
    "cases",
    "references",
    "results.parquet",
    "results.csv",
    "provenance.json",
    "timeline.csv",
    "worker-errors.log",
    "report.md",
    "index.html",
    "table.tex",
    "figures",
    "scaling.csv",
    "scaling_summary.csv",
    "bifurcation_targets",
    "bifurcation_references",
    "bifurcation_targets.parquet",
    "bifurcation_targets.csv",
    "*.tmp",
)
WRITTEN_FOLDERS = ("cases", "references", "figures", "bifurcation_targets", "bifurcation_references")


def check_out(out: Any) -> Path:
    """``out`` as a :class:`~pathlib.Path`, refused (``ConfigError`` naming it) when it is not a path,
    is a file, or holds a ``cases`` entry that is not a folder (a worker's ``FileExistsError`` later)."""
    if isinstance(out, bool) or not isinstance(out, (str, os.PathLike)) or not str(out):
        raise ConfigError(f"out = {out!r} must be the path of a results folder (a str or os.PathLike)"[:300])
    path = Path(out)
    if path.exists() and not path.is_dir():
        raise ConfigError(f"out = {str(path)!r} is a file; give a folder")
    cases = path / "cases"
    if (cases.exists() or cases.is_symlink()) and not cases.is_dir():
        raise ConfigError(
            f"{str(cases)!r} is a file, not the folder of stored cases: {str(path)!r} is not an nsbench "
            "results folder; choose another out"
        )
    return path


def make_out(out: Path) -> None:
    """Create the results folder ``out``; an ``OSError`` (a read-only or virtual file system such as
    ``/proc``) is a ``ConfigError`` naming it."""
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ConfigError(f"out = {str(out)!r}: cannot create the results folder: {exc.strerror or exc}") from None


def check_no_links(out: str | Path) -> None:
    """``ConfigError`` if something nsbench writes or deletes in the output directory ``out`` is a link."""
    refuse_links(out, WRITTEN, WRITTEN_FOLDERS)


# the stored type of each column comes from its declaration (nsbench.bench.columns), never a list of its own
_INT = columns.of_dtype(columns.INT)
_FLOAT = columns.of_dtype(columns.FLOAT)
_BOOL = columns.of_dtype(columns.BOOL)
#: The integer, float and boolean columns of the schema (the others are text or lists).
INT_COLUMNS, FLOAT_COLUMNS, BOOL_COLUMNS = _INT, _FLOAT, _BOOL


def _float_list(value: Any) -> list[float]:
    """A list column's cell as floats; Arrow stores NaN in a list as null, read back as None."""
    if not (isinstance(value, (list, tuple)) or hasattr(value, "tolist")):
        return []
    return [math.nan if x is None else float(x) for x in value]


def to_frame(rows: Iterable[dict[str, Any]]) -> pd.DataFrame:
    """Rows as a frame with the schema's columns and dtypes (extra keys are dropped)."""
    frame = pd.DataFrame(list(rows))
    for name in COLUMN_NAMES:
        if name not in frame:
            frame[name] = None
    return _conform(frame[list(COLUMN_NAMES)].copy())


def _conform(frame: pd.DataFrame, done: Iterable[str] = ()) -> pd.DataFrame:
    """``frame`` (the schema's columns, in order) in the schema's dtypes, its derived columns computed;
    the columns named in ``done`` are already in their dtype and left as they are."""
    ready = set(done)
    for name in _INT:
        frame[name] = pd.to_numeric(frame[name], errors="coerce").astype("Int64")
    for name in _FLOAT:
        frame[name] = pd.to_numeric(frame[name], errors="coerce").astype("float64")
    for name in _BOOL:
        frame[name] = frame[name].astype("boolean")
    for name in LIST_COLUMNS:
        if name not in ready:
            frame[name] = frame[name].apply(_float_list)
    for name in COLUMN_NAMES:
        if name not in _INT + _FLOAT + _BOOL + LIST_COLUMNS and name not in ready:
            frame[name] = frame[name].map(lambda v: "" if v is None else str(v)).astype("string")
    for column in columns.DECLARED:  # derived ones always from the row's own values (an older folder gets them too)
        if column.derive is not None:
            frame[column.name] = column.derive(frame).astype(_PANDAS_DTYPE[column.dtype])
    return frame


def frame_of_table(table: pa.Table) -> pd.DataFrame:
    """The frame :func:`to_frame` makes of a stored table's rows (``table.to_pandas().to_dict("records")``),
    made column by column: a large table (an archive's rows, :mod:`nsbench.archive`) without a Python dict
    per row. A list column of floats becomes one Python list per cell from its flat values (a null
    element NaN, a null cell ``[]``, as :func:`_float_list` reads them); a text column stored as text
    becomes the ``string`` dtype with a null read as '' (to_frame's rule for a missing cell; nsbench writes
    no null text). A column of another stored type, or missing, takes :func:`to_frame`'s own cell-by-cell
    conversion."""
    import numpy as np
    import pyarrow.compute as pc

    present = [name for name in COLUMN_NAMES if name in table.column_names]
    fast_lists = [name for name in LIST_COLUMNS if name in present and _is_float_list(table.schema.field(name).type)]
    fast_text = [
        name
        for name in present
        if name not in _INT + _FLOAT + _BOOL + LIST_COLUMNS
        and (pa.types.is_string(kind := table.schema.field(name).type) or pa.types.is_large_string(kind))
    ]
    plain = [name for name in present if name not in fast_lists and name not in fast_text]
    frame = table.select(plain).to_pandas() if plain else pd.DataFrame(index=pd.RangeIndex(table.num_rows))
    for name in fast_lists:
        cells = table.column(name)
        lengths = pc.fill_null(pc.list_value_length(cells), 0).to_numpy(zero_copy_only=False)
        flat = pc.list_flatten(cells).to_numpy(zero_copy_only=False).astype("float64").tolist()
        ends = np.cumsum(lengths).tolist()
        frame[name] = pd.Series([flat[a:b] for a, b in zip([0, *ends[:-1]], ends)], index=frame.index, dtype=object)
    string = pd.StringDtype()
    for name in fast_text:
        text = pc.fill_null(table.column(name), "")
        frame[name] = pd.Series(text.to_pandas(types_mapper=lambda t: string), index=frame.index)
    for name in COLUMN_NAMES:
        if name not in frame:
            frame[name] = None
    return _conform(frame[list(COLUMN_NAMES)].copy(), done=[*fast_lists, *fast_text])


def _is_float_list(kind: pa.DataType) -> bool:
    return (pa.types.is_list(kind) or pa.types.is_large_list(kind)) and pa.types.is_floating(kind.value_type)


#: The pandas dtype a frame holds each kind of column in (:func:`to_frame`).
_PANDAS_DTYPE = {
    columns.INT: "Int64",
    columns.FLOAT: "float64",
    columns.BOOL: "boolean",
    columns.TEXT: "string",
    columns.JSON: "string",
    columns.LIST: "object",
}


#: Schema metadata key of the SHA-256 of a stored table's values (a bit flipped in a value shows).
CONTENT_KEY = b"nsbench.sha256"


def content_digest(table: pa.Table) -> str:
    """SHA-256 of every value of ``table``, column by column (floats exactly, by their repr)."""
    import hashlib

    values = {name: table.column(name).to_pylist() for name in table.column_names}
    return hashlib.sha256(json.dumps(values, sort_keys=True, default=str).encode()).hexdigest()


def _table(frame: pd.DataFrame, provenance: dict[str, Any]) -> pa.Table:
    table = pa.Table.from_pandas(frame, preserve_index=False)
    meta = dict(table.schema.metadata or {})
    meta[PROVENANCE_KEY] = json.dumps(provenance, default=str).encode()
    meta[CONTENT_KEY] = content_digest(table).encode()
    return table.replace_schema_metadata(meta)


def read_table_checked(path: str | Path) -> pa.Table:
    """A Parquet table nsbench wrote, read and checked against the checksum of its values.

    Raises ``DamagedFile`` if its values changed; pyarrow's own errors if it is unreadable.
    """
    table = pq.read_table(path)
    _check_content(table)
    return table


def _check_content(table: pa.Table) -> None:
    """``DamagedFile`` if ``table`` records a checksum of its values that they no longer match."""
    stored = (table.schema.metadata or {}).get(CONTENT_KEY)
    if stored is not None and stored.decode(errors="replace") != content_digest(table):
        raise DamagedFile("its values do not match the checksum stored with them (changed since nsbench wrote it)")


def _write_atomic(table: pa.Table, path: Path) -> None:
    tmp = fresh_temporary(path)  # a leftover (or a link) is removed: never written through
    pq.write_table(table, tmp)
    os.replace(tmp, path)  # a reader never sees a half-written file; a link at path is replaced, not followed


#: What a case id may be: it names a file, so no path separators and no leading dot.
_CASE_ID = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.+=-]{0,127}")


def case_path(out: str | Path, case_id: Any) -> Path:
    """``OUT/cases/<case_id>.parquet``, refusing an id that could name a file elsewhere.

    Case ids come from data (suites, pytest-benchmark ``extra_info``): one such as
    ``../../x`` or ``/abs/path`` must not write outside the output folder.
    """
    return Path(out) / "cases" / f"{file_name(case_id, 'case id')}.parquet"


def file_name(text: Any, what: str) -> str:
    """``text`` if it can name a file inside a folder (no separators, no '..'), else ``ConfigError``.

    Names that come from data (case ids, plug-in names) pass here before they
    become part of a path, so none can reach outside the output folder.
    """
    text = str(text)
    if not _CASE_ID.fullmatch(text) or ".." in text:
        raise ConfigError(
            f"{what} {text!r} cannot name a file: it must be 1-128 characters of letters, "
            "digits and _ . + = -, start with a letter or digit, and not contain '..'"
        )
    return text


def clear_cases(out: str | Path) -> None:
    """Delete the stored cases of the nsbench store ``out`` (a fresh run into the same folder).

    Refuses, before deleting anything, when ``OUT/cases`` holds anything nsbench
    did not write there (another tool's folder, a mistyped path, someone's own
    Parquet file): only nsbench's case files (:func:`nsbench_wrote`) and their
    ``.tmp`` siblings are deleted.
    """
    cases = Path(out) / "cases"
    check_no_links(out)
    if not cases.exists():
        return
    if not cases.is_dir():
        raise ConfigError(f"{str(cases)!r} is not a folder: {str(out)!r} is not an nsbench results folder")
    foreign = [
        p.name
        for p in sorted(cases.iterdir())
        if not (p.name.endswith(".parquet.tmp") or (p.name.endswith(".parquet") and nsbench_wrote(p)))
    ]
    if foreign:
        raise ConfigError(
            f"{str(out)!r} does not look like an nsbench results folder ({str(cases)!r} holds "
            f"{foreign[0]!r}, which nsbench did not write); refusing to clear it: choose another "
            "--out"
        )
    for p in cases.iterdir():
        p.unlink()
    cases.rmdir()


#: A case id nsbench makes (:func:`nsbench.bench.keys.stable_key`): 16 hexadecimal digits.
_STABLE_KEY = re.compile(r"[0-9a-f]{16}")


def nsbench_wrote(path: str | Path) -> bool:
    """Whether the Parquet file ``path`` is nsbench's: its metadata holds nsbench's provenance, or it
    is unreadable under a name nsbench gives (a case file damaged on disk; nsbench's writes are atomic)."""
    p = Path(path)
    try:
        return PROVENANCE_KEY in (pq.read_schema(p).metadata or {})
    except (OSError, ValueError, pa.ArrowException):
        return bool(_STABLE_KEY.fullmatch(p.name[: -len(".parquet")]))


def append_row(out: str | Path, row: dict[str, Any], provenance: dict[str, Any]) -> Path:
    """Store one finished case as ``cases/<case_id>.parquet``."""
    path = case_path(out, row["case_id"])
    refuse_links(out, ["cases"])  # the worker writes here: never into a folder a link points to
    path.parent.mkdir(parents=True, exist_ok=True)
    _write_atomic(_table(to_frame([row]), provenance), path)
    return path


class DamagedFile(Exception):
    """A stored file that cannot be used (the message says why)."""


#: Columns every case file has (schema check on read).
_REQUIRED = ("case_id", "integrator", "problem_label", "status", "n_repeats")


def read_case(path: str | Path) -> pd.DataFrame:
    """The one row of a case file, checked: readable, nsbench's columns, the id its name says.

    Raises
    ------
    DamagedFile
        A truncated or foreign file, a case file copied over another case's name, or
        values that no longer match the checksum stored with them.
    """
    p = Path(path)
    try:
        table = pq.read_table(p)
        frame = table.to_pandas()
    except (OSError, ValueError, pa.ArrowException) as exc:
        raise DamagedFile(f"not a readable Parquet file: {exc}") from None
    _check_content(table)
    missing = [c for c in _REQUIRED if c not in frame.columns]
    if missing:
        raise DamagedFile(f"not an nsbench case file (no column {missing[0]!r})")
    if len(frame) != 1:
        raise DamagedFile(f"{len(frame)} rows where a case file has one")
    stored = str(frame["case_id"].iloc[0])
    if stored != p.name[: -len(".parquet")]:
        raise DamagedFile(f"it holds case {stored!r}, not the case its name says")
    return frame


def discard_damaged(
    out: str | Path,
    stream: Any = None,
    stale_after: float = STALE_AFTER,
    expect: dict[str, dict[str, Any]] | None = None,
) -> list[Path]:
    """Before a resumed run: delete damaged case files (their cases run again) and stale temporary files.

    Each damaged file is named in one warning line on ``stream``; a damaged
    cached reference is dealt with when it is loaded (it is computed again).
    ``expect`` maps case ids to the columns their row must hold (the
    parameters of the case the run would compute under that id): a stored row
    that holds other parameters is damaged too. Temporary files younger than
    ``stale_after`` seconds may belong to a run writing into this folder right
    now and are left alone.
    """
    import sys

    o = Path(out)
    check_no_links(o)
    bad = []
    cases = o / "cases"
    for f in sorted(cases.glob("*.parquet")) if cases.is_dir() else []:
        try:
            row = read_case(f).iloc[0]
            wanted = (expect or {}).get(f.name[: -len(".parquet")], {})
            differ = [k for k, v in wanted.items() if k not in row.index or _differs(row[k], v)]
            if differ:
                raise DamagedFile(f"it holds another computation than its case id says ({differ[0]} differs)")
        except DamagedFile as exc:
            if not nsbench_wrote(f):  # someone else's file: never deleted, and not read as a result
                raise ConfigError(
                    f"{f} is not an nsbench case file ({exc}) and nsbench did not write it; move "
                    f"it out of {cases} or choose another --out"
                ) from None
            print(f"nsbench: warning: {f} is damaged ({exc}); its case runs again", file=stream or sys.stderr)
            f.unlink(missing_ok=True)
            bad.append(f)
    remove_stale_temporaries(
        (
            (o, "results.*.tmp"),
            (o, "provenance.json.tmp"),
            (o, "timeline.csv.tmp"),
            (cases, "*.parquet.tmp"),
            (o / "references", "*.json.tmp"),
        ),
        stale_after,
    )
    return bad


def _differs(stored: Any, wanted: Any) -> bool:
    if isinstance(wanted, float):
        try:
            return not (float(stored) == wanted or (math.isnan(float(stored)) and math.isnan(wanted)))
        except (TypeError, ValueError):
            return True
    return str(stored) != str(wanted)


def done_ids(out: str | Path) -> set[str]:
    """Ids of the cases already stored in ``out`` (what a resumed run skips)."""
    cases = Path(out) / "cases"
    return {p.name[: -len(".parquet")] for p in cases.glob("*.parquet")} if cases.is_dir() else set()


def short_of_repeats(out: str | Path, repeats: dict[str, int]) -> dict[str, dict[str, Any]]:
    """The stored rows, by id among ``repeats`` (case id -> timed runs wanted), of successes with fewer runs.

    Rows are stored after every timing round, so an interrupted run leaves such
    rows; a resumed run keeps their samples and times only the rounds they lack
    (:class:`nsbench.bench.scheduler.Scheduler`'s ``resumed``). An unreadable file is
    left to the reader of the results to report.
    """
    short: dict[str, dict[str, Any]] = {}
    for case_id, wanted in repeats.items():
        try:
            rows = pq.read_table(case_path(out, case_id)).to_pylist()
        except (OSError, ValueError, KeyError, pa.ArrowException, ConfigError):
            continue
        for row in rows:
            n = row.get("n_repeats")
            if row.get("status") == Status.SUCCESS and n is not None and n < wanted:
                short[case_id] = row
    return short


def read_provenance(path: str | Path, damaged_ok: bool = False) -> dict[str, Any]:
    """The provenance stored in a Parquet file, a CSV export, or an output directory.

    A folder's ``provenance.json`` that is not a JSON table (a truncated write, an edit) is a
    ``ConfigError`` saying how to rebuild it, or, with ``damaged_ok`` (a run's resume, which
    rewrites it from the stored cases), read as empty.
    """
    p = Path(path)
    if p.is_dir():
        prov = p / "provenance.json"
        if not prov.exists():
            return {}
        try:
            value = json.loads(prov.read_text(encoding="utf-8"))
            if not isinstance(value, dict):
                raise ValueError(f"a JSON {type(value).__name__}, not a table")
        except ValueError as exc:  # JSONDecodeError and UnicodeDecodeError are ValueErrors
            if damaged_ok:
                return {}
            raise ConfigError(
                f"{str(prov)!r} is damaged ({str(exc).splitlines()[0][:80]}): resuming the run "
                f"(nsbench bench SUITE --out {str(p)!r}) rewrites it from the stored cases"
            ) from None
        return value
    if p.suffix == ".csv":
        meta, _ = _split_csv(p.read_text())
        return {k: v for k, v in meta.items() if k not in (CSV_ROWS, CSV_SHA256)}
    stored: dict[bytes, bytes] = pq.read_schema(p).metadata or {}
    return json.loads(stored[PROVENANCE_KEY]) if PROVENANCE_KEY in stored else {}


def load_results(path: str | Path) -> pd.DataFrame:
    """Every row stored in an output directory, a results Parquet file, or a CSV export."""
    p = Path(path)
    if p.is_dir():
        files = sorted((p / "cases").glob("*.parquet")) if (p / "cases").is_dir() else []
        if files:
            frame = to_frame(row for f in files for row in _checked(f).to_dict("records"))
            frame = frame.sort_values(["integrator", "level"], kind="stable", ignore_index=True)
            return frame.sort_values(
                "problem_label", key=lambda s: s.map(natural_key), kind="stable", ignore_index=True
            )
        if (p / "results.parquet").exists():
            return load_results(p / "results.parquet")
        raise ConfigError(f"{str(path)!r} holds no results (no cases/*.parquet or results.parquet)")
    if not p.exists():
        raise ConfigError(f"results {str(path)!r} do not exist")
    if p.suffix == ".csv":
        frame = read_csv_checked(p)
        for name in LIST_COLUMNS:
            if name in frame:  # an older export may lack a newer list column
                frame[name] = frame[name].map(lambda s: json.loads(s) if isinstance(s, str) else [])
        return to_frame(frame.to_dict("records"))
    if p.suffix == ".parquet":
        try:
            table = pq.read_table(p)
            _check_content(table)
            frame = table.to_pandas()
        except (OSError, ValueError, pa.ArrowException) as exc:
            raise ConfigError(f"{p} is not a readable Parquet file ({exc})") from None
        except DamagedFile as exc:
            raise ConfigError(f"{p} is damaged ({exc})") from None
        if "case_id" not in frame.columns:
            raise ConfigError(f"{p} holds no nsbench results (no column 'case_id')")
        return to_frame(frame.to_dict("records"))
    raise ConfigError(f"cannot read results from {str(path)!r}: expected a directory, .parquet or .csv")


def _checked(path: Path) -> pd.DataFrame:
    try:
        return read_case(path)
    except DamagedFile as exc:
        raise ConfigError(
            f"{path} is damaged ({exc}); rerun into this folder (without --fresh) to compute its case again"
        ) from None


def write_results(frame: pd.DataFrame, path: Path, provenance: dict[str, Any]) -> None:
    """``frame`` (rows of the tidy schema) as one Parquet file with ``provenance`` in its metadata, atomically."""
    _write_atomic(_table(to_frame(frame.to_dict("records")), provenance), Path(path))


#: Header entries of a CSV export that prove its table (they are not provenance).
CSV_ROWS, CSV_SHA256 = "nsbench_csv_rows", "nsbench_csv_sha256"


def write_csv(frame: pd.DataFrame, path: Path, provenance: dict[str, Any]) -> None:
    """``frame`` as CSV after one ``# key: value`` line per provenance entry, written atomically.

    The last two header lines hold the table's row count and SHA-256, so that a
    reader refuses a truncated or edited copy (:func:`read_csv_checked`).
    """
    import hashlib

    body = frame.to_csv(index=False, float_format="%.17g")
    head = "".join(
        f"# {key}: {json.dumps(value, default=str)}\n"
        for key, value in provenance.items()
        if key not in (CSV_ROWS, CSV_SHA256)
    )
    head += f"# {CSV_ROWS}: {len(frame)}\n# {CSV_SHA256}: {json.dumps(hashlib.sha256(body.encode()).hexdigest())}\n"
    write_atomic(path, head + body)


def _split_csv(text: str) -> tuple[dict[str, Any], str]:
    """The ``# key: value`` header of a CSV export (decoded where it is JSON) and the table after it."""
    meta: dict[str, Any] = {}
    at = 0
    for line in text.splitlines(keepends=True):
        if not line.startswith("# "):
            break
        key, _, value = line[2:].rstrip("\n").partition(": ")
        try:
            meta[key] = json.loads(value)
        except ValueError:
            meta[key] = value
        at += len(line)
    return meta, text[at:]


def read_csv_checked(path: Path) -> pd.DataFrame:
    """A CSV export as written: its checksum and row count hold (``ConfigError`` naming the file if not).

    An export written before checksums were kept is checked for whole rows
    (each with every column), which a truncated copy lacks.
    """
    import csv
    import hashlib

    try:
        text = Path(path).read_text()
    except UnicodeDecodeError:
        raise ConfigError(f"{path} holds no nsbench results (not UTF-8 text)") from None
    meta, body = _split_csv(text)
    damaged = f"{path} is damaged (truncated or edited since nsbench wrote it)"
    if CSV_SHA256 in meta:
        if hashlib.sha256(body.encode()).hexdigest() != meta[CSV_SHA256]:
            raise ConfigError(f"{damaged}: its table does not match the checksum in its header")
    else:  # an older export: at least every row whole
        rows = list(csv.reader(io.StringIO(body)))
        short = [i for i, r in enumerate(rows[1:], start=2) if r and len(r) != len(rows[0])]
        if not rows or short or not body.endswith("\n"):
            where = f" (line {short[0]} of its table)" if short else ""
            raise ConfigError(f"{damaged}: a row does not have every column{where}")
    try:
        frame = pd.read_csv(io.StringIO(body))
    except (ValueError, pd.errors.ParserError) as exc:
        raise ConfigError(f"{damaged}: {exc}") from None
    if CSV_ROWS in meta and len(frame) != meta[CSV_ROWS]:
        raise ConfigError(f"{damaged}: {len(frame)} rows where its header says {meta[CSV_ROWS]}")
    if "case_id" not in frame.columns:
        raise ConfigError(f"{path} holds no nsbench results (no column 'case_id')")
    return frame


def export(out: str | Path, provenance: dict[str, Any] | None = None) -> pd.DataFrame:
    """Write ``results.parquet``, ``results.csv`` and ``provenance.json`` from the stored cases."""
    o = Path(out)
    check_no_links(o)
    frame = load_results(o)
    prov = provenance if provenance is not None else read_provenance(o)
    _write_atomic(_table(frame, prov), o / "results.parquet")
    csv = frame.copy()
    for name in LIST_COLUMNS:
        csv[name] = csv[name].map(json.dumps)
    write_csv(csv, o / "results.csv", prov)
    write_atomic(o / "provenance.json", json.dumps(prov, indent=1, default=str))
    return frame


def write_timeline(out: str | Path, records: Iterable[Any]) -> Path:
    """Write ``timeline.csv``: one line per worker task, seconds from the first task's start.

    ``records`` are :class:`nsbench.bench.scheduler.TaskRecord`; the file shows
    the phases (no warm-up overlaps a timed case) and where a worker was lost.
    """
    frame = pd.DataFrame(
        [vars(r) for r in records], columns=["slot", "pid", "kind", "label", "start", "end", "outcome"]
    )
    if len(frame):
        t0 = frame["start"].min()
        frame["start"], frame["end"] = frame["start"] - t0, frame["end"] - t0
    path = Path(out) / "timeline.csv"
    write_atomic(path, frame.to_csv(index=False, float_format="%.3f"))
    return path


def json_column(frame: pd.DataFrame, name: str) -> pd.Series:
    """Decode a JSON config column (see :data:`nsbench.bench.schema.JSON_COLUMNS`)."""
    if name not in JSON_COLUMNS:
        raise ConfigError(f"{name!r} is not a JSON column; JSON columns: {', '.join(JSON_COLUMNS)}")
    return frame[name].map(lambda s: json.loads(s) if s else None)
