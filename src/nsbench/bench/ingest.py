"""``nsbench ingest FILE.json``: a pytest-benchmark JSON file into the tidy schema.

Benchmarks written with :func:`nsbench.bench.pytest_bench.bench_case` carry the
tidy-row columns in ``extra_info``; the timing comes from pytest-benchmark's
statistics (``wall_time`` = median of the rounds, ``wall_time_min``/``max`` and
``wall_spread`` from its min and max; ``wall_times`` = the rounds if the file was
saved with ``--benchmark-save-data``). Other benchmarks become rows
with their timing only. The machine and commit info become the provenance.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import pandas as pd

from nsbench.bench import storage
from nsbench.bench.schema import COLUMN_NAMES, LIST_COLUMNS, RUNNER_STATUSES
from nsbench.bench.keys import stable_key
from nsbench.errors import ConfigError
from nsbench.results import Status


def _got(value: Any) -> str:
    text = repr(value)
    return f"{type(value).__name__} {text if len(text) <= 60 else text[:57] + '...'}"


def _check_benchmark(path: str | Path, i: int, bench: Any) -> None:
    """Refuse an entry of ``benchmarks`` that is not shaped like pytest-benchmark's, naming where."""
    where = f"{str(path)!r}: benchmarks[{i}]"
    if not isinstance(bench, dict):
        raise ConfigError(f"{where} must be a table (a pytest-benchmark entry), got {_got(bench)}")
    for key in ("extra_info", "stats"):
        value = bench.get(key)
        if value is not None and not isinstance(value, dict):
            raise ConfigError(f"{where}.{key} must be a table, got {_got(value)}")
    for key in ("name", "fullname", "group"):
        value = bench.get(key)
        if value is not None and not isinstance(value, str):
            raise ConfigError(f"{where}.{key} must be a string, got {_got(value)}")
    stats = bench.get("stats") or {}
    for key in ("median", "min", "max"):
        value = stats.get(key)
        if value is not None and not (_is_number(value) and math.isfinite(value) and value >= 0):
            raise ConfigError(f"{where}.stats.{key} must be a number of seconds (finite, >= 0), got {_got(value)}")
    rounds = stats.get("rounds")
    if rounds is not None and not (_is_number(rounds) and float(rounds).is_integer() and rounds >= 0):
        raise ConfigError(f"{where}.stats.rounds must be a whole number >= 0, got {_got(rounds)}")
    data = stats.get("data")
    if data is not None and not (
        isinstance(data, list) and all(_is_number(t) and math.isfinite(t) and t >= 0 for t in data)
    ):
        raise ConfigError(f"{where}.stats.data must be a list of times (finite, >= 0 seconds), got {_got(data)}")
    for key, value in (bench.get("extra_info") or {}).items():
        if key in COLUMN_NAMES:
            _check_column(f"{where}.extra_info.{key}", key, value)


#: Columns that count something (never negative).
_COUNTS = ("nfev", "njev", "nsteps", "n_events", "n_repeats", "n_ref", "n_prefix", "n_matched", "n_missed", "n_extra")
#: Columns that are seconds (finite and never negative when given).
_SECONDS = (
    "wall_time",
    "wall_time_min",
    "wall_time_max",
    "integrator_time",
    "setup_time",
    "setup_time_timed",
    "warmup_time",
)
#: How a row may end (the engine's statuses and the runner's).
STATUSES = tuple(s.value for s in Status) + RUNNER_STATUSES


def _is_number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _check_column(where: str, key: str, value: Any) -> None:
    """Refuse an ``extra_info`` value that the results schema would store as something else (or lose)."""
    if value is None:  # JSON null: the value is missing (NaN, an empty text)
        return
    if key in storage.INT_COLUMNS:
        if not (_is_number(value) and math.isfinite(value) and float(value).is_integer()):
            raise ConfigError(f"{where} must be a whole number, got {_got(value)}")
        if key in _COUNTS and value < 0:
            raise ConfigError(f"{where} counts something: it must be >= 0, got {_got(value)}")
    elif key in storage.FLOAT_COLUMNS:
        if not _is_number(value):
            raise ConfigError(f"{where} must be a number, got {_got(value)}")
        if key in _SECONDS and not (math.isfinite(value) and value >= 0):
            raise ConfigError(f"{where} must be a number of seconds (finite, >= 0), got {_got(value)}")
    elif key in storage.BOOL_COLUMNS:
        if not isinstance(value, bool):
            raise ConfigError(f"{where} must be true or false, got {_got(value)}")
    elif key in LIST_COLUMNS:
        if not (isinstance(value, list) and all(v is None or _is_number(v) for v in value)):
            raise ConfigError(f"{where} must be a list of numbers, got {_got(value)}")
    elif not isinstance(value, str):
        raise ConfigError(f"{where} must be a string, got {_got(value)}")
    elif key == "status" and value not in STATUSES:
        raise ConfigError(f"{where} = {value!r} is not a status; one of: {', '.join(STATUSES)}")


