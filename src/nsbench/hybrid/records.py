"""Readers of a run's event log (accumulation tails, labels); the log itself is built by
:func:`nsbench.engine.events_frame` from the buffers of :mod:`nsbench.model.records`."""

from __future__ import annotations

import numpy as np
import pandas as pd

from nsbench.model.records import Records

__all__ = [
    "ACCUMULATION_ERROR",
    "Records",
    "extrapolated",
    "has_accumulation_limit",
    "labels",
    "match_accumulation_tails",
]


#: The event log's column of an extrapolated accumulation's error estimate (problems with an accumulation limit).
ACCUMULATION_ERROR = "accumulation_error"


def has_accumulation_limit(problem) -> bool:
    """Whether the problem's law declares a limit behaviour for accumulating events (Zeno)."""
    from nsbench.model.law import no_accumulation_limit

    return problem.law.functions.get("accumulation_limit", no_accumulation_limit) is not no_accumulation_limit


def extrapolated(events: pd.DataFrame) -> np.ndarray:
    """Which events of a log the accumulation rule placed (:data:`ACCUMULATION_ERROR` not NaN)."""
    if ACCUMULATION_ERROR not in events:
        return np.zeros(len(events), bool)
    return np.isfinite(events[ACCUMULATION_ERROR].to_numpy(dtype=float))


def labels(events: pd.DataFrame) -> list[tuple[str, int]]:
    """The ``(kind, block)`` of each event."""
    return list(zip(events["kind"], (int(b) for b in events["block"])))


def match_accumulation_tails(a: pd.DataFrame, b: pd.DataFrame) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Two event logs with the Zeno tails they resolved to different depths cut to the shorter one.

    The accumulation rule extrapolates when its estimate is accurate enough, which an integrator's
    accuracy decides: two solutions of the same accumulation log the same first impacts, then one goes
    on longer before its accumulation event. Over the part where the logs agree
    (:func:`nsbench.model.streaks.pair_events`), each run of equal events that ends in an extrapolated
    accumulation in both keeps as many events as the shorter one has; the rest is unchanged (logs
    without :data:`ACCUMULATION_ERROR` are returned as they are). Rows keep their columns, so a
    reference's certified errors stay with their events.
    """
    from nsbench.model.streaks import pair_events

    xa, xb = extrapolated(a), extrapolated(b)
    if not (xa.any() and xb.any()):
        return a, b
    pairs, stop = pair_events(labels(a), xa, labels(b), xb)
    i, j = stop if stop is not None else (len(a), len(b))
    keep_a = [p for p, _ in pairs] + list(range(i, len(a)))
    keep_b = [q for _, q in pairs] + list(range(j, len(b)))
    if len(keep_a) == len(a) and len(keep_b) == len(b):
        return a, b
    return a.iloc[keep_a].reset_index(drop=True), b.iloc[keep_b].reset_index(drop=True)
