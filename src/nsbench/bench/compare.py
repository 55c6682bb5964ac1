"""``nsbench compare A B``: per case, time, work and error of run B against run A, and what to flag.

**Time.** Each case has its timed samples in both runs. The change is the
Hodges-Lehmann ratio ``B / A`` of the samples with its Moses interval
(:func:`nsbench.bench.stats.ratio_interval`). A slowdown is flagged only when
both hold:

1. *the effect exceeds the factor*: the ratio is above ``factor``;
2. *a test says it is not noise*: the one-sided Mann-Whitney test of "B's
   samples tend to exceed A's" gives ``p <= 1 - confidence`` (default
   confidence 0.99; exact, distribution-free; :func:`nsbench.bench.stats.slower_p`).

Both are checked on the worker's CPU clock (``cpu_times``: the process's CPU
time over the timed runs) where both runs recorded it, else on the wall clock.
On a shared machine the wall clock also counts the time other programs held the
core: measured on the 2-core development machine (AMD EPYC, KVM) with other
developers' jobs keeping the load average at 4-8, one case's wall-clock samples
spread by 93 % (median of (max - min) / median), its CPU-clock samples by 42 %. A
significant change on the wall clock that the CPU clock does not show is
reported as ``load`` (the machine, not the code) and not flagged. The CPU clock
is not immune either (it runs slower when another process shares the core's
hyperthread or the host takes the core: the same run's CPU time rose by up to
1.85x from one run of a suite to the next); dividing each sample by a fixed 5 ms
workload timed just before it was tried and made it worse (the short workload's
own noise: more false flags and more missed slowdowns on the same runs), so the
factor and the test guard against it. A speed-up is the same with the sides
swapped (reported, never flagged). Too few samples to reach the confidence at
all (3 a side cannot: the smallest p is 1/20) give ``unverified``. A slowdown
that does not use the CPU (sleeping, waiting on I/O) does not show on the CPU
clock and is not flagged. Every listed time is warm; in results written before
that, the first run was the cold one and is left out.

**Work and errors** are deterministic, so a change of ``nfev`` (the counted
work) or of the max switching-time error beyond ``factor`` is flagged as it
is (errors above a floor of :data:`ERROR_FLOOR`). A lost success or a broken
event sequence is always flagged.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from nsbench.bench import storage
from nsbench.bench.stats import ratio_interval, slower_p, smallest_p
from nsbench.errors import ConfigError
from nsbench.status import Status

#: Errors below this are treated as equal (round-off of a double-precision reference).
ERROR_FLOOR = 1e-15
#: Default confidence of a flagged time change: the one-sided test at 1 - CONFIDENCE.
CONFIDENCE = 0.99
#: Default smallest ratio that counts as a change.
FACTOR = 1.5


def _samples(times, cold_first: bool = False) -> np.ndarray:
    t = np.asarray(list(times) if times is not None else [], dtype=float)
    t = t[np.isfinite(t) & (t > 0)]
    return t[1:] if cold_first and t.size >= 3 else t


def legacy_layout(row: pd.Series, side: str) -> bool:
    """Whether a row (columns suffixed ``_a``/``_b``) comes from a run that stored its cold run first.

    Runs before timing isolation had no ``wall_time_min`` and listed the cold
    first run in ``wall_times``; now every listed run is warm.
    """
    return pd.isna(row.get(f"wall_time_min_{side}", np.nan))


@dataclass(frozen=True)
class TimeVerdict:
    """The time change of one case: ``B / A`` with its interval, the test, the CPU clock's view, the verdict.

    ``verdict`` is one of ``same`` (the ratio within the factor), ``slower`` /
    ``faster`` (beyond the factor and significant, on the CPU clock where both
    runs recorded it, else on the wall clock), ``noise`` (beyond the factor, not
    significant), ``load`` (beyond the factor and significant on the wall clock,
    not on the CPU clock: the machine, not the work), ``unverified`` (too few
    samples to reach the confidence), ``n/a`` (no samples on a side). ``ratio``,
    ``low``, ``high`` (the interval at the confidence) and ``p`` (the one-sided
    test, NaN within the factor) are the wall clock's; ``cpu_ratio`` the CPU clock's.
    """

    ratio: float
    low: float
    high: float
    p: float
    cpu_ratio: float
    verdict: str


def _direction(a: np.ndarray, b: np.ndarray, factor: float, alpha: float) -> tuple[float, float, str]:
    """``(ratio, p, 'slower' | 'faster' | 'same' | 'noise')`` of ``b`` against ``a`` on one clock."""
    ratio = ratio_interval(a, b).estimate
    if 1.0 / factor <= ratio <= factor:
        return ratio, math.nan, "same"
    p = slower_p(a, b) if ratio > factor else slower_p(b, a)
    return ratio, p, ("slower" if ratio > factor else "faster") if p <= alpha else "noise"


def time_verdict(
    a_times,
    b_times,
    factor: float = FACTOR,
    confidence: float = CONFIDENCE,
    cold_first: tuple[bool, bool] = (False, False),
    a_cpu=(),
    b_cpu=(),
) -> TimeVerdict:
    """The :class:`TimeVerdict` of run B's samples against run A's (seconds per run).

    The verdict is taken on the CPU clock (``a_cpu``, ``b_cpu``) where both
    sides have two or more samples, else on the wall clock (``a_times``,
    ``b_times``). A significant change beyond the factor on the wall clock that
    the CPU clock does not show is ``load``. ``cold_first`` says, per side, that
    the first wall time is a cold run to leave out (results written before every
    timed run was warm).
    """
    a, b = _samples(a_times, cold_first[0]), _samples(b_times, cold_first[1])
    if a.size == 0 or b.size == 0:
        return TimeVerdict(math.nan, math.nan, math.nan, math.nan, math.nan, "n/a")
    alpha = 1.0 - confidence
    est = ratio_interval(a, b, confidence)
    ca, cb = _samples(a_cpu), _samples(b_cpu)
    cpu = ca.size >= 2 and cb.size >= 2
    cpu_ratio = ratio_interval(ca, cb).estimate if cpu else math.nan

    def out(verdict: str, p: float = math.nan) -> TimeVerdict:
        return TimeVerdict(est.estimate, est.low, est.high, p, cpu_ratio, verdict)

    # the one-sided p-value in the direction of the wall-clock ratio, for every case: within the factor too
    # (how far the samples are from telling the runs apart), and where too few samples cannot reach the
    # confidence (what they do say); it is the test of the verdict where the ratio is beyond the factor
    p = slower_p(a, b) if est.estimate >= 1.0 else slower_p(b, a)
    # the wall clock's own reading, then the CPU clock's where it was recorded
    if 1.0 / factor <= est.estimate <= factor:
        wall = "same"
    elif smallest_p(a.size, b.size) > alpha:
        wall = "unverified"
    else:
        _, _, wall = _direction(a, b, factor, alpha)
    if not cpu:
        return out(wall, p)
    if smallest_p(ca.size, cb.size) > alpha and not 1.0 / factor <= cpu_ratio <= factor:
        return out("unverified", p)
    _, _, verdict = _direction(ca, cb, factor, alpha)
    if verdict in ("same", "noise") and wall in ("slower", "faster"):
        return out("load", p)
    return out(verdict, p)


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


def work_verdict(nfev_a, nfev_b, factor: float) -> tuple[float, str]:
    """``(ratio B/A of nfev, verdict)``; verdict in ``same, more, less, n/a`` (counted work is deterministic)."""
    try:
        a, b = float(nfev_a), float(nfev_b)
    except (TypeError, ValueError):
        return math.nan, "n/a"
    if not (a > 0 and b > 0 and math.isfinite(a) and math.isfinite(b)):
        return math.nan, "n/a"
    ratio = b / a
    return ratio, "more" if ratio > factor else ("less" if ratio < 1.0 / factor else "same")


#: Columns of :func:`compare_frames`.
COLUMNS = [
    "problem",
    "integrator",
    "options",
    "level",
    "status_a",
    "status_b",
    "time_a",
    "time_b",
    "time_ratio",
    "time_low",
    "time_high",
    "time_p",
    "cpu_ratio",
    "time_verdict",
    "nfev_a",
    "nfev_b",
    "nfev_ratio",
    "nfev_verdict",
    "err_a",
    "err_b",
    "err_ratio",
    "err_verdict",
    "flagged",
    "flags",
    "case_id",
]


def check_thresholds(factor: float, confidence: float) -> None:
    """Refuse a factor that is not a finite number > 1 or a confidence outside [0.5, 1)."""
    if not (isinstance(factor, (int, float)) and factor > 1.0 and math.isfinite(factor)):
        raise ConfigError(f"factor = {factor!r} must be a finite number > 1")
    if not (isinstance(confidence, (int, float)) and 0.5 <= confidence < 1.0):
        raise ConfigError(f"confidence = {confidence!r} must be a number in [0.5, 1), e.g. 0.99")


def _float(value) -> float:
    return float(value) if value is not None and pd.notna(value) else math.nan


def compare_frames(
    a: pd.DataFrame, b: pd.DataFrame, factor: float = FACTOR, confidence: float = CONFIDENCE
) -> pd.DataFrame:
    """One row per case present in both runs (matched on ``case_id``), with verdicts and ``flagged``.

    Columns: :data:`COLUMNS`. ``time_ratio`` is the Hodges-Lehmann ratio ``B / A``
    of the wall-clock samples, ``[time_low, time_high]`` its interval at
    ``confidence``, ``time_p`` the one-sided test's p-value in the direction of
    the ratio (B slower when it is above 1, faster below; given within the factor
    too), ``cpu_ratio`` the same ratio on the CPU clock, where
    the verdict is taken (:func:`time_verdict`).
    """
    check_thresholds(factor, confidence)
    merged = a.merge(b, on="case_id", suffixes=("_a", "_b"))
    rows = []
    for _, r in merged.iterrows():
        cpu_a = r["cpu_times_a"] if "cpu_times_a" in r else ()
        cpu_b = r["cpu_times_b"] if "cpu_times_b" in r else ()
        t = time_verdict(
            r["wall_times_a"],
            r["wall_times_b"],
            factor,
            confidence,
            (legacy_layout(r, "a"), legacy_layout(r, "b")),
            cpu_a,
            cpu_b,
        )
        e_a, e_b = _float(r["switch_err_max_a"]), _float(r["switch_err_max_b"])
        e_ratio, e_verdict = error_verdict(e_a, e_b, factor)
        n_ratio, n_verdict = work_verdict(r["nfev_a"], r["nfev_b"], factor)
        lost = r["status_a"] == Status.SUCCESS and r["status_b"] != Status.SUCCESS
        broke = bool(r["sequence_ok_a"] is True and r["sequence_ok_b"] is False)
        flags = [
            name
            for name, on in (
                ("slower", t.verdict == "slower"),
                ("more work", n_verdict == "more"),
                ("less accurate", e_verdict == "worse"),
                ("status", lost),
                ("event sequence", broke),
            )
            if on
        ]
        rows.append(
            {
                "problem": r["problem_label_a"],
                "integrator": r["integrator_a"],
                "options": r["options_a"],
                "level": r["level_a"],
                "status_a": r["status_a"],
                "status_b": r["status_b"],
                "time_a": r["wall_time_a"],
                "time_b": r["wall_time_b"],
                "time_ratio": t.ratio,
                "time_low": t.low,
                "time_high": t.high,
                "time_p": t.p,
                "cpu_ratio": t.cpu_ratio,
                "time_verdict": t.verdict,
                "nfev_a": r["nfev_a"],
                "nfev_b": r["nfev_b"],
                "nfev_ratio": n_ratio,
                "nfev_verdict": n_verdict,
                "err_a": e_a,
                "err_b": e_b,
                "err_ratio": e_ratio,
                "err_verdict": e_verdict,
                "flagged": bool(flags),
                "flags": ", ".join(flags),
                "case_id": r["case_id"],
            }
        )
    return pd.DataFrame(rows, columns=COLUMNS)


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
        raise ConfigError(
            f"{str(path)!r} holds no nsbench results (no rows with a case_id): "
            "give the output folder of 'nsbench bench', 'run' or 'ingest'"
        )
    return frame


def compare(
    a: str | Path, b: str | Path, factor: float = FACTOR, confidence: float = CONFIDENCE
) -> tuple[pd.DataFrame, dict[str, int]]:
    """Compare two stored runs (directories, Parquet or CSV files).

    Returns the per-case table (:func:`compare_frames`) and counts: cases in
    both, only in A, only in B, flagged.
    """
    check_thresholds(factor, confidence)
    fa, fb = read_results(a), read_results(b)
    table = compare_frames(fa, fb, factor, confidence)
    ids_a, ids_b = set(fa["case_id"]), set(fb["case_id"])
    counts = {
        "common": len(ids_a & ids_b),
        "only_a": len(ids_a - ids_b),
        "only_b": len(ids_b - ids_a),
        "flagged": int(table["flagged"].sum()),
    }
    return table, counts
