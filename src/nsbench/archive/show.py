"""``nsbench archive show ARCHIVE``: a leaderboard per (problem, target switching-time error).

The leaderboard is the report's fixed-target ranking run on the archive's re-graded rows, one
block per (machine, environment): :func:`nsbench.bench.tables.fixed_target` takes each method's
cheapest configuration that reaches the target (success, the reference's event sequence,
``switch_err_max <= target``; a target below what the reference can certify is not graded),
and :func:`nsbench.bench.tables.ranking` ranks them with the report's ties (the methods whose
timing cannot be told from the fastest's, :func:`nsbench.bench.stats.tied_with`, share its rank,
and so on down in tiers). Each entry carries its median wall time's distribution-free interval
(:func:`nsbench.bench.stats.median_interval`). Reference-grade integrators and each problem's own
reference are not ranked, as in the report. Times of different machines or environments are never
compared: each (machine, environment) is ranked on its own.

The bifurcation targets (:func:`bifurcation_board`) are shown as the report shows them: the
report's table of those rows (:func:`nsbench.bench.targets.report_table`: each configuration's
status, located value, error against the reference's location, probes and cost), one table per
(problem, bifurcation target, machine, environment), in the report's order (integrator, level).
The report does not rank these rows (one location each, no timing samples to tell ties by), so
neither does the archive. They are kept as submitted, not re-graded.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pandas as pd

from nsbench.archive.load import Tables
from nsbench.errors import ConfigError

#: The switching-time error targets of the leaderboard (problem time units).
TARGETS = (1e-4, 1e-8, 1e-12)
#: The columns of :func:`leaderboard`.
COLUMNS = (
    "problem",
    "target",
    "machine",
    "environment",
    "rank",
    "tie",
    "method",
    "options",
    "level",
    "switch_err_max",
    "wall_time",
    "wall_low",
    "wall_high",
    "commit",
    "run_id",
)
NOTE = (
    "Costs are compared only within one machine and environment: each block below ranks the runs of one "
    "(no calibration ratio is applied across machines)."
)
#: Separates a run's id from its case id in the key the ranking sees (a case id has no ':').
_KEY = ":"


def _block(rows: pd.DataFrame, targets: tuple[float, ...]) -> list[dict[str, Any]]:
    """The ranked entries of one (machine, environment): each (problem, target), fastest first."""
    from nsbench.bench.summary import reference_grade, samples_of
    from nsbench.bench.tables import fixed_target, ranking
    from nsbench.status import TargetOutcome

    rows = rows.assign(case_id=rows["run_id"].astype(str) + _KEY + rows["case_id"].astype(str))
    by_key = rows.set_index("case_id", drop=False)
    long = fixed_target(rows, targets)
    reached = long[long["outcome"] == TargetOutcome.REACHED]
    tested = reached[~reached["integrator"].map(reference_grade).astype(bool)]
    samples = {key: samples_of(by_key.loc[key]) for key in tested["case_id"]}
    out = []
    for (problem, target), group in tested.groupby(["problem_label", "target"], sort=True):
        ranks = ranking(group, samples).set_index("integrator")["mean_rank"]
        for _, entry in group.iterrows():
            out.append(_entry(problem, target, entry, by_key.loc[entry["case_id"]], int(ranks[entry["integrator"]])))
    return out


def _entry(problem: str, target: float, entry: pd.Series, row: pd.Series, rank: int) -> dict[str, Any]:
    from nsbench.bench.stats import median_interval
    from nsbench.bench.summary import samples_of

    interval = median_interval(samples_of(row))
    return {
        "problem": problem,
        "target": float(target),
        "machine": str(row["machine"]),
        "environment": str(row["environment"]),
        "rank": rank,
        "method": str(entry["integrator"]),
        "options": str(entry["options"]),
        "level": entry["level"],
        "switch_err_max": float(row["switch_err_max"]),
        "wall_time": float(entry["wall_time"]),
        "wall_low": interval.low,
        "wall_high": interval.high,
        "commit": str(row["commit"]),
        "run_id": str(row["run_id"]),
    }


def leaderboard(tables: Tables, targets: tuple[float, ...] = TARGETS, problem: str | None = None) -> pd.DataFrame:
    """The leaderboard of an archive's tables (:data:`COLUMNS`), one block per (problem, target,
    machine, environment), ranked as the module's docstring says; ``tie`` is true for an entry that
    shares its rank with another of its block. Only the re-graded rows (``graded``) are ranked."""
    runs = tables.runs[["run_id", "machine", "environment", "commit"]]
    rows = tables.rows[tables.rows["graded"].fillna(False).astype(bool)].merge(runs, on="run_id", how="left")
    if problem is not None:
        rows = rows[rows["problem_label"].astype(str) == problem]
    records = []
    for _, block in rows.groupby(["machine", "environment"], sort=True):
        records += _block(block.reset_index(drop=True), targets)
    frame = pd.DataFrame(records, columns=[c for c in COLUMNS if c != "tie"])
    keys = ["problem", "target", "machine", "environment"]
    frame["tie"] = frame.groupby([*keys, "rank"])["method"].transform("size") > 1 if len(frame) else []
    frame = frame[list(COLUMNS)]
    return frame.sort_values(
        [*keys, "rank", "wall_time"],
        ascending=[True, False, True, True, True, True],
        kind="stable",
        ignore_index=True,
    )


#: The columns of :func:`bifurcation_board` before the report's table's own (its ``target`` first among them).
BIF_KEYS = ("problem", "machine", "environment")
BIF_AFTER = ("commit", "run_id")


def bifurcation_board(tables: Tables, problem: str | None = None) -> pd.DataFrame:
    """The archive's bifurcation-target rows as the report's table
    (:func:`nsbench.bench.targets.report_table`), with problem, machine and environment before it and
    commit and run id after, sorted by (problem, target, machine, environment) and, within each,
    in the report's order (integrator, level)."""
    from nsbench.bench.targets import report_table

    runs = tables.runs[["run_id", "machine", "environment", "commit"]]
    rows = tables.bifurcations.merge(runs, on="run_id", how="left")
    if problem is not None:
        rows = rows[rows["problem_label"].astype(str) == problem]
    if rows.empty:
        return pd.DataFrame(columns=[*BIF_KEYS, *BIF_AFTER])
    order = ["problem_label", "target", "machine", "environment", "integrator", "level", "run_id"]
    rows = rows.sort_values(order, kind="stable", ignore_index=True)
    view = report_table(rows)  # the report's columns and formatting, row for row
    front = rows[["problem_label", "machine", "environment"]].rename(columns={"problem_label": "problem"})
    return pd.concat([front, view, rows[list(BIF_AFTER)].astype(str)], axis=1)


