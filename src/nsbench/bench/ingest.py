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
from nsbench.bench.schema import COLUMN_NAMES
from nsbench.bench.suite import stable_key
from nsbench.errors import ConfigError


def _row(bench: dict[str, Any]) -> dict[str, Any]:
    info = dict(bench.get("extra_info") or {})
    stats = bench.get("stats") or {}
    row = {k: v for k, v in info.items() if k in COLUMN_NAMES}
    row.setdefault("case_id", stable_key({"pytest": bench.get("fullname", bench.get("name"))}))
    row.setdefault("integrator", bench.get("name", ""))
    row.setdefault("problem_label", bench.get("group") or "pytest-benchmark")
    row.setdefault("status", "success")
    row.setdefault("suite", "pytest-benchmark")
    row.setdefault("reference_status", "no accuracy metrics in extra_info")
    data = stats.get("data") or []
    median = float(stats.get("median", math.nan))
    low, high = float(stats.get("min", math.nan)), float(stats.get("max", math.nan))
    rounds = int(stats.get("rounds", len(data)) or 0)
    row.update(wall_time=median, wall_times=[float(t) for t in data], n_repeats=rounds,
               wall_time_min=low, wall_time_max=high,
               wall_spread=(high - low) / median if rounds > 1 and median > 0 else math.nan)
    for key in ("switch_err_max", "switch_err_rms", "switch_err_median", "switch_digits",
                "final_state_err", "state_err_l2", "first_divergence_time"):
        if row.get(key) is None and key in row:
            row[key] = math.nan  # JSON null for a non-finite metric
    return row


def read_benchmark_json(path: str | Path) -> tuple[pd.DataFrame, dict[str, Any]]:
    """Rows and provenance of a pytest-benchmark JSON file."""
    p = Path(path)
    if not p.is_file():
        raise ConfigError(f"benchmark file {str(path)!r} does not exist")
    try:
        data = json.loads(p.read_text())
    except json.JSONDecodeError as exc:
        raise ConfigError(f"{str(path)!r} is not JSON: {exc}") from None
    if not isinstance(data, dict) or "benchmarks" not in data:
        raise ConfigError(f"{str(path)!r} is not a pytest-benchmark file (no 'benchmarks' list)")
    provenance = {"source": f"pytest-benchmark {data.get('version', '?')}: {p.name}",
                  "date": data.get("datetime"), "machine_info": data.get("machine_info"),
                  "commit_info": data.get("commit_info")}
    return storage.to_frame(_row(b) for b in data["benchmarks"]), provenance


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
