"""Every column of a result row, declared once: its name, type, unit, meaning and report tables.

The rest of the bench reads these declarations rather than keeping lists of its own:
:mod:`nsbench.bench.schema` (the column order and meanings), :mod:`nsbench.bench.storage`
(the dtype each column is stored and loaded as), :mod:`nsbench.bench.report` (which columns
each report table shows, in declaration order) and the column reference of ``docs/bench.md``
(:func:`reference_table`, checked against the page by ``tests/bench/test_columns.py``). A new
metric column is one :class:`Column` here, plus the code that computes it; a column computed
from others of its row (:attr:`Column.derive`) needs nothing else, since storage computes it
whenever a frame is built (so results stored before it existed get it on load).

This module is a leaf: it imports nothing of the bench, so every layer above may read it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable, Literal

import numpy as np
import pandas as pd

from nsbench.status import Status

#: How a column is stored: whole numbers (nullable), floats (NaN when missing), booleans
#: (nullable), text, JSON text, or a list of floats.
Dtype = Literal["int", "float", "bool", "text", "json", "list"]
INT: Dtype = "int"
FLOAT: Dtype = "float"
BOOL: Dtype = "bool"
TEXT: Dtype = "text"
JSON: Dtype = "json"
LIST: Dtype = "list"
DTYPES: tuple[Dtype, ...] = (INT, FLOAT, BOOL, TEXT, JSON, LIST)

#: The report's tables of result rows (:func:`nsbench.bench.report.write_report`): every case;
#: the cases that did not succeed; the errors defined only for some problems (impacts, friction).
CASES = "cases"
FAILURES = "failures"
PROBLEM_ERRORS = "problem errors"
TABLES = (CASES, FAILURES, PROBLEM_ERRORS)


@dataclass(frozen=True)
class Column:
    """One column of a result row.

    Attributes
    ----------
    name
        The column's name in every stored file and frame.
    dtype
        How it is stored (:data:`DTYPES`).
    meaning
        What it holds, one paragraph (the docs' column reference shows it).
    unit
        Its unit: ``s`` (wall-clock seconds), ``problem time`` (and length, state, energy:
        the problem's own units), ``count``, ``1`` (a ratio); empty for text and labels.
    tables
        The report tables that show it (:data:`TABLES`).
    derive
        For a column computed from the other columns of its row: the function that computes
        it from a frame already holding them. Storage recomputes it whenever it builds a
        frame, so it cannot disagree with its inputs and an older results folder gets it too.
    """

    name: str
    dtype: Dtype
    meaning: str
    unit: str = ""
    tables: tuple[str, ...] = ()
    derive: Callable[[pd.DataFrame], pd.Series] | None = None

    def __post_init__(self) -> None:
        # a typo here would silently drop a column from storage or a report table: refuse it
        if self.dtype not in DTYPES:
            raise ValueError(f"column {self.name!r}: dtype {self.dtype!r} is not one of {', '.join(DTYPES)}")
        unknown = [t for t in self.tables if t not in TABLES]
        if unknown:
            raise ValueError(f"column {self.name!r}: table {unknown[0]!r} is not one of {', '.join(TABLES)}")


def _numbers(frame: pd.DataFrame, name: str) -> pd.Series:
    """Column ``name`` of ``frame`` as floats (NaN where missing or not a number)."""
    if name not in frame:
        return pd.Series(math.nan, index=frame.index, dtype="float64")
    return pd.to_numeric(frame[name], errors="coerce").astype("float64")


def engine_share(frame: pd.DataFrame) -> pd.Series:
    """``1 - integrator_time / wall_time``, at least 0: the part of a run's wall time spent in
    nsbench's hybrid core (events, records, callbacks) rather than in the integrator; NaN where
    either time is missing or the wall time is not positive."""
    wall, inner = _numbers(frame, "wall_time"), _numbers(frame, "integrator_time")
    return (1.0 - inner / wall).where(wall > 0).clip(lower=0.0)


def efficiency(frame: pd.DataFrame) -> pd.Series:
    """``1 / (switch_err_max x wall_time)``: the efficiency of DiffEqDevTools' work-precision shoot-outs.

    The error is the one the report's work-precision figures plot, the largest switching-time
    error over the matched prefix (``switch_err_max``, floored at the reference's certified
    error), and the time their wall-time axis plots (``wall_time``, the median warm run).
    NaN where either is missing, zero, negative or not finite, where the case did not succeed
    (the error of a partial run's prefix is no point of a work-precision curve) and where its
    event sequence is not the reference's (such a run never reaches a target either: the error
    of its prefix is not the run's error).
    """
    err, wall = _numbers(frame, "switch_err_max"), _numbers(frame, "wall_time")
    status = frame["status"].astype(object) if "status" in frame else pd.Series("", index=frame.index)
    sequence = frame["sequence_ok"].astype(object) if "sequence_ok" in frame else pd.Series(None, index=frame.index)
    usable = (
        (status == Status.SUCCESS.value)
        & (sequence == True)  # noqa: E712 - a missing (NA) flag is not True
        & np.isfinite(err)
        & np.isfinite(wall)
        & (err > 0)
        & (wall > 0)
    )
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        value = 1.0 / (err * wall)
    return value.where(usable & np.isfinite(value)).astype("float64")


#: Every column of a result row, in the stored order.
DECLARED: tuple[Column, ...] = (
    Column(
        "case_id",
        TEXT,
        "stable id of (problem, integrator config, span, dense grid, step budget)",
    ),
    Column(
        "suite",
        TEXT,
        "suite name",
    ),
    Column(
        "problem",
        TEXT,
        "registered problem name",
    ),
    Column(
        "case",
        INT,
        "problem preset 1..4",
    ),
    Column(
        "problem_label",
        TEXT,
        "readable problem label, e.g. 'two-dof/2' or 'two-dof/2 v0=0.1'",
        tables=(
            CASES,
            FAILURES,
            PROBLEM_ERRORS,
        ),
    ),
    Column(
        "problem_config",
        JSON,
        "JSON: the dict that rebuilds the problem (nsbench.problem_from_config)",
    ),
    Column(
        "integrator",
        TEXT,
        "registered integrator name",
        tables=(
            CASES,
            FAILURES,
            PROBLEM_ERRORS,
        ),
    ),
    Column(
        "family",
        TEXT,
        (
            "the integrator's family of methods (Capabilities.family): event-driven, time-stepping, switch-model, "
            "smoothing"
        ),
    ),
    Column(
        "integrator_config",
        JSON,
        "JSON: the dict that rebuilds the integrator (nsbench.integrator_from_config)",
    ),
    Column(
        "options",
        JSON,
        "JSON: the options the suite set (the rest are defaults)",
        tables=(
            CASES,
            FAILURES,
            PROBLEM_ERRORS,
        ),
    ),
    Column(
        "level",
        INT,
        "index of the option set, loose to tight",
    ),
    Column(
        "step_option",
        TEXT,
        "name of the integrator's step/tolerance option (capabilities.step_option)",
    ),
    Column(
        "step_value",
        FLOAT,
        "value of that option in this case",
    ),
    Column(
        "t0",
        FLOAT,
        "start of the time span",
        unit="problem time",
    ),
    Column(
        "t_end",
        FLOAT,
        "end of the time span",
        unit="problem time",
    ),
    Column(
        "status",
        TEXT,
        "how the case ended",
        tables=(
            CASES,
            FAILURES,
        ),
    ),
    Column(
        "message",
        TEXT,
        "why, when not success",
        tables=(FAILURES,),
    ),
    Column(
        "loop",
        TEXT,
        (
            "who ran the event loop (SimulationResult.loop): native (the integrator's own), per-arc (the core's, "
            "one advance per arc), kernel (the core's, a compiled arc kernel), whole-system"
        ),
    ),
    Column(
        "t_final",
        FLOAT,
        "where the run stopped",
        unit="problem time",
    ),
    Column(
        "nfev",
        INT,
        (
            "evaluations of the method's model: right-hand sides (one per state) for the event-driven, switch- "
            "model and smoothing methods; one-step problems (a stick/slip status solved and tested against the "
            "friction law) for moreau-jean; 0 where the method counts none (siconos), shown n/a in the tables"
        ),
        unit="count",
        tables=(CASES,),
    ),
    Column(
        "njev",
        INT,
        "Jacobian evaluations",
        unit="count",
    ),
    Column(
        "nsteps",
        INT,
        "steps or segments",
        unit="count",
    ),
    Column(
        "n_events",
        INT,
        "events logged by the run",
        unit="count",
        tables=(CASES,),
    ),
    Column(
        "counters_extra",
        JSON,
        "JSON: integrator-specific counters",
    ),
    Column(
        "wall_time",
        FLOAT,
        "seconds per run: median of the timed samples (all warm: after an untimed warm-up)",
        unit="s",
        tables=(CASES,),
    ),
    Column(
        "wall_time_min",
        FLOAT,
        "fastest timed sample (seconds per run)",
        unit="s",
    ),
    Column(
        "wall_time_max",
        FLOAT,
        "slowest timed sample (seconds per run)",
        unit="s",
    ),
    Column(
        "wall_spread",
        FLOAT,
        "relative spread of the timed samples, (max - min) / median; NaN with one sample",
        unit="1",
        tables=(CASES,),
    ),
    Column(
        "wall_times",
        LIST,
        (
            "list: seconds per run of every timed sample, in order (a sample is the mean of its `loops` runs; the "
            "warm-up and the calibration run are not among them)"
        ),
        unit="s",
    ),
    Column(
        "n_repeats",
        INT,
        ("number of timed samples: the suite's repeats (at least 3; 5 by default) if successful, 1 if the run failed"),
        unit="count",
        tables=(CASES,),
    ),
    Column(
        "loops",
        INT,
        (
            "runs per timed sample: 1 for a run of at least the suite's min_sample_time, else the first of 1, 2, "
            "5, 10, 20, ... whose runs last that long (from the calibration run)"
        ),
        unit="count",
        tables=(CASES,),
    ),
    Column(
        "integrator_time",
        FLOAT,
        (
            "seconds inside the integrator (engine's own clock) per run: median over the timed samples; NaN if "
            "the engine does not report it"
        ),
        unit="s",
        tables=(CASES,),
    ),
    Column(
        "integrator_times",
        LIST,
        "list: integrator_time per run of every timed sample",
        unit="s",
    ),
    Column(
        "engine_share",
        FLOAT,
        "1 - integrator_time / wall_time (at least 0): the part of a run's wall time spent in nsbench's "
        "hybrid core (events, records, callbacks) rather than in the integrator; NaN where either is missing",
        unit="1",
        tables=(CASES,),
        derive=engine_share,
    ),
    Column(
        "cpu_time",
        FLOAT,
        (
            "CPU seconds of the worker process per run, over the same stretch as wall_time: median over the timed "
            "samples (the work done, without the time other programs held the core)"
        ),
        unit="s",
    ),
    Column(
        "cpu_times",
        LIST,
        "list: cpu_time per run of every timed sample",
        unit="s",
    ),
    Column(
        "setup_time",
        FLOAT,
        (
            "seconds in the integrator's setup in this case's warm-up: compilation and operators for the first "
            "case of an integrator in a worker, a cache load for the others (the report charges the integrator "
            "its largest, nsbench.bench.timing.setup_table)"
        ),
        unit="s",
    ),
    Column(
        "setup_time_timed",
        FLOAT,
        (
            "longest setup among the timed runs: near 0 when warm; a large value means compilation happened while "
            "timing (setup is never part of wall_time)"
        ),
        unit="s",
    ),
    Column(
        "warmup_time",
        FLOAT,
        "seconds of the untimed warm-up run (the first tenth of the span, cold)",
        unit="s",
    ),
    Column(
        "reference",
        TEXT,
        "name of the reference integrator, empty if none",
    ),
    Column(
        "reference_config",
        JSON,
        "JSON: its config",
    ),
    Column(
        "reference_status",
        TEXT,
        "'ok', or why there is no usable reference",
    ),
    Column(
        "ref_conditioning",
        FLOAT,
        (
            "max switching-time change per unit change of the start positions, measured by the reference from a "
            "start moved by 1e-9; inf where that changes the event sequence"
        ),
        unit="problem time / problem length",
    ),
    Column(
        "ref_double_floor",
        FLOAT,
        (
            "ref_conditioning x 2.2e-16: the switching-time uncertainty of any double-precision solution from the "
            "rounding of its start; above 1e-10 the case cannot be graded in double"
        ),
        unit="problem time",
    ),
    Column(
        "ref_certainty",
        FLOAT,
        (
            "largest certified error bound of the reference's event times (an independent check at higher "
            "precision, nsbench.bench.reference.certified_errors); inf where the check's event sequence differs, "
            "NaN if not certified"
        ),
        unit="problem time",
    ),
    Column(
        "n_ref",
        INT,
        "events in the reference",
        unit="count",
    ),
    Column(
        "n_prefix",
        INT,
        "events paired one to one from the first, up to the first missed or extra event",
        unit="count",
    ),
    Column(
        "n_matched",
        INT,
        (
            "events paired by the best alignment on (kind, block) and time: fewest unmatched events, then the "
            "smallest total time difference of its pairs (nsbench.bench.metrics.align)"
        ),
        unit="count",
    ),
    Column(
        "n_missed",
        INT,
        "reference events the run does not have",
        unit="count",
        tables=(CASES,),
    ),
    Column(
        "n_extra",
        INT,
        "events of the run the reference does not have",
        unit="count",
        tables=(CASES,),
    ),
    Column(
        "first_divergence_index",
        INT,
        "index of the first missed or extra event (n_prefix), -1 if the sequences are identical",
    ),
    Column(
        "first_divergence_time",
        FLOAT,
        "time of that event (the reference's if missed, the run's if extra), NaN if identical",
        unit="problem time",
    ),
    Column(
        "sequence_ok",
        BOOL,
        "the (kind, block) sequences are identical",
    ),
    Column(
        "switch_err_max",
        FLOAT,
        (
            "max |t - t_ref| over the matched prefix, each event's error floored at the reference's certified "
            "error there (never reported below what the reference can certify)"
        ),
        unit="problem time",
        tables=(CASES,),
    ),
    Column(
        "switch_err_rms",
        FLOAT,
        "RMS of the same floored errors",
        unit="problem time",
    ),
    Column(
        "switch_err_median",
        FLOAT,
        "median of the same floored errors",
        unit="problem time",
    ),
    Column(
        "switch_digits",
        FLOAT,
        "significant correct digits of the worst switching time, -log10 max |dt|/|t_ref|",
        unit="digits",
        tables=(CASES,),
    ),
    Column(
        "efficiency",
        FLOAT,
        "1 / (switch_err_max x wall_time), the efficiency of DiffEqDevTools' work-precision shoot-outs "
        "(larger is better), from the error and time the report's work-precision figures plot; NaN unless "
        "the case succeeded with the reference's event sequence and both are positive and finite "
        "(nsbench.bench.columns.efficiency)",
        unit="1 / (problem time x s)",
        tables=(CASES,),
        derive=efficiency,
    ),
    Column(
        "at_ref_accuracy",
        BOOL,
        (
            "every |t - t_ref| of the matched prefix is within the reference's certified error there: the run's "
            "error is not measurable against this reference"
        ),
    ),
    Column(
        "final_state_err",
        FLOAT,
        "max-norm of the state error at t_end (NaN unless success)",
        unit="problem state",
    ),
    Column(
        "state_err_l2",
        FLOAT,
        "RMS over the dense points of the Euclidean state error (NaN unless success)",
        unit="problem state",
        tables=(CASES,),
    ),
    Column(
        "stick_creep",
        FLOAT,
        (
            "drift velocity off the belt per unit of stick time under an in-cone load: sum |d(x_i - v_belt t)| "
            "over consecutive dense points inside the reference's stick intervals of block i (those begun in the "
            "matched prefix) where the load, by the reference's state and by the run's own, is within the kinetic "
            "level (|R_i| <= fs_i), divided by the time they span, pooled over blocks; NaN if no two such points "
            "(nsbench.bench.metrics.stick_creep)"
        ),
        unit="problem length / problem time",
    ),
    Column(
        "stick_drift",
        FLOAT,
        (
            "largest position drift relative to the belt within those windows, |x_i(t) - x_i(t_a) - v_belt (t - "
            "t_a)| from a window's first dense point t_a"
        ),
        unit="problem length",
    ),
    Column(
        "breakaway_err_max",
        FLOAT,
        "max |t - t_ref| over the break-away (slip) events of the matched prefix; NaN if none",
        unit="problem time",
        tables=(PROBLEM_ERRORS,),
    ),
    Column(
        "located_err_max",
        FLOAT,
        (
            "max |t_located - t_ref| over the matched prefix: the switch times a whole-system method located "
            "itself (SystemResult.switch_times), beside the inferred ones of switch_err_max; NaN if it locates "
            "none"
        ),
        unit="problem time",
    ),
    Column(
        "n_located",
        INT,
        (
            "how many events of the matched prefix the method located itself (a finite t_located), of "
            "n_prefix: FESD places its switches on finite-element boundaries and locates some, not all; "
            "empty for a method that locates none of its own"
        ),
        unit="count",
    ),
    Column(
        "arc_err",
        FLOAT,
        (
            "max-norm state error of a separate run on a smooth arc: started on the reference's dense state a "
            "quarter into its longest slipping arc, stopped a quarter before the arc's end, so no switch is "
            "stepped over (nsbench.bench.families.smooth_arc_error); NaN without such an arc, or if that run "
            "fails or switches"
        ),
        unit="problem state",
    ),
    Column(
        "penetration",
        FLOAT,
        ("impact problems: the largest depth below the ground at the dense points, max(0, -x); NaN for other problems"),
        unit="problem length",
        tables=(PROBLEM_ERRORS,),
    ),
    Column(
        "energy_err",
        FLOAT,
        (
            "impact problems: |E(t_end) - E_ref(t_end)|, the energy left at the end against the reference's; NaN "
            "for other problems"
        ),
        unit="problem energy",
        tables=(PROBLEM_ERRORS,),
    ),
    Column(
        "event_t",
        LIST,
        "list: reference times of the matched prefix",
        unit="problem time",
    ),
    Column(
        "event_err",
        LIST,
        "list: signed switching-time errors t - t_ref of the matched prefix (as measured, not floored)",
        unit="problem time",
    ),
    Column(
        "event_cert",
        LIST,
        (
            "list: the reference's certified error bound at each event of the matched prefix (empty if the "
            "reference is not certified)"
        ),
        unit="problem time",
    ),
    Column(
        "event_log",
        JSON,
        (
            "JSON: the run's own event log as graded, {column: [values]} with t, kind, block (and t_located, "
            "accumulation_error where the run has them); empty if the case did not run. An archive re-grades "
            "the switching-time errors from it (nsbench archive add)"
        ),
    ),
    Column(
        "dense_states",
        JSON,
        (
            "JSON: the run's own states on the suite's dense grid (numpy.linspace(t0, t_end, dense_points)) and "
            "its final state, the states the state errors and the stick creep were computed from: "
            '{"encoding": "float64-le-base64", "n_states", "n_points", "dense", "final"}, each array\'s '
            "little-endian doubles, row-major, in base64 (nsbench.bench.metrics.dense_states_text); empty where "
            "the run has none (the case did not succeed). An archive re-grades the state errors from it"
        ),
    ),
    Column(
        "timestamp",
        TEXT,
        "UTC time the case finished",
    ),
)

#: The declarations by name.
BY_NAME: dict[str, Column] = {c.name: c for c in DECLARED}
#: Every column name, in the stored order.
NAMES: tuple[str, ...] = tuple(BY_NAME)
if len(NAMES) != len(DECLARED):  # a second declaration of a name would shadow the first
    raise ValueError("a column is declared twice")


def of_dtype(dtype: Dtype) -> tuple[str, ...]:
    """The names of the columns stored as ``dtype``, in the stored order."""
    if dtype not in DTYPES:
        raise ValueError(f"dtype {dtype!r} is not one of {', '.join(DTYPES)}")
    return tuple(c.name for c in DECLARED if c.dtype == dtype)


def in_table(table: str) -> tuple[str, ...]:
    """The names of the columns report table ``table`` shows (:data:`TABLES`), in the stored order."""
    if table not in TABLES:
        raise ValueError(f"table {table!r} is not one of {', '.join(TABLES)}")
    return tuple(c.name for c in DECLARED if table in c.tables)


def derived() -> tuple[Column, ...]:
    """The columns computed from the others of their row (:attr:`Column.derive`)."""
    return tuple(c for c in DECLARED if c.derive is not None)


#: The lines around the generated column reference in ``docs/bench.md``.
DOCS_BEGIN = "<!-- columns: generated by nsbench.bench.columns.reference_table, do not edit -->"
DOCS_END = "<!-- columns: end -->"


def _cell(text: str) -> str:
    # a '|' inside a cell (|t - t_ref|) would end the cell in a Markdown table
    return text.replace("|", "\\|")


def reference_table() -> str:
    """The column reference as a Markdown table: column, type, unit, report tables, meaning."""
    rows = ["| column | type | unit | in report tables | meaning |", "|---|---|---|---|---|"]
    rows += [
        f"| `{c.name}` | {c.dtype} | {_cell(c.unit)} | {', '.join(c.tables)} | "
        f"{_cell(c.meaning)}{' (computed from its row)' if c.derive else ''} |"
        for c in DECLARED
    ]
    return "\n".join(rows)


def with_reference(page: str) -> str:
    """``page`` (the text of ``docs/bench.md``) with the generated table between its markers.

    Raises ``ValueError`` if the page lacks the markers.
    """
    start, end = page.find(DOCS_BEGIN), page.find(DOCS_END)
    if start < 0 or end < start:
        raise ValueError(f"the page has no {DOCS_BEGIN!r} ... {DOCS_END!r} block")
    return page[: start + len(DOCS_BEGIN)] + "\n\n" + reference_table() + "\n\n" + page[end:]


if __name__ == "__main__":  # python -m nsbench.bench.columns docs/bench.md: rewrite the page's column reference
    import sys
    from pathlib import Path

    for arg in sys.argv[1:]:
        path = Path(arg)
        path.write_text(with_reference(path.read_text()))