def _row(bench: dict[str, Any]) -> dict[str, Any]:
    info = dict(bench.get("extra_info") or {})
    stats = bench.get("stats") or {}
    row = {k: v for k, v in info.items() if k in COLUMN_NAMES}
    row.setdefault("case_id", stable_key({"pytest": bench.get("fullname", bench.get("name"))}))
    row.setdefault("integrator", bench.get("name", ""))
    row.setdefault("problem_label", bench.get("group") or "pytest-benchmark")
    row.setdefault("status", Status.SUCCESS.value)
    row.setdefault("suite", "pytest-benchmark")
    row.setdefault("reference_status", "no accuracy metrics in extra_info")
    data = stats.get("data") or []
    median = float(stats.get("median", math.nan))
    low, high = float(stats.get("min", math.nan)), float(stats.get("max", math.nan))
    rounds = int(stats.get("rounds", len(data)) or 0)
    row.update(
        wall_time=median,
        wall_times=[float(t) for t in data],
        n_repeats=rounds,
        wall_time_min=low,
        wall_time_max=high,
        wall_spread=(high - low) / median if rounds > 1 and median > 0 else math.nan,
    )
    for key in (
        "switch_err_max",
        "switch_err_rms",
        "switch_err_median",
        "switch_digits",
        "final_state_err",
        "state_err_l2",
        "first_divergence_time",
    ):
        if row.get(key) is None and key in row:
            row[key] = math.nan  # JSON null for a non-finite metric
    return row


def read_benchmark_json(path: str | Path) -> tuple[pd.DataFrame, dict[str, Any]]:
    """Rows and provenance of a pytest-benchmark JSON file."""
    p = Path(path)
    if p.is_dir():
        raise ConfigError(f"benchmark file {str(path)!r} is a folder, not a JSON file")
    if not p.is_file():
        raise ConfigError(f"benchmark file {str(path)!r} does not exist")
    try:
        raw = p.read_bytes()
    except OSError as exc:
        raise ConfigError(f"cannot read benchmark file {str(path)!r}: {exc.strerror or exc}") from None
    try:
        data = json.loads(raw.decode("utf-8"))
    except UnicodeDecodeError as exc:
        raise ConfigError(
            f"{str(path)!r} is not UTF-8 text (a binary file?): byte {raw[exc.start]:#04x} at offset {exc.start}"
        ) from None
    except json.JSONDecodeError as exc:
        raise ConfigError(f"{str(path)!r} is not JSON: {exc}") from None
    except RecursionError:
        raise ConfigError(f"{str(path)!r} is nested too deeply to be a pytest-benchmark file") from None
    if not isinstance(data, dict) or "benchmarks" not in data:
        raise ConfigError(f"{str(path)!r} is not a pytest-benchmark file (no 'benchmarks' list)")
    if not isinstance(data["benchmarks"], list):
        raise ConfigError(
            f"{str(path)!r} is not a pytest-benchmark file: 'benchmarks' must be a list, got {_got(data['benchmarks'])}"
        )
    if not data["benchmarks"]:
        raise ConfigError(f"{str(path)!r} holds no benchmarks (an empty 'benchmarks' list)")
    for i, bench in enumerate(data["benchmarks"]):
        _check_benchmark(path, i, bench)
    provenance = {
        "source": f"pytest-benchmark {data.get('version', '?')}: {p.name}",
        "date": data.get("datetime"),
        "machine_info": data.get("machine_info"),
        "commit_info": data.get("commit_info"),
    }
    try:
        frame = storage.to_frame(_row(b) for b in data["benchmarks"])
    except (TypeError, ValueError, OverflowError) as exc:
        raise ConfigError(
            f"{str(path)!r}: an extra_info value does not fit the results schema: {type(exc).__name__}: {exc}"
        ) from None
    return frame, provenance


def ingest(path: str | Path, out: str | Path) -> pd.DataFrame:
    """Store the rows of a pytest-benchmark JSON file in the output directory ``out``.

    ``out`` is replaced by the file's rows (``cases/`` per row, ``results.parquet``,
    ``results.csv``, ``provenance.json``), ready for ``nsbench report``.
    """
    frame, provenance = read_benchmark_json(path)
    for case_id in frame["case_id"]:  # ids from extra_info name files: refuse any before writing
        storage.case_path(out, case_id)
    if not frame["case_id"].is_unique:
        dup = frame.loc[frame["case_id"].duplicated(), "case_id"].iloc[0]
        raise ConfigError(f"{str(path)!r}: case id {dup!r} appears more than once in extra_info")
    o = Path(out)
    storage.clear_cases(o)
    for row in frame.to_dict("records"):
        storage.append_row(o, row, provenance)
    return storage.export(o, provenance)
