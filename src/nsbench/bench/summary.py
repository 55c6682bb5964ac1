"""The answer first: per problem and accuracy target, who is cheapest and by how much.

The report opens with this. For each problem that has a reference and each
switching-time error target: the cheapest method under test that reaches the
target (median warm wall time and its interval), every other method's cost as a
ratio to it with the ratio's interval, and the methods that never reach it with
the reason (best error reached, wrong event sequence, a failure status). A
method whose time cannot be told from the fastest one's (their intervals
overlap, or the ratio's interval holds 1: :func:`tied_with`) is *tied* with it:
then no single method is named the cheapest, and every tied one is named. Runs with a wrong event
sequence (missed or extra events) are listed by name: they never count as
reaching a target (:func:`nsbench.bench.metrics.reaches`), so they can never be
the cheapest. Reference-grade integrators (closed form, extended precision; the
``reference_grade`` capability) and each problem's own reference are shown apart,
with their cost only: they are what the others are measured against.

:func:`findings` turns the tables into a few sentences a paper can quote.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from nsbench.bench.stats import Interval, median_interval, ratio_interval, tied_with  # noqa: F401 (re-exported)
from nsbench.bench.tables import first_known, grading_floor, natural_key, problem_groups, reached_mask
from nsbench.bench.timing import spread_label
from nsbench.status import ReferenceStatus, Status

#: Confidence of the intervals of the report's times and cost ratios.
CONFIDENCE = 0.95


def reference_grade(name: str) -> bool:
    """Whether the registered integrator ``name`` is a reference solution (``False`` if unknown)."""
    from nsbench.integrators import integrator_class

    try:
        return bool(integrator_class(name).capabilities.reference_grade)
    except Exception:  # not registered here (results from elsewhere): a method under test
        return False


def split_references(frame: pd.DataFrame) -> tuple[pd.DataFrame, pd.DataFrame]:
    """``(methods under test, references)``: reference-grade integrators and each problem's own reference apart."""
    grade = {name: reference_grade(name) for name in frame["integrator"].unique()}
    is_ref = frame["integrator"].map(grade).astype(bool) | (frame["integrator"] == frame["reference"])
    return frame[~is_ref], frame[is_ref]


def _time(wall: float, spread: float) -> str:
    label = spread_label(spread)
    return f"{wall:.3g} s" + (f" {label}" if label else "")


def samples_of(row: pd.Series) -> list[float]:
    """The timed samples of a row (seconds per run), or its median alone when it kept none."""
    samples = list(row["wall_times"]) if "wall_times" in row and len(row["wall_times"]) else []
    return samples or ([float(row["wall_time"])] if pd.notna(row["wall_time"]) else [])


def interval_text(est: Interval, unit: str = "") -> str:
    """``'0.0123 s [0.0120-0.0127]'`` or ``'x1.8 [1.6-2.0]'``: an estimate and its interval."""
    if not est.known:
        return ""
    head = f"x{est.estimate:.3g}" if unit == "x" else f"{est.estimate:.3g}{unit}"
    if est.coverage <= 0:  # one sample: no interval
        return head
    return f"{head} [{est.low:.3g}-{est.high:.3g}]"


def cost_ratio(fast: list[float], other: list[float], confidence: float = CONFIDENCE) -> Interval:
    """``other``'s cost as a multiple of ``fast``'s: the ratio of their median times, with the Moses interval.

    The estimate is the ratio of the costs the answer compares (the medians: the fastest is the one of
    smallest median), so against the fastest it is never below 1. The Hodges-Lehmann ratio (the median
    of the pairwise ratios, :func:`nsbench.bench.stats.ratio_interval`) estimates the same scale factor
    but can fall below 1 against the method of smallest median (``x0.917`` beside a tie); its
    distribution-free (Moses) interval is kept as the interval of the factor.
    """
    moses = ratio_interval(fast, other, confidence)
    if not moses.known:
        return moses
    return Interval(float(np.median(other) / np.median(fast)), moses.low, moses.high, moses.coverage)


def _why_not(rows: pd.DataFrame, target: float) -> str:
    """Why an integrator's configurations never reach ``target`` on one problem."""
    if (rows["status"] == Status.UNSUPPORTED).all():
        return "refuses the problem"
    ok = rows[(rows["status"] == Status.SUCCESS) & rows["sequence_ok"].fillna(False).astype(bool)]
    wrong = rows[(rows["status"] == Status.SUCCESS) & ~rows["sequence_ok"].fillna(False).astype(bool)]
    failed = rows[~rows["status"].isin([Status.SUCCESS.value, Status.UNSUPPORTED.value])]
    parts = []
    if len(ok) and ok["switch_err_max"].notna().any():
        parts.append(f"best error {ok['switch_err_max'].min():.1e}")
    if len(wrong):
        parts.append(f"wrong event sequence in {len(wrong)} of {len(rows)} configurations")
    if len(failed):
        counts = failed["status"].value_counts()
        parts.append(", ".join(f"{n} {status}" for status, n in counts.items()))
    return "; ".join(parts) or "no usable run"


