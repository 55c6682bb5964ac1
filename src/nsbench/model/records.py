"""What a run records: events, section hits and states at requested times; compiled helpers and the buffers.

The buffers are plain arrays in the bundles of :mod:`nsbench.model.abi`
(:class:`~nsbench.model.abi.Events`, :class:`~nsbench.model.abi.Hits`,
:class:`~nsbench.model.abi.Dense`), grown by :class:`Records` when the loop
says they are full.
"""

from __future__ import annotations

import numpy as np

from nsbench.model.abi import SI_NHITS, Dense, Events, Hits
from nsbench.model.compile import hot, inline, small


@inline
def copy_into(dst, src):
    """``dst[:] = src`` for 1-d arrays, without a temporary (usable without reference counting)."""
    for i in range(src.shape[0]):
        dst[i] = src[i]


@hot
def record_hit(hits, si, k, t, y):
    """Append the hit of section ``k`` at ``(t, y)`` (the caller checked there is room)."""
    j = si[SI_NHITS]
    hits.index[j] = k
    hits.t[j] = t
    for i in range(y.shape[0]):
        hits.y[j, i] = y[i]
    si[SI_NHITS] = j + 1


@hot
def sort_hits(hits, lo, hi):
    """Insertion sort of the hits ``lo .. hi - 1`` by time (one step or segment has few)."""
    hk, ht, hy = hits.index, hits.t, hits.y
    for a in range(lo + 1, hi):
        b = a
        while b > lo and ht[b] < ht[b - 1]:
            ht[b], ht[b - 1] = ht[b - 1], ht[b]
            hk[b], hk[b - 1] = hk[b - 1], hk[b]
            for i in range(hy.shape[1]):
                hy[b, i], hy[b - 1, i] = hy[b - 1, i], hy[b, i]
            b -= 1


@inline
def linear_section_value(coeffs, level, y):
    """``coeffs . y - level``."""
    out = -level
    for j in range(y.shape[0]):
        out += coeffs[j] * y[j]
    return out


@inline
def linear_section_rate(coeffs, dy):
    """``coeffs . dy``."""
    out = 0.0
    for j in range(dy.shape[0]):
        out += coeffs[j] * dy[j]
    return out


@small
def section_crossed(direction, before, after):
    """:meth:`nsbench.sections.StateSection.crossed` compiled (``direction`` -1, 0 or +1)."""
    if before == 0.0 or (after != 0.0 and (before < 0.0) == (after < 0.0)):
        return False
    upward = before < 0.0
    return direction == 0 or (direction > 0) == upward


#: Rows of a run's section-hit buffer at its start (it grows as needed; see ``hybrid.run.run_hybrid``).
HITS_AT_START = 64


class Records:
    """Growable buffers for one run: events, section hits and states at requested times.

    Events: time, event kind code, 0-based element index, the state after the
    event, the mode after it and an accumulation's error estimate (NaN otherwise). Hits: section index, time, state. Dense: one
    row per requested time.

    A full event buffer costs a return of the compiled loop to Python and a new entry
    (numba types the loop's bundles again: 15-40 us), so it starts at 1024 events
    and grows fourfold: a run of 1000 events grows it once, of 100,000 events four times.
    """

    def __init__(
        self, n_states: int, mode_size: int, t_eval: np.ndarray, events: int = 1024, hits: int = HITS_AT_START
    ) -> None:
        self.n, self.mode_size = n_states, mode_size
        self.events = Events(
            np.empty(events),
            np.empty(events, np.int64),
            np.empty(events, np.int64),
            np.empty((events, n_states)),
            np.empty((events, mode_size), np.int64),
            np.full(events, np.nan),  # rows written outside the core (inferred events) carry no estimate
        )
        self.hits = Hits(np.empty(hits, np.int64), np.empty(hits), np.empty((hits, n_states)))
        self.dense = Dense(np.ascontiguousarray(t_eval, dtype=float), np.empty((len(t_eval), n_states)))

    @staticmethod
    def _grown(bundle, cap: int, used: int):
        fields = []
        for old in bundle:
            new = (
                np.full((cap,) + old.shape[1:], np.nan)
                if old.dtype == np.float64
                else np.empty((cap,) + old.shape[1:], old.dtype)
            )
            new[:used] = old[:used]
            fields.append(new)
        return type(bundle)(*fields)

    def grow_events(self, used: int) -> None:
        """Quadruple the event buffers, keeping the first ``used`` rows."""
        self.events = self._grown(self.events, 4 * self.events.t.shape[0], used)

    def grow_hits(self, used: int, at_least: int = 0) -> None:
        """Double the hit buffers (at least ``at_least`` rows), keeping the first ``used`` rows."""
        self.hits = self._grown(self.hits, max(2 * self.hits.t.shape[0], at_least), used)

    # names used by the frames and older callers
    @property
    def ev_t(self) -> np.ndarray:
        return self.events.t

    @property
    def ev_kind(self) -> np.ndarray:
        return self.events.kind

    @property
    def ev_block(self) -> np.ndarray:
        """1-based element indices (the event log's ``block`` column)."""
        return self.events.index + 1

    @property
    def ev_y(self) -> np.ndarray:
        return self.events.y

    @property
    def ev_mode(self) -> np.ndarray:
        return self.events.mode

    @property
    def hk(self) -> np.ndarray:
        return self.hits.index

    @property
    def ht(self) -> np.ndarray:
        return self.hits.t

    @property
    def hy(self) -> np.ndarray:
        return self.hits.y

    @property
    def y_eval(self) -> np.ndarray:
        return self.dense.y
