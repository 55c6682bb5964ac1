"""Accuracy metrics of one run against its reference: event alignment, switching-time
errors, state errors, and whether a fixed switching-time target is reached.

Everything here is a pure function of two event logs (and dense states), so it is
tested on constructed logs with hand-derived values.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np
import pandas as pd

#: Relative error floor of a switching time (half an ulp): digits are capped at ~15.95.
REL_FLOOR = 2.0 ** -53
#: Longest event logs aligned in full; longer ones (event storms) are truncated.
MAX_ALIGN = 20_000
#: Reference events closer than this in time (problem units) form a tie group, whose order is
#: not a property of the solution: from rest, the inner blocks of a long chain are tied to
#: far below rounding (the coupling reaches block i at order t**(2 i)) and the arithmetic
#: orders them at random. Far below the spacing of distinct events (0.01 or more in the
#: paper's problems) and far above a tie group's rounding spread (1e-15).
TIE_TOL = 1e-9


def event_symbols(events: pd.DataFrame) -> list[str]:
    """The ``(kind, block)`` sequence of an event log as strings like ``'stick@1'``."""
    return [f"{k}@{int(b)}" for k, b in zip(events["kind"], events["block"])]


def tie_groups(t: np.ndarray, tol: float = TIE_TOL) -> np.ndarray:
    """Group label of each event of a log sorted in time: a new group where the gap exceeds ``tol``."""
    t = np.asarray(t, dtype=float)
    if t.size == 0:
        return np.zeros(0, dtype=np.int64)
    return np.concatenate([[0], np.cumsum(np.diff(t) > tol)]).astype(np.int64)


def order_ties_as_reference(reference: pd.DataFrame, events: pd.DataFrame,
                            tol: float = TIE_TOL) -> pd.DataFrame:
    """``events`` with each tie group of the reference put in the reference's order.

    Walking the reference's tie groups (:func:`tie_groups`) from the start, the
    run's events at the same positions are reordered to the reference's
    ``(kind, block)`` order when they hold the same multiset of ``(kind, block)``;
    at the first group where they do not (a missed or extra event, a wrong
    transition), nothing further is reordered and the alignment reports the
    divergence as usual. Logs without ties are returned unchanged.
    """
    groups = tie_groups(reference["t"].to_numpy(dtype=float), tol)
    if groups.size == 0 or groups[-1] == groups.size - 1:
        return events  # every reference event stands alone
    ref_sym, sym = event_symbols(reference), event_symbols(events)
    order = np.arange(len(events))
    bounds = np.flatnonzero(np.diff(np.concatenate([[-1], groups, [groups[-1] + 1]])))
    for lo, hi in zip(bounds[:-1], bounds[1:]):
        if hi - lo < 2:
            if lo >= len(sym) or sym[lo] != ref_sym[lo]:
                break
            continue
        if hi > len(sym) or sorted(sym[lo:hi]) != sorted(ref_sym[lo:hi]):
            break
        pending = {}
        for j in range(lo, hi):
            pending.setdefault(sym[j], []).append(j)
        order[lo:hi] = [pending[s].pop(0) for s in ref_sym[lo:hi]]
    if np.array_equal(order, np.arange(len(events))):
        return events
    return events.iloc[order].reset_index(drop=True)


def common_prefix(a: list[str], b: list[str]) -> int:
    """Length of the longest common prefix of two sequences."""
    n = min(len(a), len(b))
    for i in range(n):
        if a[i] != b[i]:
            return i
    return n


def lcs_length(a: list[str], b: list[str]) -> int:
    """Length of the longest common subsequence (bit-parallel, O(len(a) len(b) / word))."""
    if not a or not b:
        return 0
    masks: dict[str, int] = {}
    for i, s in enumerate(a):
        masks[s] = masks.get(s, 0) | (1 << i)
    full = (1 << len(a)) - 1
    v = full
    for s in b:
        u = v & masks.get(s, 0)
        v = ((v + u) | (v - u)) & full
    return len(a) - bin(v).count("1")


@dataclass(frozen=True)
class Alignment:
    """How an event sequence lines up with the reference's ``(kind, block)`` sequence.

    Attributes
    ----------
    n_ref, n_events
        Events in the reference and in the run.
    n_prefix
        Length of the matched prefix: events equal, in order, from the first one.
    n_matched
        Events matched by the best alignment of the whole sequences (longest
        common subsequence); ``n_missed = n_ref - n_matched``, ``n_extra = n_events - n_matched``.
    first_divergence_index
        Index of the first event where the sequences differ (``-1`` if identical).
    first_divergence_time
        Reference time of that event (the run's time if the reference has ended), NaN if identical.
    sequence_ok
        The two sequences are identical.
    truncated
        The logs were longer than :data:`MAX_ALIGN` and only their starts were aligned.
    """

    n_ref: int
    n_events: int
    n_prefix: int
    n_matched: int
    n_missed: int
    n_extra: int
    first_divergence_index: int
    first_divergence_time: float
    sequence_ok: bool
    truncated: bool


def align(reference: pd.DataFrame, events: pd.DataFrame) -> Alignment:
    """Align the event log ``events`` with ``reference`` (see :class:`Alignment`)."""
    ref_sym, sym = event_symbols(reference), event_symbols(events)
    truncated = len(ref_sym) > MAX_ALIGN or len(sym) > MAX_ALIGN
    p = common_prefix(ref_sym, sym)
    same = p == len(ref_sym) == len(sym)
    matched = len(ref_sym) if same else lcs_length(ref_sym[:MAX_ALIGN], sym[:MAX_ALIGN])
    if same:
        index, when = -1, math.nan
    else:
        index = p
        when = float(reference["t"].iloc[p]) if p < len(reference) else float(events["t"].iloc[p])
    return Alignment(n_ref=len(ref_sym), n_events=len(sym), n_prefix=p, n_matched=matched,
                     n_missed=len(ref_sym) - matched, n_extra=len(sym) - matched,
                     first_divergence_index=index, first_divergence_time=when,
                     sequence_ok=same, truncated=truncated)


#: Column of a reference's event log holding each event's certified error bound
#: (:func:`nsbench.bench.reference.certified_errors`).
CERTIFIED = "certified_error"


@dataclass(frozen=True)
class SwitchingErrors:
    """Switching-time errors over the matched prefix (NaN when the prefix is empty).

    Each event's error is ``max(|dt_i|, c_i)`` where the reference carries a
    certified error bound ``c_i`` there: a difference from the reference smaller
    than the reference's own uncertainty is no measurement of the run's error,
    so it is reported as that uncertainty ("at reference accuracy"). ``digits``
    is the number of significant correct digits of the *worst* switching time,
    ``-log10(max_i err_i / |t_ref_i|)``, capped at ``-log10(2**-53)``.
    ``at_reference`` is true when every event's ``|dt_i|`` is within ``c_i``:
    the run cannot be told apart from the reference.
    """

    err_max: float
    err_rms: float
    err_median: float
    digits: float
    at_reference: bool = False


def certainty(reference: pd.DataFrame, n: int | None = None) -> np.ndarray:
    """The certified error bound of the first ``n`` reference events (zeros if the log has none).

    An event the check could not certify (NaN in the log) has no floor here (0):
    its uncertainty shows in the reference's ``ref_certainty`` (``inf``) instead.
    """
    if CERTIFIED not in reference:
        return np.zeros(len(reference) if n is None else n)
    c = reference[CERTIFIED].to_numpy(dtype=float)[:n]
    return np.where(np.isfinite(c), c, 0.0)


def switching_errors(reference: pd.DataFrame, events: pd.DataFrame, n_prefix: int) -> tuple[SwitchingErrors, np.ndarray, np.ndarray]:
    """Errors of the first ``n_prefix`` event times; also the reference times and signed errors.

    The signed errors are the measured ``t - t_ref``; the statistics floor each
    at the reference's certified error there (see :class:`SwitchingErrors`).
    """
    t_ref = reference["t"].to_numpy(dtype=float)[:n_prefix]
    dt = events["t"].to_numpy(dtype=float)[:n_prefix] - t_ref
    if n_prefix == 0:
        nan = math.nan
        return SwitchingErrors(nan, nan, nan, nan), t_ref, dt
    floor = certainty(reference, n_prefix)
    at_reference = bool(CERTIFIED in reference and np.all(np.abs(dt) <= floor))
    err = np.maximum(np.abs(dt), floor)
    with np.errstate(divide="ignore", invalid="ignore"):
        rel = np.where(err == 0.0, 0.0, err / np.abs(t_ref))
    worst = max(float(np.max(rel)), REL_FLOOR)
    stats = SwitchingErrors(err_max=float(err.max()), err_rms=float(np.sqrt(np.mean(err ** 2))),
                            err_median=float(np.median(err)), digits=float(-math.log10(worst)),
                            at_reference=at_reference)
    return stats, t_ref, dt


def state_errors(ref_dense: np.ndarray, dense: np.ndarray, ref_final: np.ndarray,
                 final: np.ndarray) -> tuple[float, float]:
    """``(final_state_err, state_err_l2)``.

    ``final_state_err`` is the max-norm of the state difference at the final time;
    ``state_err_l2`` the root mean square over the dense points of the Euclidean
    norm of the difference. Both NaN if the run has fewer dense points than the reference.
    """
    ref_dense, dense = np.asarray(ref_dense, float), np.asarray(dense, float)
    if dense.shape != ref_dense.shape or dense.size == 0:
        return math.nan, math.nan
    final_err = float(np.max(np.abs(np.asarray(final, float) - np.asarray(ref_final, float))))
    diff = dense - ref_dense
    l2 = float(np.sqrt(np.mean(np.sum(diff ** 2, axis=0))))
    return final_err, l2


def reaches(target: float, *, status: str, sequence_ok: bool, err_max: float) -> bool:
    """Whether a run reaches a switching-time error target.

    It must have succeeded, reproduced the reference's event sequence exactly (a
    wrong sequence never counts), and kept every switching-time error within ``target``.
    """
    return bool(status == "success" and sequence_ok and math.isfinite(err_max) and err_max <= target)


def case_metrics(reference: pd.DataFrame, events: pd.DataFrame, ref_dense: np.ndarray | None,
                 dense: np.ndarray | None, ref_final: np.ndarray | None,
                 final: np.ndarray | None) -> dict:
    """Every metric column of a tidy row (see :mod:`nsbench.bench.schema`).

    Events of a tie group of the reference (:data:`TIE_TOL`) are compared in the
    reference's order (:func:`order_ties_as_reference`). If ``reference`` has a
    :data:`CERTIFIED` column, no switching-time error is reported below it.
    """
    events = order_ties_as_reference(reference, events)
    al = align(reference, events)
    sw, t_ref, dt = switching_errors(reference, events, al.n_prefix)
    if ref_dense is not None and dense is not None:
        final_err, l2 = state_errors(ref_dense, dense, ref_final, final)
    else:
        final_err, l2 = math.nan, math.nan
    out = asdict(al)
    del out["n_events"]  # the run's own counter already holds it
    out.update(switch_err_max=sw.err_max, switch_err_rms=sw.err_rms,
               switch_err_median=sw.err_median, switch_digits=sw.digits, at_ref_accuracy=sw.at_reference,
               final_state_err=final_err, state_err_l2=l2,
               event_t=t_ref.tolist(), event_err=dt.tolist(),
               event_cert=certainty(reference, al.n_prefix).tolist() if CERTIFIED in reference else [])
    return out
