"""Summary tables of a result frame: the fixed-target table (COCO style) and a ranking.

The fixed-target table answers, per problem and integrator: what is the cheapest
configuration (by warm wall time) that reaches a switching-time error target, and
what does it cost (time and ``nfev``)? A run with a wrong event sequence never
reaches a target (:func:`nsbench.bench.metrics.reaches`).
"""

from __future__ import annotations

import math
import re
from typing import Mapping, Sequence

import numpy as np
import pandas as pd

from nsbench.bench.metrics import reaches
from nsbench.bench.stats import tied_with
from nsbench.bench.timing import spread_label
from nsbench.status import ReferenceStatus, Status, TargetOutcome

DEFAULT_TARGETS = (1e-6, 1e-9, 1e-12)


def natural_key(label: str) -> tuple:
    """Sort key reading the numbers inside a label as numbers (``n=2`` before ``n=16``)."""
    return tuple(
        (0, int(part), "") if part.isdigit() else (1, 0, part) for part in re.split(r"(\d+)", str(label)) if part
    )


def problem_groups(frame: pd.DataFrame):
    """``(problem_label, rows)`` pairs in natural order of the labels."""
    labels = sorted(frame["problem_label"].unique(), key=natural_key)
    return [(label, frame[frame["problem_label"] == label]) for label in labels]


def reached_mask(frame: pd.DataFrame, target: float) -> pd.Series:
    """Which rows reach ``target`` (success, exact event sequence, max error <= target)."""
    return pd.Series(
        [
            reaches(
                target,
                status=str(s),
                sequence_ok=bool(ok) if ok is not pd.NA else False,
                err_max=float(e) if pd.notna(e) else math.nan,
            )
            for s, ok, e in zip(frame["status"], frame["sequence_ok"], frame["switch_err_max"])
        ],
        index=frame.index,
        dtype=bool,
    )


def first_known(rows: pd.DataFrame, column: str) -> float:
    """The first non-NaN value of a per-problem column (the same on every row of a problem), NaN if none."""
    known = rows[column].dropna() if column in rows else pd.Series(dtype=float)
    return float(known.iloc[0]) if len(known) else math.nan


def grading_floor(rows: pd.DataFrame) -> tuple[float, str]:
    """The smallest switching-time error target a problem's rows can be graded at, and why.

    Below the reference's certified error (``ref_certainty``) a difference from
    the reference is no measurement; below the double-precision floor
    (``ref_double_floor``: the case's amplification of a rounding of its start)
    no double-precision solution can be told right from wrong. ``(0, '')`` when
    neither is known (results without them grade every target).
    """
    cert, floor = first_known(rows, "ref_certainty"), first_known(rows, "ref_double_floor")
    limit, why = 0.0, ""
    if cert == cert and cert > limit:
        limit = cert
        why = (
            "the reference is not certified over the whole span"
            if math.isinf(cert)
            else f"the reference is certified to {cert:.1e} only"
        )
    if floor == floor and floor > limit:
        limit = floor
        why = (
            "a change of the start by 1e-9 changes the event sequence"
            if math.isinf(floor)
            else f"rounding alone moves any double-precision solution's switching times by {floor:.1e}"
        )
    return limit, why


def graded(rows: pd.DataFrame, target: float) -> bool:
    """Whether ``target`` can be graded on a problem's rows (see :func:`grading_floor`)."""
    return bool(target >= grading_floor(rows)[0])


