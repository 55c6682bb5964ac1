"""``nsbench archive show ARCHIVE``: a leaderboard per (problem, target switching-time error).

For each problem and target, each method's cheapest configuration that reaches the target
(:func:`nsbench.bench.metrics.reaches` on the re-graded errors: success, the reference's event
sequence, ``switch_err_max <= target``), ranked by its median wall time, with the median's
distribution-free interval (:func:`nsbench.bench.stats.median_interval`). Entries tied with the
fastest by the report's rule (:func:`nsbench.bench.stats.tied_with`: the intervals overlap, or the
cost ratio's interval holds 1) are marked tied. Times of different machines or environments are
never compared: each (machine, environment) is ranked on its own.
"""

from __future__ import annotations

import math

import pandas as pd

from nsbench.archive.load import Tables
from nsbench.bench.metrics import reaches
from nsbench.bench.stats import median_interval, tied_with

#: The switching-time error targets of the leaderboard (problem time units).
TARGETS = (1e-4, 1e-8, 1e-12)
#: The columns of :func:`leaderboard`.
COLUMNS = (
    "problem",
    "target",
    "machine",
    "environment",
    "rank",
    "method",
    "options",
    "level",
    "switch_err_max",
    "wall_time",
    "wall_low",
    "wall_high",
    "tie",
    "commit",
    "run_id",
)
NOTE = "Costs are compared only within one machine and environment: each block below ranks the runs of one."


def _meeting(rows: pd.DataFrame, target: float) -> pd.DataFrame:
    keep = [
        bool(g) and reaches(target, status=str(s), sequence_ok=bool(q) if pd.notna(q) else False, err_max=float(e))
        for g, s, q, e in zip(rows["graded"], rows["status"], rows["sequence_ok"], rows["switch_err_max"])
    ]
    return rows[keep]


def _ranked(group: pd.DataFrame) -> list[dict]:
    """Each method's cheapest row of one (problem, target, machine, environment), fastest first."""
    best = group.sort_values("wall_time", kind="stable").groupby("integrator", sort=False).head(1)
    best = best.sort_values(["wall_time", "integrator"], kind="stable")
    out, fastest = [], None
    for _, row in best.iterrows():
        samples = [float(w) for w in row["wall_times"]]
        interval = median_interval(samples)
        tie = ""
        if fastest is None:
            fastest = samples
        elif tied_with(fastest, samples):
            tie = "tied with the fastest"
        out.append(
            {
                "method": str(row["integrator"]),
                "options": str(row["options"]),
                "level": row["level"],
                "switch_err_max": float(row["switch_err_max"]),
                "wall_time": float(row["wall_time"]),
                "wall_low": interval.low,
                "wall_high": interval.high,
                "tie": tie,
                "commit": str(row["commit"]),
                "run_id": str(row["run_id"]),
            }
        )
    rank = 0
    for k, entry in enumerate(out):
        rank = 1 if entry["tie"] else k + 1
        entry["rank"] = rank
    return out


def leaderboard(tables: Tables, targets: tuple[float, ...] = TARGETS) -> pd.DataFrame:
    """The leaderboard of an archive's tables (:data:`COLUMNS`), one block per (problem, target,
    machine, environment)."""
    runs = tables.runs[["run_id", "machine", "environment", "commit"]]
    rows = tables.rows.merge(runs, on="run_id", how="left")
    rows = rows[pd.to_numeric(rows["wall_time"], errors="coerce").notna()]
    records = []
    for target in targets:
        meeting = _meeting(rows, target)
        for (problem, machine, env), group in meeting.groupby(["problem_label", "machine", "environment"], sort=True):
            for entry in _ranked(group):
                records.append({"problem": problem, "target": target, "machine": machine, "environment": env, **entry})
    frame = pd.DataFrame(records, columns=list(COLUMNS))
    return frame.sort_values(["problem", "target", "machine", "environment", "rank"], ascending=[True, False, True, True, True], kind="stable", ignore_index=True)


def _seconds(x: float) -> str:
    return f"{x:.3g}" if math.isfinite(x) else "-"


def render(board: pd.DataFrame) -> str:
    """The leaderboard as text: the note on costs, then one table per block."""
    lines = [NOTE]
    if board.empty:
        return "\n".join([*lines, "", "no graded run reaches any target"])
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
    lines += ["", "= tied with the fastest: the median intervals overlap or the cost ratio's interval holds 1"]
    return "\n".join(lines)