def problem_summary(frame: pd.DataFrame, targets, confidence: float = CONFIDENCE) -> pd.DataFrame:
    """One row per (problem, target): the cheapest method (or those tied for it), the others' cost ratios with
    their intervals, those never reaching it.

    Columns: ``problem, target, cheapest, time, others, not_reached`` (display
    strings; ``cheapest`` is ``'tied: a, b'`` when the fastest method cannot be
    told from others, :func:`tied_with`), ``wall_time, runner_up, ratio,
    ratio_low, ratio_high`` (the fastest's median time, the second fastest and its
    cost ratio with the ratio's interval, for :func:`findings`), ``tied`` (the
    names tied for cheapest, comma-separated, empty when one method is
    distinguishably cheapest) and ``reached`` (``'k of m'`` methods reach the target).
    """
    methods, _ = split_references(frame)
    rows = []
    for label, group in problem_groups(methods):
        if not (group["reference_status"] == ReferenceStatus.OK).any():
            continue
        limit, why = grading_floor(group[group["reference_status"] == ReferenceStatus.OK])
        for target in targets:
            row = {
                "problem": label,
                "target": f"{target:.0e}",
                "cheapest": "",
                "time": "",
                "others": "",
                "not_reached": "",
                "wall_time": math.nan,
                "runner_up": "",
                "ratio": math.nan,
                "ratio_low": math.nan,
                "ratio_high": math.nan,
                "tied": "",
                "reached": "",
            }
            rows.append(row)
            if target < limit:  # no method can be told right from wrong at this target
                row.update(not_reached=f"not graded at this target: {why}", reached="not graded")
                continue
            best: dict[str, list[float]] = {}
            missed = {}
            for name, runs in group.groupby("integrator", sort=True):
                hit = runs[reached_mask(runs, target)]
                if len(hit):
                    best[name] = samples_of(hit.loc[hit["wall_time"].idxmin()])
                elif not (runs["status"] == Status.UNSUPPORTED).all():
                    missed[name] = _why_not(runs, target)
            order = sorted(best, key=lambda n: float(np.median(best[n])))
            row.update(
                not_reached="; ".join(f"{n} ({why})" for n, why in missed.items()),
                reached=f"{len(best)} of {len(best) + len(missed)}",
            )
            if not order:
                continue
            first = order[0]
            fast = best[first]
            ties = [first] + [n for n in order[1:] if tied_with(fast, best[n], confidence)]
            ratios = [(n, cost_ratio(fast, best[n], confidence), n in ties) for n in order[1:]]
            row.update(
                cheapest=first if len(ties) == 1 else "tied: " + ", ".join(ties),
                time=interval_text(median_interval(fast, confidence), " s"),
                wall_time=float(np.median(fast)),
                tied=", ".join(ties) if len(ties) > 1 else "",
                others=_others(ratios),
            )
            if ratios:
                name, est, _ = ratios[0]
                row.update(runner_up=name, ratio=est.estimate, ratio_low=est.low, ratio_high=est.high)
    return pd.DataFrame(
        rows,
        columns=[
            "problem",
            "target",
            "cheapest",
            "time",
            "others",
            "not_reached",
            "wall_time",
            "runner_up",
            "ratio",
            "ratio_low",
            "ratio_high",
            "tied",
            "reached",
        ],
    )


def compact(summary: pd.DataFrame, target: str) -> pd.DataFrame:
    """One row per problem at one target (a table that fits a page): cheapest (or tied), its time, the
    next fastest and the cost ratio with its interval."""
    rows = summary[summary["target"] == target]
    ratio = [
        interval_text(Interval(r, lo, hi, 1.0 if lo == lo else 0.0), "x") if r == r else ""
        for r, lo, hi in zip(rows["ratio"], rows["ratio_low"], rows["ratio_high"])
    ]
    return pd.DataFrame(
        {
            "problem": rows["problem"],
            "cheapest": rows["cheapest"],
            "time": rows["time"],
            "next": rows["runner_up"],
            "ratio": ratio,
            "reach it": rows["reached"],
        }
    ).reset_index(drop=True)


