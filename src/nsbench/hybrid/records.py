"""The buffers the hybrid loop writes (events, section hits, dense states), grown on demand, and their frames."""

from __future__ import annotations

import numpy as np
import pandas as pd

from nsbench.problems.modes import EVENT_KINDS, PHASE_NAMES


class Records:
    """Growable arrays for one run: events, section hits and states at requested times.

    Events: ``t``, kind code (:data:`nsbench.hybrid.rules.EV_STICK` ...), 1-based block,
    the state after the event and the mode after it. Hits: section index, time,
    state. Dense: one row per requested time.
    """

    def __init__(self, n_states: int, n_blocks: int, n_eval: int, events: int = 256, hits: int = 64) -> None:
        self.n, self.nb = n_states, n_blocks
        self.ev_t = np.empty(events)
        self.ev_kind = np.empty(events, np.int64)
        self.ev_block = np.empty(events, np.int64)
        self.ev_y = np.empty((events, n_states))
        self.ev_mode = np.empty((events, n_blocks), np.int8)
        self.hk = np.empty(hits, np.int64)
        self.ht = np.empty(hits)
        self.hy = np.empty((hits, n_states))
        self.y_eval = np.empty((n_eval, n_states))

    def grow_events(self, used: int) -> None:
        """Double the event buffers, keeping the first ``used`` rows."""
        cap = 2 * self.ev_t.shape[0]
        for name in ("ev_t", "ev_kind", "ev_block", "ev_y", "ev_mode"):
            old = getattr(self, name)
            new = np.empty((cap,) + old.shape[1:], old.dtype)
            new[:used] = old[:used]
            setattr(self, name, new)

    def grow_hits(self, used: int, at_least: int = 0) -> None:
        """Double the hit buffers (at least ``at_least`` rows), keeping the first ``used`` rows."""
        cap = max(2 * self.ht.shape[0], at_least)
        for name in ("hk", "ht", "hy"):
            old = getattr(self, name)
            new = np.empty((cap,) + old.shape[1:], old.dtype)
            new[:used] = old[:used]
            setattr(self, name, new)


def mode_text(phases) -> str:
    """A mode as the event log writes it, e.g. ``'stick|slip-'``."""
    return "|".join(PHASE_NAMES[int(p)] for p in phases)


def parse_mode(text: str) -> tuple[int, ...]:
    """The inverse of :func:`mode_text`."""
    codes = {name: phase for phase, name in PHASE_NAMES.items()}
    return tuple(codes[part] for part in text.split("|"))


def event_frame(rec: Records, n_events: int, state_names: tuple[str, ...]) -> pd.DataFrame:
    """The event log: ``t, kind, block, <states>, mode`` (the state and the mode after each event)."""
    k = n_events
    frame = pd.DataFrame(rec.ev_y[:k], columns=list(state_names))
    frame.insert(0, "t", rec.ev_t[:k].copy())
    frame.insert(1, "kind", np.asarray(EVENT_KINDS, dtype=object)[rec.ev_kind[:k]] if k else
                 np.empty(0, dtype=object))
    frame.insert(2, "block", rec.ev_block[:k].astype("int64"))
    modes = rec.ev_mode[:k]
    cache: dict[bytes, str] = {}
    texts = []
    for row in modes:
        key = row.tobytes()
        if key not in cache:
            cache[key] = mode_text(row)
        texts.append(cache[key])
    frame["mode"] = pd.Series(texts, dtype=object)
    return frame