def render_bifurcations(board: pd.DataFrame) -> str:
    """The bifurcation-target tables as text, one per (problem, target, machine, environment)."""
    if board.empty:
        return ""
    lines = ["Bifurcation targets (as submitted, not re-graded; listed as the report lists them, not ranked)"]
    lines.append("each row: the bifurcation value the configuration locates with its own flow, and its error")
    for (problem, target, machine, env), block in board.groupby(
        ["problem", "target", "machine", "environment"], sort=False
    ):
        lines += ["", f"{problem}, bifurcation target {target} ({machine}, {env})"]
        lines.append("method                level  status         value            error     probes  cost s    run")
        for _, e in block.iterrows():
            error = f"{e['bifurcation_error']:.3g}" if e["bifurcation_error"] == e["bifurcation_error"] else "-"
            lines.append(
                f"{e['integrator']:<22}{e['level']!s:>5}  {e['status']:<13}  {e['bifurcation_value']:<15}  "
                f"{error:<8}  {e['probes']!s:>6}  {_seconds(float(e['cost (s)'])):<8}  {e['run_id']}"
            )
    return "\n".join(lines)


def _seconds(x: float) -> str:
    return f"{x:.3g}" if math.isfinite(x) else "-"


def render(board: pd.DataFrame) -> str:
    """The leaderboard as text: the note on costs, then one table per block."""
    lines = [NOTE]
    if board.empty:
        return "\n".join([*lines, "", "no graded run of a method under test reaches any target"])
    for (problem, target, machine, env), block in board.groupby(
        ["problem", "target", "machine", "environment"], sort=False
    ):
        lines += ["", f"{problem}, switching-time error <= {target:g} ({machine}, {env})"]
        lines.append("rank  method                level  wall time s [95% interval]        switch err  commit      run")
        for _, e in block.iterrows():
            interval = f"{_seconds(e['wall_time'])} [{_seconds(e['wall_low'])}, {_seconds(e['wall_high'])}]"
            tie = " =" if e["tie"] else ""
            lines.append(
                f"{e['rank']:>4}{tie:<2}{e['method']:<22}{e['level']!s:>5}  {interval:<32}  "
                f"{e['switch_err_max']:<10.2g}  {str(e['commit'])[:10]:<10}  {e['run_id']}"
            )
    if board["tie"].any():
        lines += ["", "= tied: the timings of the entries of one rank cannot be told apart (the report's rule)"]
    return "\n".join(lines)


