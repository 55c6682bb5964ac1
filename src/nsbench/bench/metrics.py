"""Accuracy metrics of one run against its reference: event alignment, switching-time
errors, state errors, and whether a fixed switching-time target is reached.

Everything here is a pure function of two event logs (and dense states), so it is
tested on constructed logs with hand-derived values.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
import pandas as pd

# the column of a reference's event log holding each event's certified error bound, declared by the
# certification (nsbench.certify.certified_errors)
from nsbench.certify import CERTIFIED
from nsbench.status import Status

#: Relative error floor of a switching time (half an ulp): digits are capped at ~15.95.
REL_FLOOR = 2.0**-53
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


def order_ties_as_reference(reference: pd.DataFrame, events: pd.DataFrame, tol: float = TIE_TOL) -> pd.DataFrame:
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
        pending: dict[Any, list[int]] = {}
        for j in range(lo, hi):
            pending.setdefault(sym[j], []).append(j)
        order[lo:hi] = [pending[s].pop(0) for s in ref_sym[lo:hi]]
    if np.array_equal(order, np.arange(len(events))):
        return events
    return events.iloc[order].reset_index(drop=True)


@dataclass(frozen=True)
class Alignment:
    """How an event log lines up with the reference's, on ``(kind, block)`` and time.

    The best alignment pairs events of the same ``(kind, block)`` in order and
    leaves the others unmatched: it has the fewest unmatched events and, among
    those, the smallest sum of ``|t - t_ref|`` over its pairs (:func:`align`). So
    a run that misses a stick is not paired with the reference's next stick of
    the same block when the one it missed is the closer in time: the missed event
    is reported as missed, where it happened.

    Attributes
    ----------
    n_ref, n_events
        Events in the reference and in the run.
    n_prefix
        Length of the matched prefix: events paired one to one, in order, from
        the first one up to the first unmatched event.
    n_matched
        Events paired by the best alignment; ``n_missed = n_ref - n_matched``,
        ``n_extra = n_events - n_matched``.
    first_divergence_index
        Index of the first unmatched event (``n_prefix``; ``-1`` if the logs match).
    first_divergence_time
        Time of that event: the reference's for a missed event, the run's for an
        extra one; NaN if the logs match.
    first_divergence
        ``'missed'``, ``'extra'`` or ``''`` (the logs match).
    sequence_ok
        The two ``(kind, block)`` sequences are identical.
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
    first_divergence: str = ""


def _label_codes(reference: pd.DataFrame, events: pd.DataFrame) -> tuple[np.ndarray, np.ndarray]:
    """Integer codes of the ``(kind, block)`` labels of two logs (equal labels, equal codes)."""
    kinds = np.concatenate([reference["kind"].to_numpy(dtype=str), events["kind"].to_numpy(dtype=str)])
    blocks = np.concatenate([reference["block"].to_numpy(dtype=np.int64), events["block"].to_numpy(dtype=np.int64)])
    if not kinds.size:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    _, kind_codes = np.unique(kinds, return_inverse=True)
    low = int(blocks.min())
    codes = kind_codes.astype(np.int64) * (int(blocks.max()) - low + 1) + (blocks - low)
    return codes[: len(reference)], codes[len(reference) :]


