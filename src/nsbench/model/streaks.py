"""Pairing the events of two solutions whose Zeno tails were resolved to different depths (pure Python).

The accumulation rule (:func:`nsbench.model.rules.accumulation_time`) extrapolates a Zeno sequence once
its estimate is accurate enough, which the accuracy of the event times decides: two solutions of the
same accumulation log the same first events of the sequence, then one goes on longer before its
accumulation event. :func:`pair_events` pairs two logs event by event, and where a run of equal events
ends in an extrapolated accumulation in both, pairs as many of them as the shorter run has and then
the two accumulation events. Used by the bench's alignment and certification and by the mp check.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Hashable, Sequence, Union

if TYPE_CHECKING:
    import numpy as np

#: Which events are extrapolated: a sequence of bools or a boolean array.
Marks = Union[Sequence[bool], "np.ndarray"]


def streak_ends(labels: Sequence[Hashable], extrapolated: Marks) -> dict[int, int]:
    """First index of each run of equal labels followed by an extrapolated event -> that event's index."""
    out: dict[int, int] = {}
    start = 0
    for i in range(1, len(labels) + 1):
        if i == len(labels) or labels[i] != labels[start] or extrapolated[i]:
            if i < len(labels) and extrapolated[i] and not extrapolated[start]:
                out[start] = i
            start = i
    return out


def pair_events(
    labels_a: Sequence[Hashable],
    extrapolated_a: Marks,
    labels_b: Sequence[Hashable],
    extrapolated_b: Marks,
) -> tuple[list[tuple[int, int]], tuple[int, int] | None]:
    """Index pairs ``(i, j)`` of two event logs that agree from the start, and where they stop agreeing.

    ``labels`` are the events' ``(kind, element)``; ``extrapolated`` marks the events the accumulation
    rule placed. Events pair one to one while their label and mark agree; a run of equal labels that
    ends in an extrapolated event in both logs pairs its first ``min`` events and the two extrapolated
    events (the longer run's other events lie in the tail the shorter one extrapolated). The second
    value is ``None`` if every event of both logs is paired or skipped so, else the indices ``(i, j)``
    of the first events that do not agree (``i == len(labels_a)`` or ``j == len(labels_b)`` when one
    log ends first).
    """
    ends_a, ends_b = streak_ends(labels_a, extrapolated_a), streak_ends(labels_b, extrapolated_b)
    pairs: list[tuple[int, int]] = []
    i = j = 0
    na, nb = len(labels_a), len(labels_b)
    while i < na and j < nb:
        if labels_a[i] != labels_b[j] or bool(extrapolated_a[i]) != bool(extrapolated_b[j]):
            break
        if i in ends_a and j in ends_b:
            n = min(ends_a[i] - i, ends_b[j] - j)
            pairs += [(i + k, j + k) for k in range(n)]
            pairs.append((ends_a[i], ends_b[j]))
            i, j = ends_a[i] + 1, ends_b[j] + 1
            continue
        pairs.append((i, j))
        i, j = i + 1, j + 1
    return pairs, (None if i == na and j == nb else (i, j))
