"""Re-grading a submitted run against the archive's own references.

Each row's switching-time errors are computed again from the event log its results folder
keeps (the ``event_log`` column, :func:`nsbench.bench.metrics.event_log_text`) against a
certified reference the archive computes itself (:func:`nsbench.bench.reference.compute_reference`,
cached under ``ARCHIVE/references/`` in the bench's checksummed format), with the bench's own
grading (:func:`nsbench.bench.metrics.case_metrics`). The submitted error columns are only
compared with the result, never used.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from nsbench.bench import metrics
from nsbench.bench.reference import Reference, compute_reference, load_reference, reference_key, save_reference
from nsbench.errors import NsbenchError
from nsbench.status import ReferenceStatus

#: Dense points of an archive reference when the run's provenance does not give its suite's
#: ``dense_points``. With the run's own number the archive's reference is the very computation the
#: bench graded against (the same problem, integrator, span and grid); the grid is kept because a
#: reference integrator that steps to its output times would place its events a few ulps apart on
#: another grid. The state errors, which need the run's dense states, are not re-graded.
DENSE_POINTS = 2
#: Agreement allowed between a submitted error and the re-graded one, in units of the rounding of
#: the span's largest time (``ULPS * eps * max(|t0|, |t_end|, 1)``). On one machine the two gradings
#: are the same computation on the same log and agree bit for bit; a reference computed on another
#: machine may round its switching times differently (FMA contraction, another libm), by a few
#: ulps of the times themselves, which moves every ``t - t_ref`` by as much. The tolerance only
#: decides whether a submission is refused: the archive keeps the re-graded errors, never the
#: submitted ones, so a difference within it changes no entry of the leaderboard.
ULPS = 16
#: The columns re-graded from the event log (they replace the submitted ones in the archive).
REGRADED = (
    "n_ref",
    "n_prefix",
    "n_matched",
    "n_missed",
    "n_extra",
    "first_divergence_index",
    "first_divergence_time",
    "sequence_ok",
    "switch_err_max",
    "switch_err_rms",
    "switch_err_median",
    "switch_digits",
    "at_ref_accuracy",
    "breakaway_err_max",
    "located_err_max",
    "n_located",
    "event_t",
    "event_err",
    "event_cert",
)


@dataclass(frozen=True)
class Graded:
    """One row re-graded: the re-graded columns, its events, and why it was not (``mark``)."""

    values: dict[str, Any]
    events: pd.DataFrame
    mark: str = ""
    #: Graded, but with something this nsbench does not know (an integrator plug-in not installed here).
    note: str = ""

    @property
    def graded(self) -> bool:
        return not self.mark


def archive_reference(
    folder: Path, problem: dict[str, Any], config: dict[str, Any], t0: float, t_end: float, dense_points: int
) -> Reference:
    """The archive's certified reference of ``problem`` by the integrator ``config`` over ``[t0, t_end]``:
    loaded from ``folder`` (checksums checked) or computed and stored there."""
    key = reference_key(problem, [config], t0, t_end, dense_points)
    ref = load_reference(folder, key)
    if ref is None:
        ref = compute_reference(problem, [config], t0, t_end, dense_points)
        save_reference(folder, ref)
    return ref


def unknown_parts(row: pd.Series) -> tuple[list[str], list[str]]:
    """What of a row this nsbench does not know: ``(blocking, noted)``. A problem or reference integrator
    it does not know blocks the re-grading (no reference can be computed here); an integrator under
    test it does not know (a plug-in not installed here) does not: the grading needs only the log."""
    from nsbench.integrators import list_integrators
    from nsbench.problems import list_problems

    blocking, noted = [], []
    if str(row["problem"]) not in list_problems():
        blocking.append(f"unknown problem {row['problem']}")
    ref = _json(row["reference_config"])
    if isinstance(ref, dict) and ref.get("name") not in list_integrators():
        blocking.append(f"unknown reference integrator {ref.get('name')}")
    if str(row["integrator"]) not in list_integrators():
        noted.append(f"unknown integrator {row['integrator']} (a plug-in not installed here)")
    return blocking, noted


def _json(text: Any) -> Any:
    try:
        return json.loads(str(text)) if text is not None and not pd.isna(text) and str(text) else None
    except ValueError:
        return None


def grade_row(row: pd.Series, references: Path, dense_points: int = DENSE_POINTS) -> Graded:
    """Re-grade one tidy row (see the module's docstring) against the reference of ``dense_points``
    (the run's suite's); a row that cannot be is kept, marked."""
    log_text = "" if pd.isna(row["event_log"]) else str(row["event_log"])
    if not log_text:
        return Graded({}, no_events(), mark=f"not re-graded: the case did not run ({row['status']})")
    blocking, noted = unknown_parts(row)
    if blocking:
        return Graded({}, no_events(), mark=f"not re-graded: {'; '.join(blocking)}")
    ref_config, problem = _json(row["reference_config"]), _json(row["problem_config"])
    if not isinstance(ref_config, dict) or not isinstance(problem, dict):
        return Graded({}, no_events(), mark="not re-graded: the run had no reference integrator")
    try:
        events = metrics.event_log_frame(log_text)
    except (ValueError, TypeError) as exc:
        return Graded({}, no_events(), mark=f"not re-graded: its event_log is damaged ({exc})")
    try:
        t0, t_end = float(row["t0"]), float(row["t_end"])
        ref = archive_reference(references, problem, ref_config, t0, t_end, dense_points)
    except NsbenchError as exc:  # a problem or reference configuration this nsbench refuses
        return Graded({}, no_events(), mark=f"not re-graded: the archive's reference cannot be computed ({exc})")
    if ReferenceStatus.of(ref.status) is not ReferenceStatus.OK:
        return Graded({}, no_events(), mark=f"not re-graded: the archive's reference: {ref.status}")
    values, table = _grade(ref, events)
    # an unknown integrator plug-in: graded all the same (the grading needs no integrator), and marked
    return Graded(values, table, note="; ".join(noted))


def _grade(ref: Reference, events: pd.DataFrame) -> tuple[dict[str, Any], pd.DataFrame]:
    from nsbench.engine import match_accumulation_tails

    out = metrics.case_metrics(ref.events, events, None, None, None, None)
    values = {name: out[name] for name in REGRADED if name in out}
    values["n_ref"] = len(ref.events)
    # the events the grading paired, as it paired them (a Zeno tail cut, ties in the reference's order)
    reference, run = match_accumulation_tails(ref.events, events)
    run = metrics.order_ties_as_reference(reference, run)
    n = int(out["n_prefix"])
    t_ref = np.asarray(out["event_t"], dtype=float)
    cert = np.asarray(out["event_cert"], dtype=float) if len(out["event_cert"]) else np.full(n, math.nan)
    table = pd.DataFrame(
        {
            "event": np.arange(n, dtype=np.int64),
            "kind": reference["kind"].astype(str).to_numpy()[:n],
            "block": reference["block"].to_numpy(dtype=np.int64)[:n],
            "t": run["t"].to_numpy(dtype=float)[:n],
            "t_ref": t_ref,
            "abs_dt": np.abs(np.asarray(out["event_err"], dtype=float)),
            "certified_error": cert,
        }
    )
    return values, table


def no_events() -> pd.DataFrame:
    return pd.DataFrame(
        {
            "event": pd.Series([], dtype=np.int64),
            "kind": pd.Series([], dtype=str),
            "block": pd.Series([], dtype=np.int64),
            **{name: pd.Series([], dtype=float) for name in ("t", "t_ref", "abs_dt", "certified_error")},
        }
    )


def tolerance(row: pd.Series) -> float:
    """The agreement allowed for the row's errors (:data:`ULPS`)."""
    scale = max(abs(float(row["t0"])), abs(float(row["t_end"])), 1.0)
    return ULPS * float(np.finfo(float).eps) * scale


def disagreement(row: pd.Series, values: dict[str, Any]) -> str:
    """How the submitted row's errors differ from the re-graded ``values`` ('' if they agree).

    A row the submitter could not grade (its reference failed) has nothing to compare.
    """
    if ReferenceStatus.of(str(row["reference_status"])) is not ReferenceStatus.OK:
        return ""
    tol = tolerance(row)
    for name in ("n_prefix", "sequence_ok"):
        if _value(row[name]) != _value(values[name]):
            return f"{name} {_value(row[name])} submitted, {_value(values[name])} re-graded"
    got, want = float(row["switch_err_max"]), float(values["switch_err_max"])
    if not _close(got, want, tol):
        return f"switch_err_max {got!r} submitted, {want!r} re-graded (allowed: {tol:.2g})"
    sent = np.asarray(list(row["event_err"]), dtype=float)
    mine = np.asarray(values["event_err"], dtype=float)
    if sent.shape != mine.shape:
        return f"event_err holds {sent.size} events submitted, {mine.size} re-graded"
    bad = [i for i, (a, b) in enumerate(zip(sent, mine)) if not _close(float(a), float(b), tol)]
    if bad:
        i = bad[0]
        return f"event_err[{i}] {sent[i]!r} submitted, {mine[i]!r} re-graded ({len(bad)} events differ)"
    return ""


def _value(v: Any) -> bool | int | None:
    """A count or flag as a plain value (``None`` when missing), whatever dtype it came in."""
    if v is None or pd.isna(v):
        return None
    return bool(v) if isinstance(v, (bool, np.bool_)) else int(v)


def _close(a: float, b: float, tol: float) -> bool:
    if math.isnan(a) or math.isnan(b):
        return math.isnan(a) and math.isnan(b)
    return abs(a - b) <= tol


def dense_points_of(provenance: dict[str, Any]) -> int:
    """The run's suite's ``dense_points`` from its provenance (:data:`DENSE_POINTS` if it has none)."""
    value = (provenance.get("suite") or {}).get("dense_points") if isinstance(provenance, dict) else None
    return (
        int(value) if isinstance(value, int) and not isinstance(value, bool) and 2 <= value <= 10**6 else DENSE_POINTS
    )
