"""``nsbench compare A B``: per case, time and error ratios of run B against run A.

A time change is flagged only when the ratio of the medians exceeds ``factor``
*and* the repeats say it is not noise: every timed run of one side is slower
than every timed run of the other (the ranges do not overlap). Every run in
``wall_times`` is warm; in results written before that, the first run was the
cold one and is left out. With a single timed run on either side a change is
reported as ``unverified``, never flagged.
Errors are deterministic, so an error change is flagged when it exceeds
``factor`` (above a floor of :data:`ERROR_FLOOR`). A lost success or a broken
event sequence is always flagged.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd

from nsbench.bench import storage
from nsbench.errors import ConfigError

#: Errors below this are treated as equal (round-off of a double-precision reference).
ERROR_FLOOR = 1e-15


def _samples(times, cold_first: bool = False) -> np.ndarray:
    t = np.asarray(list(times), dtype=float)
    return t[1:] if cold_first and t.size >= 3 else t


def legacy_layout(row: pd.Series, side: str) -> bool:
    """Whether a row (columns suffixed ``_a``/``_b``) comes from a run that stored its cold run first.

    Runs before timing isolation had no ``wall_time_min`` and listed the cold
    first run in ``wall_times``; now every listed run is warm.
    """
    return pd.isna(row.get(f"wall_time_min_{side}", np.nan))


def time_verdict(a_times, b_times, factor: float,
                 cold_first: tuple[bool, bool] = (False, False)) -> tuple[float, str]:
    """``(ratio of medians B/A, verdict)``; verdict in ``same, slower, faster, noise, unverified, n/a``.

    ``cold_first`` says, per side, that the first time is a cold run to leave out
    (results written before every timed run was warm).
    """
    a, b = _samples(a_times, cold_first[0]), _samples(b_times, cold_first[1])
    if a.size == 0 or b.size == 0:
        return math.nan, "n/a"
    ratio = float(np.median(b) / np.median(a))
    if 1.0 / factor <= ratio <= factor:
        return ratio, "same"
    if a.size < 2 or b.size < 2:
        return ratio, "unverified"
    if ratio > factor and b.min() > a.max():
        return ratio, "slower"
    if ratio < 1.0 / factor and b.max() < a.min():
        return ratio, "faster"
    return ratio, "noise"


def error_verdict(err_a: float, err_b: float, factor: float) -> tuple[float, str]:
    """``(ratio B/A of max switching-time errors, verdict)``; verdict in ``same, worse, better, n/a``."""
    if not (math.isfinite(err_a) and math.isfinite(err_b)):
        return math.nan, "n/a"
    ratio = max(err_b, ERROR_FLOOR) / max(err_a, ERROR_FLOOR)
    if ratio > factor:
        return ratio, "worse"
    if ratio < 1.0 / factor:
        return ratio, "better"
    return ratio, "same"


def compare_frames(a: pd.DataFrame, b: pd.DataFrame, factor: float = 1.5) -> pd.DataFrame:
    """One row per case present in both runs (matched on ``case_id``), with verdicts and ``flagged``."""
    if not (factor > 1.0 and math.isfinite(factor)):
        raise ConfigError(f"factor = {factor!r} must be a finite number > 1")
    merged = a.merge(b, on="case_id", suffixes=("_a", "_b"))
    rows = []
    for _, r in merged.iterrows():
        t_ratio, t_verdict = time_verdict(r["wall_times_a"], r["wall_times_b"], factor,
                                          (legacy_layout(r, "a"), legacy_layout(r, "b")))
        e_a = float(r["switch_err_max_a"]) if pd.notna(r["switch_err_max_a"]) else math.nan
        e_b = float(r["switch_err_max_b"]) if pd.notna(r["switch_err_max_b"]) else math.nan
        e_ratio, e_verdict = error_verdict(e_a, e_b, factor)
        lost = r["status_a"] == "success" and r["status_b"] != "success"
        broke = bool(r["sequence_ok_a"] is True and r["sequence_ok_b"] is False)
        flags = [name for name, on in (("slower", t_verdict == "slower"), ("less accurate", e_verdict == "worse"),
                                       ("status", lost), ("event sequence", broke)) if on]
        rows.append({"problem": r["problem_label_a"], "integrator": r["integrator_a"],
                     "options": r["options_a"], "status_a": r["status_a"], "status_b": r["status_b"],
                     "time_a": r["wall_time_a"], "time_b": r["wall_time_b"], "time_ratio": t_ratio,
                     "time_verdict": t_verdict, "err_a": e_a, "err_b": e_b, "err_ratio": e_ratio,
                     "err_verdict": e_verdict, "flagged": bool(flags), "flags": ", ".join(flags),
                     "case_id": r["case_id"]})
    columns = ["problem", "integrator", "options", "status_a", "status_b", "time_a", "time_b", "time_ratio",
               "time_verdict", "err_a", "err_b", "err_ratio", "err_verdict", "flagged", "flags", "case_id"]
    return pd.DataFrame(rows, columns=columns)


def read_results(path: str | Path) -> pd.DataFrame:
    """The rows of an nsbench results folder, Parquet or CSV file; anything else is a ``ConfigError``.

    Parameters
    ----------
    path
        Output folder of ``nsbench bench``/``run``/``ingest``, or its ``results.parquet``/``results.csv``.

    Returns
    -------
    pandas.DataFrame
        The rows, in the tidy schema.

    Raises
    ------
    ConfigError
        Missing, unreadable, binary or malformed file, or a folder or file that
        holds no nsbench results (another tool's, an empty folder).
    """
    try:
        frame = storage.load_results(path)
    except ConfigError:
        raise
    except (OSError, ValueError, KeyError, TypeError) as exc:  # pandas/pyarrow parse errors are ValueErrors
        reason = exc.strerror if isinstance(exc, OSError) and exc.strerror else f"{type(exc).__name__}: {exc}"
        reason = " ".join(str(reason).split())
        raise ConfigError(f"cannot read results from {str(path)!r}: {reason[:200]}") from None
    if len(frame) == 0 or not frame["case_id"].fillna("").astype(str).str.len().gt(0).all():
        raise ConfigError(f"{str(path)!r} holds no nsbench results (no rows with a case_id): "
                          "give the output folder of 'nsbench bench', 'run' or 'ingest'")
    return frame


def compare(a: str | Path, b: str | Path, factor: float = 1.5) -> tuple[pd.DataFrame, dict[str, int]]:
    """Compare two stored runs (directories, Parquet or CSV files).

    Returns the per-case table and counts: cases in both, only in A, only in B, flagged.
    """
    fa, fb = read_results(a), read_results(b)
    table = compare_frames(fa, fb, factor)
    ids_a, ids_b = set(fa["case_id"]), set(fb["case_id"])
    counts = {"common": len(ids_a & ids_b), "only_a": len(ids_a - ids_b), "only_b": len(ids_b - ids_a),
              "flagged": int(table["flagged"].sum())}
    return table, counts
