"""How a case is timed, and the statistics of its timed samples: median, range, relative spread.

A case is timed on ``repeats`` *samples* (:data:`DEFAULT_SAMPLES` unless the
suite says otherwise), all after an untimed warm-up. A sample is one run, or,
for a run shorter than the suite's ``min_sample_time``, a loop of ``loops``
runs back to back whose mean is the sample (:func:`loops_for`, the rule of
``timeit``'s autorange): a sample then lasts long enough that one scheduler
hiccup or the clock's granularity is a small part of it. Pure functions of
lists of seconds, so they are tested on constructed samples.
"""

from __future__ import annotations

import math
import statistics
from typing import Iterable

import pandas as pd

from nsbench.bench.labels import options_text
from nsbench.status import Status

#: Fewest timed samples per case: a spread needs three (a suite asking for fewer gets three).
MIN_REPEATS = 3
#: Timed samples per case unless a suite says otherwise: with 5 a side, a difference between two
#: methods can be told at 99 % (the smallest one-sided Mann-Whitney p-value is 1/252) and a median
#: has a distribution-free interval of 94 % (the range of the samples).
DEFAULT_SAMPLES = 5
#: Shortest sample unless a suite says otherwise (seconds of timed run): shorter runs are looped.
#: 50 ms is 50,000 times perf_counter's resolution and a dozen of the Linux scheduler's time
#: slices (so one preemption is a few per cent of a sample), and costs the default suite about
#: 40 s more than single runs on 2 cores (docs/bench.md, "How a case runs").
MIN_SAMPLE_TIME = 0.05
#: Most runs in one sample (a run of 1 us would otherwise loop 20,000 times).
MAX_LOOPS = 10_000
#: Relative spread ``(max - min) / median`` above which a report flags a case's timing, and above which
#: (on the CPU clock) a case gets more samples, up to the suite's ``max_repeats``.
WIDE_SPREAD = 0.25


def loops_for(run_seconds: float, min_sample_time: float) -> int:
    """Runs per sample: the first of 1, 2, 5, 10, 20, 50, ... whose runs last ``min_sample_time``.

    ``run_seconds`` is one warm run's time (the calibration run). A run as long
    as the minimum, a failed or unmeasured one, or a minimum of 0 gives 1; the
    count never exceeds :data:`MAX_LOOPS`.
    """
    if not (run_seconds > 0 and math.isfinite(run_seconds)) or not min_sample_time > 0:
        return 1
    loops, k = 1, 0
    while loops * run_seconds < min_sample_time and loops < MAX_LOOPS:
        loops = int(round(loops * (2, 2.5, 2)[k % 3]))  # 1 -> 2 -> 5 -> 10 -> 20 -> 50 ...
        k += 1
    return min(loops, MAX_LOOPS)


def loops_within(loops: int, call_seconds: float, budget: float) -> int:
    """``loops`` lowered to the largest of 1, 2, 5, 10, ... whose whole calls fit in ``budget`` seconds.

    ``call_seconds`` is the whole call of one run (set-up and result included,
    beyond the engine's clock that :func:`loops_for` counts); an unmeasured call
    or budget leaves ``loops`` as it is, and the result is never below 1.
    """
    if not (call_seconds > 0 and math.isfinite(call_seconds) and budget > 0 and math.isfinite(budget)):
        return loops
    best, step, k = 1, 1, 0
    while step <= loops and step * call_seconds <= budget:
        best = step
        step = int(round(step * (2, 2.5, 2)[k % 3]))
        k += 1
    return best


def needs_more(row: dict, max_repeats: int) -> bool:
    """Whether a successful case, timed on its planned samples, should get one more.

    Yes while it has fewer than ``max_repeats`` samples and the relative spread
    ``(max - min) / median`` of its CPU-clock samples (the clock
    :mod:`nsbench.bench.compare` tests; the wall clock where they are missing)
    exceeds :data:`WIDE_SPREAD`: on a busy machine a noisy case gets the
    samples its comparisons need, on a quiet one the planned count is enough.
    """
    from nsbench.bench.stats import relative_spread

    wall = list(row.get("wall_times") or [])
    if row.get("status") != Status.SUCCESS or len(wall) >= max_repeats:
        return False
    cpu = [c for c in row.get("cpu_times") or [] if c == c]
    return relative_spread(cpu if len(cpu) == len(wall) else wall) > WIDE_SPREAD


def _median(values: list[float]) -> float:
    finite = [v for v in values if math.isfinite(v)]
    return float(statistics.median(finite)) if finite else math.nan