#: Cost ratios listed by name in a summary cell; the rest are counted with their largest ratio.
SHOWN_RATIOS = 5


def _others(ratios: list[tuple[str, Interval, bool]]) -> str:
    def one(name, est, tied):
        return f"{name} {interval_text(est, 'x')}" + (" tied" if tied else "")

    text = ", ".join(one(*r) for r in ratios[:SHOWN_RATIOS])
    if len(ratios) > SHOWN_RATIOS:
        text += f", {len(ratios) - SHOWN_RATIOS} more up to x{ratios[-1][1].estimate:.3g}"
    return text


def display(summary: pd.DataFrame) -> pd.DataFrame:
    """The summary table as shown in a report."""
    return summary[["problem", "target", "cheapest", "time", "others", "not_reached"]].rename(
        columns={
            "time": "its time [interval]",
            "others": "others: cost ratio to the fastest [interval]",
            "not_reached": "never reach the target (why)",
        }
    )


def wrong_sequences(frame: pd.DataFrame) -> pd.DataFrame:
    """Successful runs whose event sequence differs from the reference's: missed and extra events."""
    methods, _ = split_references(frame)
    bad = methods[
        (methods["status"] == Status.SUCCESS)
        & (methods["reference_status"] == ReferenceStatus.OK)
        & ~methods["sequence_ok"].fillna(False).astype(bool)
    ]
    table = bad.assign(missed_extra=[f"{_int(m)} / {_int(x)}" for m, x in zip(bad["n_missed"], bad["n_extra"])])
    table = table[["problem_label", "integrator", "options", "missed_extra", "n_ref"]].rename(
        columns={"problem_label": "problem", "missed_extra": "events missed / extra", "n_ref": "reference events"}
    )
    return table.sort_values("problem", key=lambda s: s.map(natural_key), kind="stable", ignore_index=True)


def reference_costs(frame: pd.DataFrame) -> pd.DataFrame:
    """The references and reference-grade integrators per problem: their cheapest run's cost (not ranked)."""
    _, refs = split_references(frame)
    refs = refs[refs["status"] == Status.SUCCESS]
    rows = []
    for (label, name), runs in refs.groupby(["problem_label", "integrator"], sort=False):
        b = runs.loc[runs["wall_time"].idxmin()] if runs["wall_time"].notna().any() else runs.iloc[0]
        role = "the reference" if name == b["reference"] else "reference-grade"
        rows.append(
            {
                "problem": label,
                "integrator": name,
                "role": role,
                "time": _time(
                    float(b["wall_time"]), float(b["wall_spread"]) if pd.notna(b["wall_spread"]) else math.nan
                ),
            }
        )
    table = pd.DataFrame(rows, columns=["problem", "integrator", "role", "time"])
    cond = conditioning_table(frame)
    if len(cond):
        table = table.merge(cond[["problem", "certified", "conditioning", "double floor"]], on="problem", how="left")
    return table.sort_values("problem", key=lambda s: s.map(natural_key), kind="stable", ignore_index=True)


def conditioning_table(frame: pd.DataFrame) -> pd.DataFrame:
    """Per problem with a reference: how far its reference is certified, how strongly it amplifies a
    change of its start, and what that costs in double.

    Columns ``problem, certified, conditioning, double floor`` (display strings),
    ``certainty`` and ``floor`` (numbers) and ``gradable``: the reference is
    certified and the double floor is at most
    :data:`~nsbench.bench.reference.DOUBLE_GRADABLE` over the whole span.
    """
    from nsbench.bench.reference import DOUBLE_GRADABLE

    columns = ["problem", "certified", "conditioning", "double floor", "certainty", "floor", "gradable"]
    rows = []
    if "ref_conditioning" not in frame:
        return pd.DataFrame(columns=columns)
    for label, group in problem_groups(frame[frame["reference_status"] == ReferenceStatus.OK]):
        cond, certainty = first_known(group, "ref_conditioning"), first_known(group, "ref_certainty")
        if cond != cond and certainty != certainty:
            continue
        floor = cond * float(np.finfo(float).eps)
        rows.append(
            {
                "problem": label,
                "certified": "-"
                if certainty != certainty
                else ("not over the span" if math.isinf(certainty) else f"{certainty:.2g}"),
                "conditioning": "-" if cond != cond else ("sequence changes" if math.isinf(cond) else f"{cond:.3g}"),
                "double floor": "-" if not math.isfinite(floor) else f"{floor:.2g}",
                "certainty": certainty,
                "floor": floor,
                "gradable": bool(not floor > DOUBLE_GRADABLE and not certainty > DOUBLE_GRADABLE),
            }
        )
    return pd.DataFrame(rows, columns=columns)


