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

The bifurcation targets (:func:`bifurcation_board`) have a leaderboard of their own, one block per
(problem, bifurcation target, machine, environment), each row the report's table of that row
(:func:`nsbench.bench.targets.report_table`: status, located value, error against the reference's
location, probes, cost). As on the switching-time leaderboard, each method has one entry per block:
its cheapest configuration that located the bifurcation within its ``xtol`` of the reference's
location, over every run of the block (``per="configuration"``: every configuration of every run, as
``show --every-configuration`` prints them). The entries are ranked by their cost, the integrator's own
time summed over the probes (``integrator_time``, the report's ``cost (s)``), with the same ranking
code as above (:func:`nsbench.bench.tables.ranking`). That table records one cost per configuration and
no timing samples, so no interval: the ranking is the one ``ranking`` gives without samples, entries
sharing a rank only when their costs are equal. A method none of whose configurations located it is
listed after, unranked, with its closest configuration and the reason. These rows are kept as
submitted, not re-graded.
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
    long = fixed_target(rows, targets)
    reached = long[long["outcome"] == TargetOutcome.REACHED]
    tested = reached[~reached["integrator"].map(reference_grade).astype(bool)]
    # each tested row's cells an entry shows, by its key (one row a key: a run's case ids are distinct),
    # as plain values: a frame's .loc per entry cost seconds in an archive of thousands of runs
    wanted = rows[rows["case_id"].isin(set(tested["case_id"]))]
    cells = ["case_id", "wall_times", "wall_time", "machine", "environment", "switch_err_max", "commit", "run_id"]
    by_key = {r["case_id"]: r for r in wanted[cells].to_dict("records")}
    samples = {key: samples_of(by_key[key]) for key in tested["case_id"]}
    out = []
    for (problem, target), group in tested.groupby(["problem_label", "target"], sort=True):
        ranks = ranking(group, samples).set_index("integrator")["mean_rank"]
        for entry in group[["case_id", "integrator", "options", "level", "wall_time"]].to_dict("records"):
            out.append(_entry(problem, target, entry, by_key[entry["case_id"]], int(ranks[entry["integrator"]])))
    return out


def _entry(problem: str, target: float, entry: dict[str, Any], row: dict[str, Any], rank: int) -> dict[str, Any]:
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


def ties(frame: pd.DataFrame, keys: list[str]) -> pd.Series:
    """True for an entry that shares its ``rank`` with another of its block (``keys``); false for an
    unranked one (``rank`` missing)."""
    if frame.empty:
        return pd.Series([], dtype=bool, index=frame.index)
    size = frame.groupby([*keys, "rank"], dropna=True)["rank"].transform("size")
    return (size.fillna(0) > 1).astype(bool)


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
    frame["tie"] = ties(frame, keys)
    frame = frame[list(COLUMNS)]
    return frame.sort_values(
        [*keys, "rank", "wall_time"],
        ascending=[True, False, True, True, True, True],
        kind="stable",
        ignore_index=True,
    )


#: The columns of :func:`bifurcation_board` before the report's table's own, and after them.
BIF_KEYS = ("problem", "machine", "environment", "rank", "tie")
BIF_AFTER = ("xtol", "reason", "located", "configurations", "commit", "run_id")
#: The two forms of :func:`bifurcation_board`: one entry per method and block, or every configuration.
BIF_PER = ("method", "configuration")
#: What the bifurcation-target leaderboard ranks by, and why without an interval.
BIF_RANKING = (
    "Each method's cheapest configuration that located the bifurcation within its xtol of the reference's location "
    "(located/of: how many of its configurations in the block did), ranked by cost: the integrator's own time "
    "summed over the probes (cost (s), as the report's table records it), within one machine and environment. The "
    "bifurcation-target table records one cost per configuration and no timing samples, so no interval: entries "
    "share a rank (=) only when their costs are equal. A method none of whose configurations located it is listed "
    "after, unranked, with its closest configuration and the reason."
)
#: The same for ``per="configuration"``: every configuration an entry.
BIF_RANKING_EVERY = (
    "Every configuration of every run, ranked by cost: the integrator's own time summed over the probes (cost (s)), "
    "within one machine and environment; no interval (one cost per configuration): entries share a rank (=) only "
    "when their costs are equal. The configurations that did not locate the bifurcation within its xtol of the "
    "reference's location are listed after, unranked, with the reason."
)


def not_located(row: pd.Series | dict[str, Any]) -> str:
    """Why a bifurcation-target row is not ranked ('' if it located the bifurcation within its ``xtol``
    of the reference's location and records a cost)."""
    from nsbench.status import ReferenceStatus, Status

    if str(row["status"]) != Status.SUCCESS.value:
        message = "" if pd.isna(row["message"]) else str(row["message"])
        return f"{row['status']}: {message}" if message else str(row["status"])
    if ReferenceStatus.of(str(row["reference_status"])) is not ReferenceStatus.OK:
        return f"no reference location ({row['reference_status']})"
    error, xtol = float(row["bifurcation_error"]), float(row["xtol"])
    if not math.isfinite(error):
        return "no error against the reference's location"
    if not error <= xtol:
        return f"located {error:.3g} from the reference's location, beyond its xtol {xtol:g}"
    cost = float(row["integrator_time"])
    if not (math.isfinite(cost) and cost > 0):
        return "located, but no cost recorded (the integrator has no clock of its own)"
    return ""


#: A bifurcation-target row's block: costs are ranked within one.
_BIF_BLOCK = ["problem_label", "target", "machine", "environment"]


def _bif_ranks(rows: pd.DataFrame) -> pd.Series:
    """Each row's rank in its block (missing for the rows :func:`not_located` names): the rank the
    leaderboard's ranking code (:func:`nsbench.bench.tables.ranking`) gives one entry per configuration
    without timing samples, 1 + the number of strictly cheaper ones (equal costs share the best).

    That is pandas' ``rank(method="min")`` of the costs, computed here for a whole block at once:
    ``ranking`` compares every entry with every other (seconds for a block of thousands of configurations
    in a large archive); ``tests/archive/test_bifurcations.py`` holds the two to the same ranks."""
    ranks = pd.Series(pd.NA, index=rows.index, dtype="Int64")
    located = rows[rows["reason"] == ""]
    if located.empty:
        return ranks
    keys = [located[k] for k in _BIF_BLOCK]
    cost = located["integrator_time"].astype(float)  # finite and positive: not_located names the others
    ranks.loc[located.index] = cost.groupby(keys, sort=False, dropna=False).rank(method="min").astype(int)
    return ranks


def _one_per_method(rows: pd.DataFrame) -> pd.DataFrame:
    """Each method's entry in each block: its cheapest located configuration (equal costs: the first in
    the report's order, then run id), else its configuration closest to the reference's location (no
    finite error: the first in that order). ``located`` and ``configurations`` count its rows in the block."""
    keys = [*_BIF_BLOCK, "integrator"]
    rows = rows.assign(_located=rows["reason"] == "")
    group = rows.groupby(keys, sort=False, dropna=False)
    rows["located"] = group["_located"].transform("sum").astype(int)
    rows["configurations"] = group["_located"].transform("size").astype(int)
    cost = rows["integrator_time"].astype(float).where(rows["_located"], math.inf)
    error = rows["bifurcation_error"].astype(float).where(lambda e: e.notna(), math.inf)
    rows = rows.assign(_cost=cost, _error=error.where(~rows["_located"], 0.0), _level=rows["level"].astype(float))
    order = [*keys, "_cost", "_error", "_level", "run_id"]
    picked = rows.sort_values(order, kind="stable").drop_duplicates(keys, keep="first")
    return picked.drop(columns=["_located", "_cost", "_error", "_level"]).reset_index(drop=True)


def bifurcation_board(tables: Tables, problem: str | None = None, per: str = "method") -> pd.DataFrame:
    """The bifurcation-target leaderboard (module docstring): problem, machine, environment, rank and
    tie, then the report's table (:func:`nsbench.bench.targets.report_table`) row for row, then xtol,
    the reason a row is not ranked ('' if it is), ``located`` and ``configurations`` (how many of the
    method's configurations in the block located it, of how many), commit and run id.

    ``per="method"`` (the default, as ``show`` and ``site`` list it): one entry per method and block,
    its cheapest located configuration over every run of the block (else its closest one, unranked);
    ``per="configuration"``: every configuration of every run (``located`` 1 or 0 of 1). Sorted by
    (problem, target, machine, environment); within each, the ranked rows by rank and cost, then the
    others in the report's order (integrator, level)."""
    from nsbench.bench.targets import report_table

    if per not in BIF_PER:
        raise ConfigError(f"per = {per!r}: give one of {', '.join(map(repr, BIF_PER))}")
    runs = tables.runs[["run_id", "machine", "environment", "commit"]]
    rows = tables.bifurcations.merge(runs, on="run_id", how="left")
    if problem is not None:
        rows = rows[rows["problem_label"].astype(str) == problem]
    if rows.empty:
        return pd.DataFrame(columns=[*BIF_KEYS, *BIF_AFTER])
    rows = rows.reset_index(drop=True)
    rows["reason"] = [not_located(r) for r in rows.to_dict("records")]
    if per == "method":
        rows = _one_per_method(rows)
    else:
        rows["located"] = (rows["reason"] == "").astype(int)
        rows["configurations"] = 1
    rows["rank"] = _bif_ranks(rows)
    rows["tie"] = ties(rows, _BIF_BLOCK)
    # within a block the ranked rows by rank (then cost), then the unranked ones in the report's order
    # (integrator, level): their cost is no rank
    rows["_unranked"] = rows["rank"].isna()
    rows["_rank"] = rows["rank"].astype("Float64").fillna(math.inf).astype(float)
    rows["_cost"] = rows["integrator_time"].astype(float).where(~rows["_unranked"], 0.0)
    order = [*_BIF_BLOCK, "_rank", "_cost", "integrator", "level", "run_id"]
    rows = rows.sort_values(order, kind="stable", ignore_index=True)
    view = report_table(rows)  # the report's columns and formatting, row for row
    front = rows[["problem_label", "machine", "environment", "rank", "tie"]].rename(
        columns={"problem_label": "problem"}
    )
    counts = rows[["xtol", "reason", "located", "configurations"]]
    return pd.concat([front, view, counts, rows[["commit", "run_id"]].astype(str)], axis=1)


def render_bifurcations(board: pd.DataFrame, per: str = "method") -> str:
    """The bifurcation-target leaderboard as text, one table per (problem, target, machine, environment);
    ``per`` says which form of :func:`bifurcation_board` ``board`` is."""
    if board.empty:
        return ""
    lines = [
        "Bifurcation targets (as submitted, not re-graded): each configuration locates the bifurcation with its own flow"
    ]
    lines.append(BIF_RANKING if per == "method" else BIF_RANKING_EVERY)
    for (problem, target, machine, env), block in board.groupby(
        ["problem", "target", "machine", "environment"], sort=False
    ):
        lines += ["", f"{problem}, bifurcation target {target} ({machine}, {env})"]
        lines.append(
            "rank  method                level  status         value            error     probes  cost s    located/of  run"
        )
        for e in block.to_dict("records"):
            error = f"{e['bifurcation_error']:.3g}" if e["bifurcation_error"] == e["bifurcation_error"] else "-"
            rank = "   -  " if pd.isna(e["rank"]) else f"{int(e['rank']):>4}{' =' if e['tie'] else '  '}"
            why = f"  (not ranked: {e['reason']})" if e["reason"] else ""
            of = f"{e['located']}/{e['configurations']}"
            lines.append(
                f"{rank}{e['integrator']:<22}{e['level']!s:>5}  {e['status']:<13}  {e['bifurcation_value']:<15}  "
                f"{error:<8}  {e['probes']!s:>6}  {_seconds(float(e['cost (s)'])):<8}  "
                f"{of:>10}  {e['run_id']}{why}"
            )
    if board["tie"].any():
        lines += ["", "= tied: equal costs (no interval is recorded for a bifurcation target's cost)"]
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
    every_configuration
        List every configuration of every run on the bifurcation-target leaderboard, not one entry per
        method and block (:func:`bifurcation_board`'s ``per``).
    """

    archive: str
    problem: str | None = None
    target: float | str | None = None
    every_configuration: bool = False

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

    # the leaderboard reads only the rows, and not their dense states and event logs (checked all the same)
    tables = load(request.archive, events=False, bulky=False)
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
    per = "configuration" if request.every_configuration else "method"
    bifurcations = bifurcation_board(tables, request.problem, per=per)
    if len(bifurcations):
        print()
        print(render_bifurcations(bifurcations, per=per))
    return ArchiveShowOutcome(board, bifurcations)