def fixed_target(frame: pd.DataFrame, targets=DEFAULT_TARGETS) -> pd.DataFrame:
    """Long table: one row per (problem, integrator, target).

    Columns: ``problem_label, integrator, target, outcome`` (``reached``, ``not
    reached``, ``not graded`` below what the reference can certify or double
    precision can resolve (:func:`grading_floor`), ``no reference``,
    ``unsupported``, or ``reference`` for the problem's reference itself), and for reached targets the cheapest case's
    ``wall_time`` (median of its timed runs), ``wall_spread`` (``(max - min) /
    median``), ``nfev, options, level, case_id``.
    """
    rows = []
    for (label, name), group in frame.groupby(["problem_label", "integrator"], sort=True):
        has_ref = bool((group["reference_status"] == ReferenceStatus.OK).any())
        for target in targets:
            row = {
                "problem_label": label,
                "integrator": name,
                "target": float(target),
                "outcome": TargetOutcome.NO_REFERENCE.value,
                "wall_time": math.nan,
                "wall_spread": math.nan,
                "nfev": pd.NA,
                "options": "",
                "level": pd.NA,
                "case_id": "",
            }
            if (group["status"] == Status.UNSUPPORTED).all():
                row["outcome"] = TargetOutcome.UNSUPPORTED.value
            elif has_ref and (group["reference"] == name).all():
                # the reference against itself: its cost is informative, its error is 0 by construction
                best = group.loc[group["wall_time"].idxmin()] if group["wall_time"].notna().any() else None
                row["outcome"] = TargetOutcome.REFERENCE.value
                if best is not None:
                    row.update(_cost(best))
            elif has_ref and not graded(group, target):
                row["outcome"] = TargetOutcome.NOT_GRADED.value
            elif has_ref:
                ok = group[reached_mask(group, target)]
                if len(ok):
                    best = ok.loc[ok["wall_time"].idxmin()]
                    row.update(outcome=TargetOutcome.REACHED.value, **_cost(best))
                else:
                    row["outcome"] = TargetOutcome.NOT_REACHED.value
            rows.append(row)
    table = pd.DataFrame(
        rows,
        columns=[
            "problem_label",
            "integrator",
            "target",
            "outcome",
            "wall_time",
            "wall_spread",
            "nfev",
            "options",
            "level",
            "case_id",
        ],
    )
    return table.sort_values("problem_label", key=lambda s: s.map(natural_key), kind="stable", ignore_index=True)


def _cost(best: pd.Series) -> dict:
    spread = best["wall_spread"] if "wall_spread" in best and pd.notna(best["wall_spread"]) else math.nan
    return {
        "wall_time": float(best["wall_time"]),
        "wall_spread": float(spread),
        "nfev": best["nfev"],
        "options": best["options"],
        "level": best["level"],
        "case_id": best["case_id"],
    }


def _time(row: pd.Series) -> str:
    """``'0.123 s ±4%'``: the median and half its min-max range (no ± for a single run)."""
    label = spread_label(row["wall_spread"])
    return f"{row['wall_time']:.3g} s" + (f" {label}" if label else "")


def work_text(nfev) -> str:
    """``nfev`` as a table shows it: the count, or ``'n/a'`` where the method counts none.

    A run that reached a target did some work, so a stored 0 (or nothing) is no count: the method
    does not report one (``siconos`` hands back no evaluation count), and 0 would read as free.
    """
    try:
        count = int(nfev)
    except (TypeError, ValueError):  # NA, NaN, None
        return "n/a"
    return str(count) if count > 0 else "n/a"


def _cell(row: pd.Series) -> str:
    if row["outcome"] == TargetOutcome.REACHED:
        return f"{_time(row)} / {work_text(row['nfev'])}"
    if row["outcome"] == TargetOutcome.REFERENCE and pd.notna(row["wall_time"]):
        return f"ref ({_time(row)} / {work_text(row['nfev'])})"
    short = {
        TargetOutcome.NO_REFERENCE: "no ref",
        TargetOutcome.UNSUPPORTED: "unsupported",
        TargetOutcome.NOT_GRADED: "not graded",
    }
    return short.get(row["outcome"], "-")  # a str member hashes and compares as its text


def fixed_target_wide(long: pd.DataFrame) -> pd.DataFrame:
    """Display form: rows (problem, integrator), one column per target, cells ``'time s ±x% / nfev'``."""
    if long.empty:
        return pd.DataFrame(columns=["problem", "integrator"])
    cells = long.assign(cell=long.apply(_cell, axis=1), col=long["target"].map(lambda t: f"{t:.0e}"))
    wide = cells.pivot_table(
        index=["problem_label", "integrator"], columns="col", values="cell", aggfunc="first", sort=False
    )
    order = [f"{t:.0e}" for t in sorted(long["target"].unique(), reverse=True)]
    wide = wide[order].reset_index().rename(columns={"problem_label": "problem"})
    wide.columns.name = None
    return wide