def align(reference: pd.DataFrame, events: pd.DataFrame) -> Alignment:
    """Align the event log ``events`` with ``reference`` on ``(kind, block)`` and time (see :class:`Alignment`).

    Identical label sequences are paired one to one. Otherwise a dynamic program
    (:func:`nsbench.bench._alignment.diagonal_moves`, compiled) finds the
    alignment with the fewest unmatched events and the smallest total time
    difference of its pairs, in ``O(n m)`` time and ``O(m)`` memory; logs longer
    than :data:`MAX_ALIGN` are aligned over their first :data:`MAX_ALIGN` events.
    """
    ref_codes, codes = _label_codes(reference, events)
    n, m = len(ref_codes), len(codes)
    truncated = n > MAX_ALIGN or m > MAX_ALIGN
    if n == m and np.array_equal(ref_codes, codes):
        return Alignment(
            n_ref=n,
            n_events=m,
            n_prefix=n,
            n_matched=n,
            n_missed=0,
            n_extra=0,
            first_divergence_index=-1,
            first_divergence_time=math.nan,
            sequence_ok=True,
            truncated=truncated,
        )
    from nsbench.bench._alignment import MATCH, SKIP_REFERENCE, diagonal_moves

    t_ref = reference["t"].to_numpy(dtype=float)
    t_run = events["t"].to_numpy(dtype=float)
    na, ma = min(n, MAX_ALIGN), min(m, MAX_ALIGN)
    gaps, _, moves = diagonal_moves(ref_codes[:na], t_ref[:na], codes[:ma], t_run[:ma])
    matched = (na + ma - int(gaps)) // 2
    k = int(np.argmax(moves != MATCH)) if (moves != MATCH).any() else len(moves)
    if k < len(moves):
        missed = moves[k] == SKIP_REFERENCE
    else:  # one log is a prefix of the other (as far as aligned)
        missed = k < n
    when = float(t_ref[k]) if missed else float(t_run[k])
    return Alignment(
        n_ref=n,
        n_events=m,
        n_prefix=k,
        n_matched=matched,
        n_missed=n - matched,
        n_extra=m - matched,
        first_divergence_index=k,
        first_divergence_time=when,
        sequence_ok=False,
        truncated=truncated,
        first_divergence="missed" if missed else "extra",
    )


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


def switching_errors(
    reference: pd.DataFrame, events: pd.DataFrame, n_prefix: int
) -> tuple[SwitchingErrors, np.ndarray, np.ndarray]:
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
    stats = SwitchingErrors(
        err_max=float(err.max()),
        err_rms=float(np.sqrt(np.mean(err**2))),
        err_median=float(np.median(err)),
        digits=float(-math.log10(worst)),
        at_reference=at_reference,
    )
    return stats, t_ref, dt


def state_errors(
    ref_dense: np.ndarray, dense: np.ndarray, ref_final: np.ndarray | None, final: np.ndarray | None
) -> tuple[float, float]:
    """``(final_state_err, state_err_l2)``.

    ``final_state_err`` is the max-norm of the state difference at the final time;
    ``state_err_l2`` the root mean square over the dense points of the Euclidean
    norm of the difference. Both NaN if the run has fewer dense points than the reference;
    ``final_state_err`` NaN if either final state is missing (``None``).
    """
    ref_dense, dense = np.asarray(ref_dense, float), np.asarray(dense, float)
    if dense.shape != ref_dense.shape or dense.size == 0:
        return math.nan, math.nan
    final_err = float(np.max(np.abs(np.asarray(final, float) - np.asarray(ref_final, float))))
    diff = dense - ref_dense
    l2 = float(np.sqrt(np.mean(np.sum(diff**2, axis=0))))
    return final_err, l2


def _stick_rows(log: pd.DataFrame, t_end: float, n_prefix: int | None) -> list[tuple[int, int, float, int, float]]:
    """``(block, stick index, start, slip index or -1, stop)`` of each stick interval of ``log``."""
    out = []
    open_at: dict[int, tuple[int, float]] = {}
    rows = zip(log["t"].to_numpy(dtype=float), log["kind"], log["block"])
    for j, (t, kind, block) in enumerate(rows):
        b = int(block)
        if kind == "stick" and (n_prefix is None or j < n_prefix):
            open_at.setdefault(b, (j, float(t)))
        elif kind == "slip" and b in open_at:
            j0, t0 = open_at.pop(b)
            out.append((b, j0, t0, j, float(t)))
    out.extend((b, j0, t0, -1, float(t_end)) for b, (j0, t0) in open_at.items())
    return sorted(out, key=lambda row: (row[2], row[0]))


def stick_intervals(
    reference: pd.DataFrame, t_end: float, n_prefix: int | None = None
) -> list[tuple[int, float, float]]:
    """The true stick intervals of the reference: ``(block, start, stop)`` (1-based block), from each
    ``stick`` event of a block to its next ``slip`` event (or ``t_end``). A block stuck from the start
    (before any event) is not counted: the log does not say so. With ``n_prefix``, only the intervals whose
    ``stick`` event is among the first ``n_prefix`` (a run's matched prefix: it reproduced the sequence up to
    that stick, so its state there is the reference's to the switching-time error)."""
    return [(b, t0, t1) for b, _, t0, _, t1 in _stick_rows(reference, t_end, n_prefix)]


