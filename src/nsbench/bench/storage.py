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

import json
import math
import os
import re
from pathlib import Path
from typing import Any, Iterable

import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

from nsbench.bench.schema import COLUMN_NAMES, JSON_COLUMNS, LIST_COLUMNS
from nsbench.bench.tables import natural_key
from nsbench.errors import ConfigError
from nsbench.files import STALE_AFTER, remove_stale_temporaries

PROVENANCE_KEY = b"nsbench.provenance"
_INT = ("case", "level", "nfev", "njev", "nsteps", "n_events", "n_repeats", "loops", "n_ref", "n_prefix",
        "n_matched", "n_missed", "n_extra", "first_divergence_index")
_FLOAT = ("step_value", "t0", "t_end", "t_final", "wall_time", "wall_time_min", "wall_time_max",
          "wall_spread", "integrator_time", "cpu_time", "setup_time", "setup_time_timed", "warmup_time",
          "first_divergence_time",
          "switch_err_max", "switch_err_rms", "switch_err_median", "switch_digits",
          "final_state_err", "state_err_l2", "ref_conditioning", "ref_double_floor", "ref_certainty")
_BOOL = ("sequence_ok", "at_ref_accuracy")


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
    frame = frame[list(COLUMN_NAMES)].copy()
    for name in _INT:
        frame[name] = pd.to_numeric(frame[name], errors="coerce").astype("Int64")
    for name in _FLOAT:
        frame[name] = pd.to_numeric(frame[name], errors="coerce").astype("float64")
    for name in _BOOL:
        frame[name] = frame[name].astype("boolean")
    for name in LIST_COLUMNS:
        frame[name] = frame[name].apply(_float_list)
    for name in COLUMN_NAMES:
        if name not in _INT + _FLOAT + _BOOL + LIST_COLUMNS:
            frame[name] = frame[name].map(lambda v: "" if v is None else str(v)).astype("string")
    return frame


def _table(frame: pd.DataFrame, provenance: dict[str, Any]) -> pa.Table:
    table = pa.Table.from_pandas(frame, preserve_index=False)
    meta = dict(table.schema.metadata or {})
    meta[PROVENANCE_KEY] = json.dumps(provenance, default=str).encode()
    return table.replace_schema_metadata(meta)


def _write_atomic(table: pa.Table, path: Path) -> None:
    tmp = path.with_name(path.name + ".tmp")
    pq.write_table(table, tmp)
    os.replace(tmp, path)  # a reader never sees a half-written file


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
        raise ConfigError(f"{what} {text!r} cannot name a file: it must be 1-128 characters of letters, "
                          "digits and _ . + = -, start with a letter or digit, and not contain '..'")
    return text


def clear_cases(out: str | Path) -> None:
    """Delete the stored cases of the nsbench store ``out`` (a fresh run into the same folder).

    Refuses, before deleting anything, when ``OUT/cases`` holds anything nsbench
    does not write there (another tool's folder, a mistyped path): only
    ``*.parquet`` case files and their ``.tmp`` siblings are deleted.
    """
    cases = Path(out) / "cases"
    if not cases.exists():
        return
    if not cases.is_dir():
        raise ConfigError(f"{str(cases)!r} is not a folder: {str(out)!r} is not an nsbench results folder")
    foreign = [p.name for p in cases.iterdir()
               if not (p.is_file() and (p.name.endswith(".parquet") or p.name.endswith(".parquet.tmp")))]
    if foreign:
        raise ConfigError(f"{str(out)!r} does not look like an nsbench results folder ({str(cases)!r} holds "
                          f"{foreign[0]!r}); refusing to clear it: choose another --out")
    for p in cases.iterdir():
        p.unlink()
    cases.rmdir()


