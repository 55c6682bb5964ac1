"""Statistics of the timed repeats of a case: median, range, relative spread.

Pure functions of lists of seconds, so they are tested on constructed samples.
"""

from __future__ import annotations

import math
import statistics
from typing import Iterable

import pandas as pd

#: Fewest timed runs per case: a spread needs three (a suite asking for fewer gets three).
MIN_REPEATS = 3
#: Relative spread ``(max - min) / median`` above which a report flags a case's timing.
WIDE_SPREAD = 0.25


def _median(values: list[float]) -> float:
    finite = [v for v in values if math.isfinite(v)]
    return float(statistics.median(finite)) if finite else math.nan


def summarize(wall_times: Iterable[float], integrator_times: Iterable[float] = ()) -> dict[str, float]:
    """The timing columns of a row from its timed runs.

    Returns
    -------
    dict
        ``wall_time`` (median), ``wall_time_min``, ``wall_time_max``,
        ``wall_spread`` (``(max - min) / median``, NaN with fewer than two runs)
        and ``integrator_time`` (median of the finite ``integrator_times``, NaN if none).
    """
    times = [float(t) for t in wall_times]
    if not times:
        nan = math.nan
        return {"wall_time": nan, "wall_time_min": nan, "wall_time_max": nan, "wall_spread": nan,
                "integrator_time": _median([float(t) for t in integrator_times])}
    med, low, high = float(statistics.median(times)), min(times), max(times)
    spread = (high - low) / med if len(times) > 1 and med > 0 else math.nan
    return {"wall_time": med, "wall_time_min": low, "wall_time_max": high, "wall_spread": spread,
            "integrator_time": _median([float(t) for t in integrator_times])}


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
    mask = (frame["status"] == "success") & (frame["wall_spread"].astype(float) > threshold)
    return frame[mask].sort_values("wall_spread", ascending=False, kind="stable")