def _run_interval(events: pd.DataFrame, j0: int, j1: int, n_prefix: int, t_end: float) -> tuple[float, float]:
    """The run's own stick interval matched to the reference's with stick index ``j0`` and slip index ``j1``:
    from its event ``j0`` (the prefix pairs events one to one) to its event ``j1`` if matched, else to the
    block's next slip in its own log (or ``t_end``)."""
    t = events["t"].to_numpy(dtype=float)
    start = float(t[j0])
    if 0 <= j1 < n_prefix:
        return start, float(t[j1])
    block = int(events["block"].iloc[j0])
    later = (events["kind"].to_numpy()[j0 + 1 :] == "slip") & (events["block"].to_numpy()[j0 + 1 :] == block)
    hits = np.flatnonzero(later)
    return start, float(t[j0 + 1 + hits[0]]) if hits.size else float(t_end)


@dataclass(frozen=True)
class StickCreep:
    """How fast and how far a run moves off the belt while the reference sticks under an in-cone load.

    The windows are the dense points inside the reference's stick intervals of block
    ``i`` (:func:`stick_intervals`) that start within the run's matched prefix (after a
    run's sequence departs from the reference's, the two states are unrelated: a
    regularised block that broke away early is elsewhere), cut to where the run sticks too
    (its matched stick to its slip: a switching-time error is not creep), at which the load is in the cone,
    ``|R_i| <= fs_i`` with ``v_i = v_belt``, by the reference's state and by the run's own
    (:func:`creep_cone`, :func:`in_cone`: within the kinetic level,
    so inside the static cone ``fr_i >= fs_i`` of Coulomb's law with stiction and
    within what a regularised law can hold; all the points of the interval where the
    load is not known), cut into runs of consecutive points.

    ``creep`` is the drift velocity per unit of stick time, as MuJoCo's users measure
    creep: the distance the block moves relative to the belt, ``sum |d(x_i - v_belt t)|``
    over consecutive points of a window, divided by the stick time those pairs span,
    pooled over every window and block. A regularised law creeps at a speed of order
    (its force's deficit)/(its sharpness), so ``creep`` falls as ``1/eps``; an exact
    method's is rounding, the switch model's at most ``eta``. ``drift`` is the largest
    position drift relative to the belt within a window, ``|(x_i(t) - x_i(t_a)) -
    v_belt (t - t_a)|`` from its first point ``t_a``. Both NaN when no window holds
    two points (or the problem has no belt).
    """

    creep: float
    drift: float