def append_row(out: str | Path, row: dict[str, Any], provenance: dict[str, Any]) -> Path:
    """Store one finished case as ``cases/<case_id>.parquet``."""
    path = case_path(out, row["case_id"])
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
        A truncated or foreign file, or a case file copied over another case's name.
    """
    p = Path(path)
    try:
        frame = pq.read_table(p).to_pandas()
    except (OSError, ValueError, pa.ArrowException) as exc:
        raise DamagedFile(f"not a readable Parquet file: {exc}") from None
    missing = [c for c in _REQUIRED if c not in frame.columns]
    if missing:
        raise DamagedFile(f"not an nsbench case file (no column {missing[0]!r})")
    if len(frame) != 1:
        raise DamagedFile(f"{len(frame)} rows where a case file has one")
    stored = str(frame["case_id"].iloc[0])
    if stored != p.name[: -len(".parquet")]:
        raise DamagedFile(f"it holds case {stored!r}, not the case its name says")
    return frame


def discard_damaged(out: str | Path, stream: Any = None, stale_after: float = STALE_AFTER) -> list[Path]:
    """Before a resumed run: delete damaged case files (their cases run again) and stale temporary files.

    Each damaged file is named in one warning line on ``stream``; a damaged
    cached reference is dealt with when it is loaded (it is computed again).
    Temporary files younger than ``stale_after`` seconds may belong to a run
    writing into this folder right now and are left alone.
    """
    import sys

    o = Path(out)
    bad = []
    cases = o / "cases"
    for f in sorted(cases.glob("*.parquet")) if cases.is_dir() else []:
        try:
            read_case(f)
        except DamagedFile as exc:
            print(f"nsbench: warning: {f} is damaged ({exc}); its case runs again", file=stream or sys.stderr)
            f.unlink(missing_ok=True)
            bad.append(f)
    remove_stale_temporaries((o, cases, o / "references"), stale_after)
    return bad


def done_ids(out: str | Path) -> set[str]:
    """Ids of the cases already stored in ``out`` (what a resumed run skips)."""
    cases = Path(out) / "cases"
    return {p.name[: -len(".parquet")] for p in cases.glob("*.parquet")} if cases.is_dir() else set()


def short_of_repeats(out: str | Path, repeats: dict[str, int]) -> set[str]:
    """Ids among ``repeats`` (case id -> timed runs wanted) stored as successes with fewer runs.

    Rows are stored after every timing round, so an interrupted run leaves such
    rows; a resumed run times those cases again. An unreadable file is left to
    the reader of the results to report.
    """
    short = set()
    for case_id, wanted in repeats.items():
        try:
            table = pq.read_table(case_path(out, case_id), columns=["status", "n_repeats"])
        except (OSError, ValueError, KeyError, pa.ArrowException, ConfigError):
            continue
        for status, n in zip(table.column("status").to_pylist(), table.column("n_repeats").to_pylist()):
            if status == "success" and n is not None and n < wanted:
                short.add(case_id)
    return short


def read_provenance(path: str | Path) -> dict[str, Any]:
    """The provenance stored in a Parquet file, a CSV export, or an output directory."""
    p = Path(path)
    if p.is_dir():
        prov = p / "provenance.json"
        return json.loads(prov.read_text()) if prov.exists() else {}
    if p.suffix == ".csv":
        out = {}
        with open(p) as fh:
            for line in fh:
                if not line.startswith("# "):
                    break
                key, _, value = line[2:].rstrip("\n").partition(": ")
                out[key] = json.loads(value)
        return out
    meta = pq.read_schema(p).metadata or {}
    return json.loads(meta[PROVENANCE_KEY]) if PROVENANCE_KEY in meta else {}


def load_results(path: str | Path) -> pd.DataFrame:
    """Every row stored in an output directory, a results Parquet file, or a CSV export."""
    p = Path(path)
    if p.is_dir():
        files = sorted((p / "cases").glob("*.parquet")) if (p / "cases").is_dir() else []
        if files:
            frame = to_frame(row for f in files for row in _checked(f).to_dict("records"))
            frame = frame.sort_values(["integrator", "level"], kind="stable", ignore_index=True)
            return frame.sort_values("problem_label", key=lambda s: s.map(natural_key), kind="stable",
                                     ignore_index=True)
        if (p / "results.parquet").exists():
            return load_results(p / "results.parquet")
        raise ConfigError(f"{str(path)!r} holds no results (no cases/*.parquet or results.parquet)")
    if not p.exists():
        raise ConfigError(f"results {str(path)!r} do not exist")
    if p.suffix == ".csv":
        frame = pd.read_csv(p, comment="#")
        for name in LIST_COLUMNS:
            if name in frame:  # an older export may lack a newer list column
                frame[name] = frame[name].map(lambda s: json.loads(s) if isinstance(s, str) else [])
        return to_frame(frame.to_dict("records"))
    if p.suffix == ".parquet":
        try:
            frame = pd.read_parquet(p)
        except (OSError, ValueError, pa.ArrowException) as exc:
            raise ConfigError(f"{p} is not a readable Parquet file ({exc})") from None
        if "case_id" not in frame.columns:
            raise ConfigError(f"{p} holds no nsbench results (no column 'case_id')")
        return to_frame(frame.to_dict("records"))
    raise ConfigError(f"cannot read results from {str(path)!r}: expected a directory, .parquet or .csv")


def _checked(path: Path) -> pd.DataFrame:
    try:
        return read_case(path)
    except DamagedFile as exc:
        raise ConfigError(f"{path} is damaged ({exc}); rerun into this folder (without --fresh) to compute "
                          "its case again") from None


def write_results(frame: pd.DataFrame, path: Path, provenance: dict[str, Any]) -> None:
    """``frame`` (rows of the tidy schema) as one Parquet file with ``provenance`` in its metadata, atomically."""
    _write_atomic(_table(to_frame(frame.to_dict("records")), provenance), Path(path))


def write_csv(frame: pd.DataFrame, path: Path, provenance: dict[str, Any]) -> None:
    """``frame`` as CSV after one ``# key: value`` line per provenance entry, written atomically."""
    tmp = path.with_name(path.name + ".tmp")
    with open(tmp, "w") as fh:
        for key, value in provenance.items():
            fh.write(f"# {key}: {json.dumps(value, default=str)}\n")
        frame.to_csv(fh, index=False, float_format="%.17g")
    os.replace(tmp, path)


