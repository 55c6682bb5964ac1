"""The tidy frames of what a run recorded (events), from the buffers of :mod:`nsbench.model.records`."""

from __future__ import annotations

import numpy as np
import pandas as pd

from nsbench.model.records import Records

__all__ = ["Records", "event_frame"]


def event_frame(problem, rec: Records, n_events: int, located: np.ndarray | None = None) -> pd.DataFrame:
    """The event log: ``t, kind, block, <states>, mode`` (the state and the mode after each event).

    ``kind`` is the event kind's name (``problem.event_kinds``), ``block`` the 1-based
    index of the element its guard belongs to, ``mode`` the problem's name of the mode.
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
    if located is not None:
        frame.insert(1, "t_located", np.asarray(located, dtype=float)[:k].copy())
    return frame
