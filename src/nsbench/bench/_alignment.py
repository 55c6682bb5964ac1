"""The compiled alignment of two event logs on label and time (used by :mod:`nsbench.bench.metrics`).

A dynamic program over the suffixes of the two logs: an alignment pairs events
of equal label (``(kind, block)``) in order and leaves the others unmatched
(missed reference events, extra events of the run). The best alignment has the
fewest unmatched events and, among those, the smallest sum of ``|t - t_ref|``
over its pairs: the label sequence decides how many events match, the times
decide which. So a run that misses a stick is aligned with the reference's
*next* stick only when that is as close in time as the one it missed.

Importing this module imports numba; compiled once per install (cached on disk).
"""

from __future__ import annotations

import numba
import numpy as np

#: Moves of the alignment at a cell (i, j): pair the two events, or leave one unmatched.
MATCH, SKIP_REFERENCE, SKIP_RUN = 0, 1, 2


@numba.njit(cache=True, nogil=True)
def diagonal_moves(ref_labels, ref_t, run_labels, run_t):  # pragma: no cover - compiled
    """The best alignment's cost and its move at every diagonal cell ``(k, k)``.

    ``S[i][j]`` is the best ``(unmatched events, sum of |dt| of the pairs)`` of the
    suffixes ``ref[i:]`` and ``run[j:]``, compared lexicographically; rows are
    computed from the end, two at a time (memory ``O(len(run))``). On a tie a
    pair is preferred to leaving events unmatched, and between the two gaps the
    one whose event comes first in time is left unmatched first.

    Returns
    -------
    gaps : int
        Unmatched events of the best alignment (missed plus extra).
    cost : float
        Sum of ``|t_run - t_ref|`` over its pairs.
    moves : int64 array of ``min(n, m)``
        The best move at ``(k, k)`` (:data:`MATCH`, :data:`SKIP_REFERENCE`, :data:`SKIP_RUN`).
    """
    n, m = ref_labels.shape[0], run_labels.shape[0]
    gaps_next = np.empty(m + 1, np.int64)
    cost_next = np.zeros(m + 1)
    for j in range(m + 1):
        gaps_next[j] = m - j  # ref[n:] is empty: every remaining run event is extra
    gaps_here = np.empty(m + 1, np.int64)
    cost_here = np.zeros(m + 1)
    moves = np.full(min(n, m), SKIP_REFERENCE, np.int64)
    for i in range(n - 1, -1, -1):
        gaps_here[m] = n - i
        cost_here[m] = 0.0
        for j in range(m - 1, -1, -1):
            # leave ref[i] unmatched, or run[j]: the one that comes first in time on a tie
            g_ref, c_ref = gaps_next[j] + 1, cost_next[j]
            g_run, c_run = gaps_here[j + 1] + 1, cost_here[j + 1]
            if g_ref < g_run or (g_ref == g_run and (c_ref < c_run or (c_ref == c_run and ref_t[i] <= run_t[j]))):
                best_g, best_c, move = g_ref, c_ref, SKIP_REFERENCE
            else:
                best_g, best_c, move = g_run, c_run, SKIP_RUN
            if ref_labels[i] == run_labels[j]:
                g_pair, c_pair = gaps_next[j + 1], cost_next[j + 1] + abs(run_t[j] - ref_t[i])
                if g_pair < best_g or (g_pair == best_g and c_pair <= best_c):
                    best_g, best_c, move = g_pair, c_pair, MATCH
            gaps_here[j] = best_g
            cost_here[j] = best_c
            if i == j:
                moves[i] = move
        gaps_next, gaps_here = gaps_here, gaps_next
        cost_next, cost_here = cost_here, cost_next
    return gaps_next[0], cost_next[0], moves