def summarize(
    wall_times: Iterable[float], integrator_times: Iterable[float] = (), cpu_times: Iterable[float] = ()
) -> dict[str, float]:
    """The timing columns of a row from its timed samples (seconds per run of each sample).

    Returns
    -------
    dict
        ``wall_time`` (median), ``wall_time_min``, ``wall_time_max``,
        ``wall_spread`` (``(max - min) / median``, NaN with fewer than two samples),
        ``integrator_time`` and ``cpu_time`` (medians of the finite values given, NaN if none).
    """
    times = [float(t) for t in wall_times]
    inner = _median([float(t) for t in integrator_times])
    cpu = _median([float(t) for t in cpu_times])
    if not times:
        nan = math.nan
        return {
            "wall_time": nan,
            "wall_time_min": nan,
            "wall_time_max": nan,
            "wall_spread": nan,
            "integrator_time": inner,
            "cpu_time": cpu,
        }
    med, low, high = float(statistics.median(times)), min(times), max(times)
    spread = (high - low) / med if len(times) > 1 and med > 0 else math.nan
    return {
        "wall_time": med,
        "wall_time_min": low,
        "wall_time_max": high,
        "wall_spread": spread,
        "integrator_time": inner,
        "cpu_time": cpu,
    }


def spread_label(spread: float) -> str:
    """``'±4%'``: half the min-max range relative to the median, for table cells ('' if unknown)."""
    if spread is None or spread is pd.NA or not math.isfinite(float(spread)):
        return ""
    half = 50.0 * float(spread)
    return f"±{half:.0f}%" if half >= 1 else "±<1%"


def wide_spread(frame: pd.DataFrame, threshold: float = WIDE_SPREAD) -> pd.DataFrame:
    """Successful rows whose relative spread exceeds ``threshold``, widest first."""
    if "wall_spread" not in frame:
        return frame.iloc[0:0]
    mask = (frame["status"] == Status.SUCCESS) & (frame["wall_spread"].astype(float) > threshold)
    return frame[mask].sort_values("wall_spread", ascending=False, kind="stable")


def noise_line(frame: pd.DataFrame, provenance: dict | None = None) -> str:
    """One sentence on how noisy the machine was while the cases were timed.

    The load average (sampled each time a sample was sent to a worker, in
    ``provenance['timing']``; it counts the workers themselves) and the median
    relative spread ``(max - min) / median`` of the successful cases' samples.
    """
    timing = (provenance or {}).get("timing") or {}
    parts = []
    load = timing.get("load")
    if load:
        workers, cores = timing.get("workers"), timing.get("cores")
        text = f"load average {load['median']:.1f} ({load['min']:.1f}-{load['max']:.1f}) while timing"
        if workers and cores:
            other = max(0.0, load["median"] - workers)
            text += f", on {cores} cores with {workers} worker(s) (about {other:.1f} from other programs)"
        parts.append(text)
    ok = frame[(frame["status"] == Status.SUCCESS)] if "status" in frame else frame
    spreads = pd.to_numeric(ok.get("wall_spread", pd.Series(dtype=float)), errors="coerce").dropna()
    if len(spreads):
        wide = int((spreads > WIDE_SPREAD).sum())
        parts.append(
            f"a case's timed samples spread by {100 * spreads.median():.0f} % (median over "
            f"{len(spreads)} cases of (max - min) / median; {wide} spread by more than "
            f"{WIDE_SPREAD:.0%})"
        )
    if not parts:
        return ""
    return "How noisy the machine was: " + "; ".join(parts) + "."


def setup_table(frame: pd.DataFrame) -> pd.DataFrame:
    """Set-up per integrator: its first use (the largest over its cases) and the median of the others.

    The first case of an integrator that a worker warms up pays the compilation
    (numba kernels, heyoka models, SUNDIALS objects) and the others find it done,
    so a case's ``setup_time`` says which case ran first, not what an accuracy
    level costs: the set-up belongs to the integrator. Columns ``integrator,
    first_use, on, later, cases`` (seconds; ``on`` the case that paid it).
    """
    columns = ["integrator", "first_use", "on", "later", "cases"]
    if "setup_time" not in frame:
        return pd.DataFrame(columns=columns)
    known = frame[pd.to_numeric(frame["setup_time"], errors="coerce").notna()]
    rows = []
    for name, group in known.groupby("integrator", sort=True):
        times = group["setup_time"].astype(float)
        top = times.idxmax()
        rest = times.drop(top)
        rows.append(
            {
                "integrator": name,
                "first_use": float(times.max()),
                "on": f"{group.loc[top, 'problem_label']} at {options_text(group.loc[top, 'options']) or 'defaults'}"
                if "options" in group
                else f"{group.loc[top, 'problem_label']} level {group.loc[top, 'level']}",
                "later": float(rest.median()) if len(rest) else math.nan,
                "cases": len(group),
            }
        )
    table = pd.DataFrame(rows, columns=columns)
    return table.sort_values("first_use", ascending=False, kind="stable", ignore_index=True)
