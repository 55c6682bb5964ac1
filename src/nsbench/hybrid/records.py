"""The tidy frames of what a run recorded (events), from the buffers of :mod:`nsbench.model.records`."""

from __future__ import annotations

import numpy as np
import pandas as pd

from nsbench.model.records import Records

__all__ = [
    "ACCUMULATION_ERROR",
    "Records",
    "event_frame",
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


def event_frame(problem, rec: Records, n_events: int, located: np.ndarray | None = None) -> pd.DataFrame:
    """The event log: ``t, kind, block, <states>, mode`` (the state and the mode after each event).

    ``kind`` is the event kind's name (``problem.event_kinds``), ``block`` the 1-based
    index of the element its guard belongs to, ``mode`` the problem's name of the mode.
    A problem whose law declares an accumulation limit also has :data:`ACCUMULATION_ERROR`:
    at an event the Zeno rule extrapolated, the error estimate of its time
    (:func:`nsbench.model.rules.tail_estimate`), NaN at every other event.
    ``located`` (a whole-system method that locates its own switches): the method's own
    time of each event, as a column ``t_located`` after ``t`` (NaN where it located none).
    """
    k = n_events
    ev = rec.events
    frame = pd.DataFrame(ev.y[:k], columns=list(problem.state_names))
    frame.insert(0, "t", ev.t[:k].copy())
    frame.insert(
        1, "kind", np.asarray(problem.event_kinds, dtype=object)[ev.kind[:k]] if k else np.empty(0, dtype=object)
    )
    frame.insert(2, "block", (ev.index[:k] + 1).astype("int64"))
    cache: dict[bytes, str] = {}
    texts = []
    for row in ev.mode[:k]:
        key = row.tobytes()
        if key not in cache:
            cache[key] = problem.mode_name(tuple(int(v) for v in row))
        texts.append(cache[key])
    frame["mode"] = pd.Series(texts, dtype=object)
    if has_accumulation_limit(problem):
        frame[ACCUMULATION_ERROR] = ev.err[:k].copy()
    if located is not None:
        frame.insert(1, "t_located", np.asarray(located, dtype=float)[:k].copy())
    return frame


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