def in_cone(problem, times: np.ndarray, ref_dense: np.ndarray) -> np.ndarray | None:
    """Per block and dense point, whether the reference's load is in the cone: ``|R_i| <= fs_i`` at ``v_i = v_belt``.

    ``ref_dense`` is the reference's dense states ``(n_states, n_points)``. ``R_i`` is MODEL.md's restoring
    force (every force on block ``i`` but friction) with every block at the belt speed, as while stuck
    (``problem.belt_speed_restoring``). ``None`` where the problem does not give its loads.
    """
    restoring = getattr(problem, "belt_speed_restoring", None)
    coefficients = getattr(problem, "coefficients", None)
    if restoring is None or coefficients is None:
        return None
    dense = np.asarray(ref_dense, dtype=float)
    times = np.asarray(times, dtype=float)
    loads = np.array(restoring(times, [dense[2 * i] for i in range(dense.shape[0] // 2)]), dtype=float)
    fs = np.asarray(coefficients.fs, dtype=float).reshape(-1, 1)
    return np.abs(loads.reshape(fs.shape[0], -1)) <= fs


def creep_cone(problem, times: np.ndarray, ref_dense: np.ndarray, dense: np.ndarray | None) -> np.ndarray | None:
    """The windows' load test of :class:`StickCreep`: the load in the cone (:func:`in_cone`) by the reference's
    state and, where the run's dense states ``dense`` are given, by the run's own too (a block whose neighbour
    broke away early in the run carries another load than the reference's: only an in-cone one counts)."""
    cone = in_cone(problem, times, ref_dense)
    if cone is not None and dense is not None:
        own = in_cone(problem, times, dense)
        if own is not None:
            cone = cone & own
    return cone


def stick_creep(
    reference: pd.DataFrame,
    times: np.ndarray,
    dense: np.ndarray,
    v_belt: float,
    t_end: float,
    cone: np.ndarray | None = None,
    n_prefix: int | None = None,
    events: pd.DataFrame | None = None,
) -> StickCreep:
    """:class:`StickCreep` of a run's dense states ``dense`` (shape ``(n_states, n_points)``, states
    ``x1, v1, x2, v2, ...``) at ``times``, over the reference's stick intervals (:func:`stick_intervals`)
    where ``cone`` (shape ``(n_blocks, n_points)``, :func:`in_cone`; ``None``: everywhere) holds, of the
    intervals whose stick event is among the run's first ``n_prefix`` matched events (``None``: all). With the
    run's event log ``events`` (and ``n_prefix``) each interval is cut to where the run sticks too (its matched
    stick to its slip), so a run's switching-time error does not count as creep.

    The interval ends are left out (a point exactly at a switch belongs to neither phase).
    """
    times = np.asarray(times, dtype=float)
    dense = np.asarray(dense, dtype=float)
    moved, spent, drift = 0.0, 0.0, -math.inf
    for block, j0, a, j1, b in _stick_rows(reference, t_end, n_prefix):
        if events is not None and n_prefix is not None:
            a2, b2 = _run_interval(events, j0, j1, n_prefix, t_end)
            a, b = max(a, a2), min(b, b2)
        inside = (times > a) & (times < b)
        if cone is not None:
            inside &= np.asarray(cone[block - 1], dtype=bool)
        idx = np.flatnonzero(inside)
        for window in np.split(idx, np.flatnonzero(np.diff(idx) > 1) + 1):
            if window.size < 2:
                continue
            t = times[window]
            off = dense[2 * (block - 1), window] - v_belt * t  # position relative to the belt
            moved += float(np.sum(np.abs(np.diff(off))))
            spent += float(t[-1] - t[0])
            drift = max(drift, float(np.max(np.abs(off - off[0]))))
    if spent == 0.0:
        return StickCreep(math.nan, math.nan)
    return StickCreep(moved / spent, drift)


def breakaway_error(reference: pd.DataFrame, event_err: np.ndarray, n_prefix: int) -> float:
    """Largest ``|t - t_ref|`` over the break-away (``slip``) events of the matched prefix, NaN if none."""
    kinds = reference["kind"].to_numpy()[:n_prefix]
    err = np.abs(np.asarray(event_err, dtype=float)[:n_prefix])[kinds == "slip"]
    return float(err.max()) if err.size else math.nan


def located_error(reference: pd.DataFrame, events: pd.DataFrame, n_prefix: int) -> float:
    """Largest ``|t_located - t_ref|`` over the matched prefix (the switches the method located itself,
    ``SystemResult.switch_times``), NaN if the run has no ``t_located`` column or locates none of them."""
    if "t_located" not in events or n_prefix == 0:
        return math.nan
    own = events["t_located"].to_numpy(dtype=float)[:n_prefix]
    err = np.abs(own - reference["t"].to_numpy(dtype=float)[:n_prefix])
    return float(np.nanmax(err)) if np.isfinite(err).any() else math.nan


def located_count(events: pd.DataFrame, n_prefix: int) -> int | None:
    """How many events of the matched prefix the method located itself (a finite ``t_located``),
    ``None`` if the run has no ``t_located`` column (a method that locates none of its own)."""
    if "t_located" not in events:
        return None
    return int(np.isfinite(events["t_located"].to_numpy(dtype=float)[:n_prefix]).sum())


def impact_metrics(
    energy, dense: np.ndarray | None, ref_final: np.ndarray | None, final: np.ndarray | None
) -> tuple[float, float]:
    """``(penetration, energy_err)`` of an impact problem (one contact at ``x = 0``, the first state).

    ``penetration`` is the largest depth below the ground at the dense points,
    ``max(0, -x)`` (NaN without them); ``energy_err`` is ``|E(final) - E(ref_final)|``
    with the problem's energy function ``energy`` (NaN without the final states).
    """
    pen = math.nan
    if dense is not None and np.size(dense):
        pen = float(max(0.0, -float(np.min(np.asarray(dense, dtype=float)[0]))))
    err = math.nan
    if ref_final is not None and final is not None:
        err = float(
            abs(float(energy(np.asarray(final, dtype=float))) - float(energy(np.asarray(ref_final, dtype=float))))
        )
    return pen, err


def observed_order(steps, errors) -> float:
    """Slope of ``log(error)`` against ``log(step)`` by least squares over the finite, positive pairs (NaN with
    fewer than two distinct steps). For a regularisation parameter that sharpens as it grows (``eps``),
    pass its inverse as the step."""
    s = np.asarray(steps, dtype=float)
    e = np.asarray(errors, dtype=float)
    keep = np.isfinite(s) & np.isfinite(e) & (s > 0) & (e > 0)
    if np.unique(s[keep]).size < 2:
        return math.nan
    return float(np.polyfit(np.log(s[keep]), np.log(e[keep]), 1)[0])


def reaches(target: float, *, status: str, sequence_ok: bool, err_max: float) -> bool:
    """Whether a run reaches a switching-time error target.

    It must have succeeded, reproduced the reference's event sequence exactly (a
    wrong sequence never counts), and kept every switching-time error within ``target``.
    """
    return bool(status == Status.SUCCESS and sequence_ok and math.isfinite(err_max) and err_max <= target)


def case_metrics(
    reference: pd.DataFrame,
    events: pd.DataFrame,
    ref_dense: np.ndarray | None,
    dense: np.ndarray | None,
    ref_final: np.ndarray | None,
    final: np.ndarray | None,
    times: np.ndarray | None = None,
    v_belt: float | None = None,
    t_end: float | None = None,
    cone: np.ndarray | None = None,
) -> dict:
    """Every metric column of a tidy row (see :mod:`nsbench.bench.schema`).

    ``times`` (the dense grid), ``v_belt`` and ``t_end`` give the stick creep
    (:func:`stick_creep`; NaN without them: a problem without a belt), over the points
    where ``cone`` (:func:`in_cone` of the reference's dense states) holds.
    ``located_err_max`` is the largest ``|t_located - t_ref|`` over the matched prefix, from
    the run's ``t_located`` column (a method that locates its own switches); NaN without it;
    ``n_located`` counts those events (NA without the column).

    Events of a tie group of the reference (:data:`TIE_TOL`) are compared in the
    reference's order (:func:`order_ties_as_reference`), and the impacts of a Zeno tail
    one log resolved deeper than the other before the same accumulation are left out
    (:func:`nsbench.engine.match_accumulation_tails`). If ``reference`` has a
    :data:`CERTIFIED` column, no switching-time error is reported below it.
    """
    from nsbench.engine import match_accumulation_tails

    # a Zeno tail resolved to another depth before the same accumulation event is no missed event
    reference, events = match_accumulation_tails(reference, events)
    events = order_ties_as_reference(reference, events)
    al = align(reference, events)
    sw, t_ref, dt = switching_errors(reference, events, al.n_prefix)
    if ref_dense is not None and dense is not None:
        final_err, l2 = state_errors(ref_dense, dense, ref_final, final)
    else:
        final_err, l2 = math.nan, math.nan
    creep = StickCreep(math.nan, math.nan)
    if dense is not None and times is not None and v_belt is not None and t_end is not None:
        creep = stick_creep(reference, times, dense, v_belt, t_end, cone, al.n_prefix, events)
    out = asdict(al)
    del out["n_events"]  # the run's own counter already holds it
    del out["first_divergence"]  # n_missed / n_extra say it in the row; the time is first_divergence_time
    out.update(
        switch_err_max=sw.err_max,
        switch_err_rms=sw.err_rms,
        switch_err_median=sw.err_median,
        switch_digits=sw.digits,
        at_ref_accuracy=sw.at_reference,
        final_state_err=final_err,
        state_err_l2=l2,
        stick_creep=creep.creep,
        stick_drift=creep.drift,
        breakaway_err_max=breakaway_error(reference, dt, al.n_prefix),
        located_err_max=located_error(reference, events, al.n_prefix),
        n_located=located_count(events, al.n_prefix),
        event_t=t_ref.tolist(),
        event_err=dt.tolist(),
        event_cert=certainty(reference, al.n_prefix).tolist() if CERTIFIED in reference else [],
    )
    return out


#: The columns of an event log the metrics read (:func:`case_metrics`): what a stored log keeps.
GRADED_LOG_COLUMNS = ("t", "kind", "block", "t_located", "accumulation_error")


def event_log_text(events: pd.DataFrame) -> str:
    """An event log's graded columns (:data:`GRADED_LOG_COLUMNS`, those it has) as JSON text.

    Floats are written by their ``repr`` (``json``), so :func:`event_log_frame` reads back the very
    same values: grading the stored log again gives the stored errors bit for bit.
    """
    import json

    kept = {}
    for name in GRADED_LOG_COLUMNS:
        if name in events:
            values = events[name].tolist()
            kept[name] = [int(v) for v in values] if name == "block" else values
    return json.dumps(kept, default=float)


def event_log_frame(text: str) -> pd.DataFrame:
    """The event log stored by :func:`event_log_text`, as the frame the metrics take.

    Raises ``ValueError`` if ``text`` is not such a log (not JSON, no ``t``/``kind``/``block``,
    columns of different lengths).
    """
    import json

    data = json.loads(text)
    if not isinstance(data, dict) or not {"t", "kind", "block"} <= set(data):
        raise ValueError("not an event log (a JSON table with t, kind and block)")
    lengths = {len(v) for v in data.values()}
    if len(lengths) > 1:
        raise ValueError("its columns have different lengths")
    frame = pd.DataFrame({k: data[k] for k in GRADED_LOG_COLUMNS if k in data})
    frame["t"] = frame["t"].astype(float)
    frame["block"] = frame["block"].astype(np.int64)
    frame["kind"] = frame["kind"].astype(str)
    for name in ("t_located", "accumulation_error"):
        if name in frame:
            frame[name] = pd.to_numeric(frame[name], errors="coerce").astype(float)
    return frame


#: How :func:`dense_states_text` writes its arrays: IEEE 754 doubles, little-endian, row-major, in base64.
DENSE_ENCODING = "float64-le-base64"


def dense_states_text(dense: np.ndarray, final: np.ndarray) -> str:
    """A run's dense states ``(n_states, n_points)`` on the suite's grid and its final state, as JSON text.

    ``{"encoding": "float64-le-base64", "n_states": n, "n_points": m, "dense": ..., "final": ...}``:
    each array's IEEE 754 doubles, little-endian, row-major (state by state), in base64, so
    :func:`dense_states_arrays` reads back the very same bits (NaN and infinities included) in about
    11 characters a value. The grid is not stored: it is the suite's, ``numpy.linspace(t0, t_end, m)``.
    """
    import base64
    import json

    dense = np.ascontiguousarray(dense, dtype="<f8")
    final = np.ascontiguousarray(final, dtype="<f8").reshape(-1)
    if dense.ndim != 2 or final.size != dense.shape[0]:
        raise ValueError(f"dense states of shape {dense.shape} and a final state of {final.size} values do not fit")
    return json.dumps(
        {
            "encoding": DENSE_ENCODING,
            "n_states": int(dense.shape[0]),
            "n_points": int(dense.shape[1]),
            "dense": base64.b64encode(dense.tobytes()).decode("ascii"),
            "final": base64.b64encode(final.tobytes()).decode("ascii"),
        }
    )


def dense_states_arrays(text: str) -> tuple[np.ndarray, np.ndarray]:
    """``(dense, final)`` stored by :func:`dense_states_text`, bit for bit.

    Raises ``ValueError`` if ``text`` is not such a record (not JSON, another encoding, arrays of
    another length than their shape).
    """
    import base64
    import binascii
    import json

    data = json.loads(text)
    if not isinstance(data, dict) or data.get("encoding") != DENSE_ENCODING:
        raise ValueError(f"not dense states (a JSON object of encoding {DENSE_ENCODING!r})")
    n, m = data.get("n_states"), data.get("n_points")
    if not (isinstance(n, int) and isinstance(m, int) and n >= 1 and m >= 0):
        raise ValueError(f"n_states {n!r} and n_points {m!r} must be whole numbers, n_states at least 1")
    try:
        dense = np.frombuffer(base64.b64decode(str(data.get("dense")), validate=True), dtype="<f8")
        final = np.frombuffer(base64.b64decode(str(data.get("final")), validate=True), dtype="<f8")
    except (binascii.Error, ValueError) as exc:
        raise ValueError(f"its arrays are not base64 doubles ({exc})") from None
    if dense.size != n * m or final.size != n:
        raise ValueError(f"{dense.size} dense and {final.size} final values for {n} states at {m} points")
    return dense.reshape(n, m).astype(float), final.astype(float)