def _int(value) -> str:
    return (
        "?" if value is None or value is pd.NA or (isinstance(value, float) and math.isnan(value)) else str(int(value))
    )


def findings(summary: pd.DataFrame, wrong: pd.DataFrame, cond: pd.DataFrame | None = None) -> list[str]:
    """A few sentences stating the answer: the cheapest method per target, by how much, and what went wrong."""
    from nsbench.bench.reference import DOUBLE_GRADABLE

    out = []
    for r in cond[~cond["gradable"]].itertuples() if cond is not None and len(cond) else ():
        if r.certainty > DOUBLE_GRADABLE:
            where = (
                "its reference is not certified over the whole span (an independent check's event sequence differs)"
                if math.isinf(r.certainty)
                else f"its reference's event times are certified to {r.certainty:.1g} only"
            )
            out.append(f"{r.problem} is not graded below that: {where}.")
        if not r.floor > DOUBLE_GRADABLE:
            continue
        if math.isinf(r.floor):
            out.append(
                f"{r.problem} cannot be graded in double precision: moving its start by 1e-9 changes "
                "its event sequence, so rounding alone makes any double-precision solution differ from "
                "the reference by more than the targets."
            )
        else:
            out.append(
                f"{r.problem} amplifies a change of its start {r.conditioning}-fold in its switching "
                f"times: rounding alone leaves any double-precision solution uncertain by about "
                f"{r.floor:.1g}, so smaller errors there are not measurable."
            )
    problems = summary["problem"].nunique()
    for target, rows in summary.groupby("target", sort=False):
        ungraded = int(rows["reached"].eq("not graded").sum())
        not_graded = (
            f"{ungraded} problem(s) cannot be graded at it (the reference's certainty or double rounding is coarser)"
            if ungraded
            else ""
        )
        won = rows[rows["cheapest"] != ""]
        if won.empty:
            if ungraded == len(rows):
                out.append(
                    f"No problem can be graded at a switching-time error of {target}: "
                    "the references' certainty or double rounding is coarser."
                )
            else:
                out.append(
                    f"No method under test reaches a switching-time error of {target} on any problem"
                    + (f"; {not_graded}" if ungraded else "")
                    + "."
                )
            continue
        single = won[won["tied"] == ""]
        parts = []
        if len(single):
            wins = single["cheapest"].value_counts()
            lead, n = wins.index[0], int(wins.iloc[0])
            mine = single[single["cheapest"] == lead]
            ratio, lows = mine["ratio"].dropna(), mine["ratio_low"].dropna()
            margin = ""
            if len(ratio):
                low, high = f"{ratio.min():.2g}", f"{ratio.max():.2g}"
                span = f"{low} to {high} times" if low != high else f"{low} times"  # not "1.2 to 1.2"
                margin = f"; the next method costs {span} as much"
                if len(lows):
                    margin += f" (the 95 % intervals of these ratios start at {lows.min():.2g} or above)"
            text = (
                f"At a switching-time error of {target}, {lead} is the cheapest method on {n} of "
                f"{len(rows)} problems{margin}"
            )
            others = [f"{name} on {int(k)}" for name, k in wins.iloc[1:].items()]
            if others:
                text += f" ({', '.join(others)} elsewhere)"
            parts.append(text)
        else:
            parts.append(
                f"At a switching-time error of {target}, no method is distinguishably the cheapest on any problem"
            )
        tied = won[won["tied"] != ""]
        if len(tied):
            listed = "; ".join(f"{_and(r.tied.split(', '))} on {r.problem}" for r in tied.itertuples())
            parts.append(
                f"on {len(tied)} problem(s) the cheapest cannot be told apart (their timing intervals "
                f"overlap), so they are tied: {listed}"
            )
        text = "; ".join(parts)
        unreached = rows["cheapest"].eq("").sum() - ungraded
        if unreached:
            text += f"; {int(unreached)} problem(s) have no method reaching it"
        if ungraded:
            text += f"; {not_graded}"
        out.append(text + ".")
    if len(wrong):
        names = sorted(set(wrong["integrator"]))
        out.append(
            f"{len(wrong)} run(s) end with a wrong event sequence (missed or extra events), by "
            f"{', '.join(names)}: they count as not reaching any target."
        )
    elif problems:
        out.append("Every successful run of a method under test has the reference's event sequence.")
    return out


def _and(names: list[str]) -> str:
    """``'a and b'``, ``'a, b and c'``."""
    return names[0] if len(names) == 1 else ", ".join(names[:-1]) + " and " + names[-1]