def export(out: str | Path, provenance: dict[str, Any] | None = None) -> pd.DataFrame:
    """Write ``results.parquet``, ``results.csv`` and ``provenance.json`` from the stored cases."""
    o = Path(out)
    frame = load_results(o)
    prov = provenance if provenance is not None else read_provenance(o)
    _write_atomic(_table(frame, prov), o / "results.parquet")
    csv = frame.copy()
    for name in LIST_COLUMNS:
        csv[name] = csv[name].map(json.dumps)
    write_csv(csv, o / "results.csv", prov)
    (o / "provenance.json").write_text(json.dumps(prov, indent=1, default=str))
    return frame


def write_timeline(out: str | Path, records: Iterable[Any]) -> Path:
    """Write ``timeline.csv``: one line per worker task, seconds from the first task's start.

    ``records`` are :class:`nsbench.bench.scheduler.TaskRecord`; the file shows
    the phases (no warm-up overlaps a timed case) and where a worker was lost.
    """
    frame = pd.DataFrame([vars(r) for r in records],
                         columns=["slot", "pid", "kind", "label", "start", "end", "outcome"])
    if len(frame):
        t0 = frame["start"].min()
        frame["start"], frame["end"] = frame["start"] - t0, frame["end"] - t0
    path = Path(out) / "timeline.csv"
    frame.to_csv(path, index=False, float_format="%.3f")
    return path


def json_column(frame: pd.DataFrame, name: str) -> pd.Series:
    """Decode a JSON config column (see :data:`nsbench.bench.schema.JSON_COLUMNS`)."""
    if name not in JSON_COLUMNS:
        raise ConfigError(f"{name!r} is not a JSON column; JSON columns: {', '.join(JSON_COLUMNS)}")
    return frame[name].map(lambda s: json.loads(s) if s else None)
