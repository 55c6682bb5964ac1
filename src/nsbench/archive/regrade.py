"""Re-grading a submitted run against the archive's own references.

Each row's switching-time errors are computed again from the event log its results folder
keeps (the ``event_log`` column, :func:`nsbench.bench.metrics.event_log_text`) against a
certified reference the archive computes itself (:func:`nsbench.bench.reference.compute_reference`,
cached under ``ARCHIVE/references/`` in the bench's checksummed format), with the bench's own
grading (:func:`nsbench.bench.metrics.case_metrics`). The state errors (:data:`STATE_REGRADED`)
are computed again the same way from the run's own dense states (the ``dense_states`` column,
:func:`nsbench.bench.metrics.dense_states_text`) against the same reference's dense states; a run
made before nsbench kept them has its state errors kept as submitted and marked (:class:`Graded`).
The submitted error columns are only compared with the result, never used.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
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
#: another grid. The run's dense states (``dense_states``) are on that grid, so the state errors are
#: compared point by point, as the bench compared them.
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
#: The state columns re-graded from the run's dense states (``dense_states``), when it keeps them, with
#: the bench's own grading: :func:`nsbench.bench.metrics.state_errors` and
#: :func:`nsbench.bench.metrics.stick_creep` (``stick_drift`` is the creep's companion, one call).
#: ``penetration`` and ``energy_err`` (impact problems) and ``arc_err`` (a separate run) are kept as
#: submitted.
STATE_REGRADED = ("final_state_err", "state_err_l2", "stick_creep", "stick_drift")


@dataclass(frozen=True)
class Graded:
    """One row re-graded: the re-graded columns, its events, and why it was not (``mark``)."""

    values: dict[str, Any]
    events: pd.DataFrame
    mark: str = ""
    #: Graded, but with something this nsbench does not know (an integrator plug-in not installed here).
    note: str = ""
    #: The state columns (:data:`STATE_REGRADED`) were re-graded too; if not (``states_note`` says why)
    #: they are kept as submitted.
    states: bool = False
    states_note: str = ""
    #: The agreement allowed for each re-graded state column (:func:`state_allowances`).
    allowed: dict[str, float] = field(default_factory=dict)

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
    states, why = run_states(row, problem, ref)
    values, table = _grade(ref, events, states)
    # an unknown integrator plug-in: graded all the same (the grading needs no integrator), and marked
    if why:
        return Graded(values, table, note="; ".join(noted), states_note=why)
    allowed = state_allowances(ref, values, None if states is None else states.dense)
    return Graded(values, table, note="; ".join(noted), states=True, allowed=allowed)


@dataclass(frozen=True)
class States:
    """What the bench computed a row's state errors from: the problem, the run's dense states and final state."""

    problem: Any
    dense: np.ndarray
    final: np.ndarray
    t_end: float


#: The mark of a row whose state errors are kept as submitted because its run keeps no dense states.
NO_STATES = (
    "state errors as submitted, not re-graded: the run keeps no dense states (made by an nsbench before the "
    "dense_states column, or the column was emptied)"
)


def run_states(row: pd.Series, problem: dict[str, Any], ref: Reference) -> tuple[States | None, str]:
    """The row's dense states to grade (``None``: none, the bench's state errors are then NaN), and why its
    state errors cannot be re-graded ('' if they can).

    A row that did not succeed has none (the bench grades no state of a failed run: its state errors
    are NaN, and so are the archive's). A successful row without them was made by an nsbench that did
    not keep them (or they were stripped): its state errors are kept as submitted, and marked.
    """
    from nsbench.problems import problem_from_config
    from nsbench.status import Status

    text = "" if pd.isna(row.get("dense_states")) else str(row.get("dense_states") or "")
    if not text:
        return None, (NO_STATES if str(row["status"]) == Status.SUCCESS.value else "")
    try:
        dense, final = metrics.dense_states_arrays(text)
    except (ValueError, TypeError) as exc:
        return None, f"state errors as submitted, not re-graded: its dense_states is damaged ({exc})"
    if dense.shape != ref.y_dense.shape:
        return None, (
            f"state errors as submitted, not re-graded: its dense states are {dense.shape[0]} x {dense.shape[1]}, "
            f"the archive's reference's {ref.y_dense.shape[0]} x {ref.y_dense.shape[1]} (another grid)"
        )
    try:
        built = problem_from_config(problem)
    except NsbenchError as exc:
        return None, f"state errors as submitted, not re-graded: its problem cannot be built here ({exc})"
    return States(built, dense, final, float(row["t_end"])), ""


def _grade(ref: Reference, events: pd.DataFrame, states: States | None) -> tuple[dict[str, Any], pd.DataFrame]:
    from nsbench.engine import match_accumulation_tails

    if states is None:
        out = metrics.case_metrics(ref.events, events, None, None, None, None)
    else:  # the bench's own call (nsbench.bench.execute.time_case), on the run's stored states
        problem = states.problem
        belt = problem.v0 if problem.traits.belt_blocks else None  # the stick creep needs a belt
        cone = metrics.creep_cone(problem, ref.t_dense, ref.y_dense, states.dense) if belt is not None else None
        out = metrics.case_metrics(
            ref.events,
            events,
            ref.y_dense,
            states.dense,
            ref.y_final,
            states.final,
            times=ref.t_dense,
            v_belt=belt,
            t_end=states.t_end,
            cone=cone,
        )
    values = {name: out[name] for name in (*REGRADED, *STATE_REGRADED) if name in out}
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


#: Ulps of the states a reference computed on another machine may differ by (as :data:`ULPS` of the times).
STATE_ULPS = ULPS


def state_allowances(ref: Reference, values: dict[str, Any], dense: np.ndarray | None) -> dict[str, float]:
    """The agreement allowed between each submitted state column and the re-graded one.

    On one machine the two gradings are the same computation on the same states and agree bit for
    bit. A reference computed on another machine may differ by a few ulps of the states
    (:data:`STATE_ULPS` ulps of ``S``, the largest magnitude of its dense and final states: an ulp
    of one component, carried along the flow, reaches the others), and another numpy may sum in
    another order. With ``eps`` the machine epsilon, ``n`` states and ``m`` dense points:

    - ``final_state_err``, a maximum over states of ``|y_i - r_i|``, moves by at most the change of
      one ``r_i`` plus the rounding of the subtraction: ``STATE_ULPS eps S + eps |value|``;
    - ``state_err_l2``, ``sqrt(mean_j sum_i d_ij**2)``, is a norm, so it moves by at most the same
      norm of the reference's change, ``sqrt(n) STATE_ULPS eps S``, plus the rounding of a sum of
      ``n m`` squares in any order (relative ``(n m - 1) eps``): ``... + n m eps |value|``;
    - ``stick_creep`` and ``stick_drift`` are computed from the run's own states alone; the
      reference only decides which dense points count (a discrete choice a few ulps change only at
      a point within ulps of a switch or of the cone's edge: then the honest submission disagrees
      and is refused, naming the row). Their elementwise arithmetic is correctly rounded on every
      IEEE machine (the grid too: ``numpy.linspace`` is ``start + k * step`` elementwise, each
      operation rounded once, in every numpy 2); what may differ is the order of the two sums of
      at most ``m`` non-negative terms whose ratio the creep is: ``2 m eps |value|`` (the drift, a
      maximum, has no sum: the same allowance is generous for it).

    The allowance only decides whether a submission is refused: the archive keeps its own values.
    """
    eps = float(np.finfo(float).eps)
    states = np.concatenate([np.ravel(ref.y_dense), np.ravel(ref.y_final)])
    finite = np.abs(states[np.isfinite(states)])
    scale = float(finite.max()) if finite.size else 0.0
    n, m = (dense.shape[0], dense.shape[1]) if dense is not None else (0, 0)

    def size(name: str) -> float:
        v = float(values.get(name, math.nan))
        return abs(v) if math.isfinite(v) else 0.0

    return {
        "final_state_err": STATE_ULPS * eps * scale + eps * size("final_state_err"),
        "state_err_l2": math.sqrt(n) * STATE_ULPS * eps * scale + n * m * eps * size("state_err_l2"),
        "stick_creep": 2 * m * eps * size("stick_creep"),
        "stick_drift": 2 * m * eps * size("stick_drift"),
    }


def disagreement(row: pd.Series, values: dict[str, Any], allowed: dict[str, float] | None = None) -> str:
    """How the submitted row's errors differ from the re-graded ``values`` ('' if they agree); with
    ``allowed`` (:func:`state_allowances`: the state columns were re-graded) its state errors too.

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
    if allowed is None:  # the state columns were not re-graded: nothing of theirs to compare
        return ""
    for name in STATE_REGRADED:
        got, want = float(row[name]), float(values[name])
        if not _close(got, want, allowed[name]):
            return f"{name} {got!r} submitted, {want!r} re-graded (allowed: {allowed[name]:.2g})"
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
