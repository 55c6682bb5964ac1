"""The answer by problem class: for each class of non-smooth behaviour and each target, the cheapest method.

Each problem declares its class (``HybridProblem.problem_class``: ``friction``,
``impact``, ``sliding``, ``smooth``; a family that declares none is its own
class), read here from the problem a result row rebuilds; nothing is guessed from
names. Within a class, for one switching-time error target, a method's cost on a
problem is its cheapest configuration that reaches the target there (median warm
wall time); its *class cost ratio* is the geometric mean, over the class's graded
problems, of that cost divided by the cheapest method's cost on the same problem
(1 for a method that is the cheapest on every one). The class's cheapest method
is the one with the smallest ratio among the methods that reach the target on
every graded problem of the class; a method that misses a problem cannot be the
class's cheapest and is named apart. Reference-grade integrators and each
problem's reference are left out, as in the per-problem answer.
"""

from __future__ import annotations

import json
import math
from functools import lru_cache

import numpy as np
import pandas as pd

from nsbench.bench.summary import CONFIDENCE, samples_of, split_references, tied_with
from nsbench.bench.tables import grading_floor, problem_groups, reached_mask

#: The classes in the order the report lists them (others follow, alphabetically).
CLASS_ORDER = ("friction", "impact", "sliding", "smooth")
COLUMNS = ["class", "problems", "target", "cheapest", "ratio", "runner_up", "wins", "not_on_every_problem"]


@lru_cache(maxsize=None)
def class_of(problem_config: str) -> str:
    """The declared class of the problem a row's ``problem_config`` (JSON) rebuilds; ``''`` if it cannot be built."""
    from nsbench.problems import problem_from_config

    try:
        return problem_from_config(json.loads(problem_config)).behaviour()
    except Exception:  # results from a machine with a problem this one lacks: no class to group by
        return ""


def _order(name: str) -> tuple[int, str]:
    return (CLASS_ORDER.index(name) if name in CLASS_ORDER else len(CLASS_ORDER), name)


def class_summary(frame: pd.DataFrame, targets) -> pd.DataFrame:
    """One row per (class, target): the cheapest method over the class's problems (module docstring).

    Columns: ``class``, ``problems`` (the graded problems' labels), ``target``,
    ``cheapest``, ``ratio`` (its class cost ratio, text), ``runner_up`` (the next
    method and its ratio), ``wins`` (on how many of the problems it is the
    cheapest, and on how many more it is tied with the cheapest within the timing
    noise, :func:`nsbench.bench.summary.tied_with`), ``not_on_every_problem`` (methods reaching the target on some but
    not all of them).
    """
    if frame.empty or "problem_config" not in frame:
        return pd.DataFrame(columns=COLUMNS)
    methods, _ = split_references(frame)
    methods = methods.assign(problem_class=methods["problem_config"].map(class_of))
    rows = []
    for klass in sorted((c for c in methods["problem_class"].unique() if c), key=_order):
        group = methods[methods["problem_class"] == klass]
        problems = [(label, rows_) for label, rows_ in problem_groups(group)
                    if (rows_["reference_status"] == "ok").any()]
        for target in targets:
            costs: dict[str, dict[str, float]] = {}  # problem -> method -> cheapest reaching time
            samples: dict[str, dict[str, list[float]]] = {}  # ... and that run's timed samples
            graded = []
            for label, rows_ in problems:
                limit, _ = grading_floor(rows_[rows_["reference_status"] == "ok"])
                if target < limit:
                    continue
                graded.append(label)
                hit = rows_[reached_mask(rows_, target)]
                fastest = {name: runs.loc[runs["wall_time"].idxmin()] for name, runs in hit.groupby("integrator")}
                costs[label] = {name: float(row_["wall_time"]) for name, row_ in fastest.items()}
                samples[label] = {name: samples_of(row_) for name, row_ in fastest.items()}
            row = {"class": klass, "problems": ", ".join(graded), "target": f"{target:.0e}", "cheapest": "",
                   "ratio": "", "runner_up": "", "wins": "", "not_on_every_problem": ""}
            rows.append(row)
            if not graded:
                row["cheapest"] = "not graded at this target"
                continue
            everywhere = set.intersection(*(set(costs[p]) for p in graded))
            somewhere = set().union(*(set(costs[p]) for p in graded)) - everywhere
            row["not_on_every_problem"] = ", ".join(sorted(somewhere))
            if not everywhere:
                row["cheapest"] = "no method reaches it on every problem"
                continue
            best = {p: min(costs[p].values()) for p in graded}
            ratio = {m: math.exp(np.mean([math.log(costs[p][m] / best[p]) for p in graded])) for m in everywhere}
            order = sorted(everywhere, key=lambda m: (ratio[m], m))
            first = order[0]
            wins = sum(costs[p][first] == best[p] for p in graded)
            # where another method is cheaper, is the difference within the timing noise (summary.tied_with)?
            ties = sum(costs[p][first] != best[p] and tied_with(
                samples[p][min(costs[p], key=costs[p].__getitem__)], samples[p][first], CONFIDENCE) for p in graded)
            won = f"{wins} of {len(graded)}" + (f" (tied on {ties} more)" if ties else "")
            row.update(cheapest=first, ratio=f"{ratio[first]:.2f}", wins=won,
                       runner_up=f"{order[1]} ({ratio[order[1]]:.2f})" if len(order) > 1 else "")
    return pd.DataFrame(rows, columns=COLUMNS)


def class_findings(summary: pd.DataFrame) -> list[str]:
    """One sentence per class: its cheapest method at each target."""
    out = []
    for klass, rows in summary.groupby("class", sort=False):
        parts = []
        for _, r in rows.iterrows():
            if r["ratio"]:
                parts.append(f"at {r['target']} {r['cheapest']} (cost ratio {r['ratio']}, cheapest on {r['wins']})")
            else:
                parts.append(f"at {r['target']} {r['cheapest']}")
        out.append(f"**{klass}** ({rows['problems'].iloc[0] or 'no graded problem'}): " + "; ".join(parts) + ".")
    return out


def display(summary: pd.DataFrame) -> pd.DataFrame:
    """The table as the report shows it."""
    return summary.rename(columns={"ratio": "class cost ratio", "runner_up": "runner-up (ratio)",
                                   "wins": "cheapest on", "not_on_every_problem": "reaches it on some problems only"})