@dataclass(frozen=True)
class ArchiveShowRequest:
    """What ``archive show`` asks for, checked at its construction (a :class:`~nsbench.errors.ConfigError`
    naming the value before anything is read).

    Attributes
    ----------
    archive
        The archive (a folder of schema ``nsbench-results/1``).
    problem
        Only this problem label, e.g. ``one-dof/1`` (``None``: every problem).
    target
        One switching-time error target, a positive number (``None``: :data:`TARGETS`).
    """

    archive: str
    problem: str | None = None
    target: float | str | None = None

    def __post_init__(self) -> None:
        from nsbench.archive import layout
        from nsbench.inputs import parse_number

        if not str(self.archive).strip():
            raise ConfigError("ARCHIVE expects an archive folder, got ''")
        layout.check_schema(Path(self.archive))
        if self.problem is not None and not str(self.problem).strip():
            raise ConfigError("--problem expects a problem label such as one-dof/1, got ''")
        if self.target is not None:
            value = parse_number(str(self.target), "--target")
            if not (math.isfinite(value) and value > 0):
                raise ConfigError(f"--target = {self.target!r}: give a positive, finite switching-time error")
            object.__setattr__(self, "target", value)

    @property
    def targets(self) -> tuple[float, ...]:
        return TARGETS if self.target is None else (float(self.target),)


@dataclass(frozen=True)
class ArchiveShowOutcome:
    """The leaderboard printed, and the bifurcation-target tables."""

    board: pd.DataFrame
    bifurcations: pd.DataFrame | None = None
    exit_code: int = 0


def show_archive(request: ArchiveShowRequest) -> ArchiveShowOutcome:
    """Print the archive's runs and its leaderboard (every file checked on read: ``ConfigError`` if damaged)."""
    from nsbench.archive.load import load

    tables = load(request.archive, events=False)  # the leaderboard reads only the rows
    labels = set(tables.rows["problem_label"].astype(str)) | set(tables.bifurcations["problem_label"].astype(str))
    if request.problem is not None and request.problem not in labels:
        known = ", ".join(sorted(labels)) or "none"
        raise ConfigError(f"--problem {request.problem!r} is in no run of {request.archive!r} (it holds: {known})")
    print(f"{len(tables.runs)} run(s) in {request.archive}:")
    for run in tables.runs.itertuples():
        marks = f"; marked: {run.marks}" if run.marks else ""
        print(
            f"  {run.run_id}  {run.machine}  {run.environment}  commit {str(run.commit)[:10]}  {run.n_rows} rows{marks}"
        )
    board = leaderboard(tables, request.targets, request.problem)
    print()
    print(render(board))
    bifurcations = bifurcation_board(tables, request.problem)
    if len(bifurcations):
        print()
        print(render_bifurcations(bifurcations))
    return ArchiveShowOutcome(board, bifurcations)