def _pair_ranks(group: pd.DataFrame, samples: Mapping[str, Sequence[float]] | None, confidence: float) -> pd.Series:
    """Ranks within one (problem, target), in tiers of methods that cannot be told apart; last if not reached.

    Without ``samples`` (tables built from medians alone) a method's rank is
    1 + the reaching methods with a smaller median (equal medians share a rank).
    With them, the ranks come in tiers, as the answer names ties
    (:func:`nsbench.bench.summary.problem_summary`): the fastest reaching method
    and every one whose timing cannot be told from its
    (:func:`nsbench.bench.stats.tied_with`) share rank 1; of the others, the
    fastest and those tied with it share rank 1 + the number ranked before them;
    and so on. So every method the answer calls tied for the cheapest is
    ranked 1, and no single method gets rank 1 where the timings do not single
    it out.
    """
    hit = group["outcome"] == TargetOutcome.REACHED
    t = group["wall_time"].where(hit, np.inf)
    last = float(len(group))
    if samples is None:
        return t.rank(method="min").where(np.isfinite(t), last)
    own = {i: list(samples.get(group.at[i, "case_id"], ())) for i in group.index[hit & np.isfinite(t)]}
    out = pd.Series(last, index=group.index)
    # tiers from the fastest down, each the fastest left and every method tied with it, as the answer
    # names the methods tied for cheapest (summary.problem_summary): tiedness is not transitive, so
    # counting faster methods pairwise could rank 2nd a method the answer calls tied for the cheapest
    left = sorted(own, key=lambda i: (t[i], str(group.at[i, "integrator"])))
    placed = 0
    while left:
        head = left[0]
        tier = [i for i in left if i == head or tied_with(own[head], own[i], confidence)]
        for i in tier:
            out[i] = 1.0 + placed
        placed += len(tier)
        left = [i for i in left if i not in tier]
    return out


def ranking(
    long: pd.DataFrame, samples: Mapping[str, Sequence[float]] | None = None, confidence: float = 0.95
) -> pd.DataFrame:
    """Rank integrators by time to reach each (problem, target) that has a reference.

    In each (problem, target) an integrator that reaches it gets rank 1 + the
    number of reaching integrators that are faster; those that do not reach it
    are ranked last (the number of integrators in that group). ``samples``
    (``case_id`` -> the case's timed samples) makes the ranking honour the
    timing noise as the answer does: the methods tied with the fastest
    (:func:`nsbench.bench.stats.tied_with` at ``confidence``) share its rank,
    and so on down in tiers (:func:`_pair_ranks`). The table gives the mean rank, the
    targets reached out of those attempted, and the geometric mean time over
    reached ones; integrators with the same mean rank and targets reached share
    the table's ``rank``.
    """
    # ranked: the graded pairs of the methods that run the problem (a refusal is no rank)
    ranked = long["outcome"].map(lambda o: TargetOutcome(o).graded and o != TargetOutcome.UNSUPPORTED)
    scored = long[ranked.astype(bool)]  # a boolean mask even when empty (an object one would select columns)
    if scored.empty:
        return pd.DataFrame(columns=["rank", "integrator", "mean_rank", "reached", "attempted", "geo_mean_time"])
    ranks = []
    for _, group in scored.groupby(["problem_label", "target"]):
        r = _pair_ranks(group, samples, confidence)
        ranks.append(
            pd.DataFrame(
                {
                    "integrator": group["integrator"],
                    "r": r,
                    "hit": group["outcome"] == TargetOutcome.REACHED,
                    "t": group["wall_time"],
                }
            )
        )
    all_ranks = pd.concat(ranks)
    table = (
        all_ranks.groupby("integrator")
        .agg(
            mean_rank=("r", "mean"),
            reached=("hit", "sum"),
            attempted=("hit", "size"),
            geo_mean_time=("t", lambda s: float(np.exp(np.log(s.dropna()).mean())) if s.notna().any() else math.nan),
        )
        .reset_index()
    )
    table = table.sort_values(["mean_rank", "reached"], ascending=[True, False], kind="stable")
    key = list(zip(table["mean_rank"].round(12), -table["reached"]))
    table.insert(0, "rank", [1 + sum(k < mine for k in key) for mine in key])
    return table.reset_index(drop=True)
