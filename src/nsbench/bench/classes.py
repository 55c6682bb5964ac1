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

Every class cost ratio carries a 95 % interval, and the class's cheapest is
named only where it is distinguishable. Both come from a percentile bootstrap
over the timed samples (:func:`class_ratios`): each resample draws every
(problem, method)'s samples with replacement and takes their median, so the
interval holds the timing noise of every problem the ratio averages over. A
method is *tied* with the one of smallest ratio when the interval of their
quotient (the geometric mean over the problems of its cost over the smallest
one's) holds 1, or when a cost it rests on has fewer than two samples, the rule
of :func:`nsbench.bench.stats.tied_with` carried over to a geometric mean.
"""

from __future__ import annotations

import json
import math
from functools import lru_cache

import numpy as np
import pandas as pd

from nsbench.bench.stats import Interval
from nsbench.bench.summary import CONFIDENCE, samples_of, split_references, tied_with
from nsbench.bench.tables import grading_floor, problem_groups, reached_mask
from nsbench.status import ReferenceStatus

#: Bootstrap resamples of the class cost ratios (seeded: the same results give the same report).
BOOTSTRAP = 2000

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


def _resampled_medians(samples: list[float], rng: np.random.Generator, n: int) -> np.ndarray:
    """``n`` bootstrap medians of ``samples`` (their median ``n`` times when there are fewer than two)."""
    x = np.asarray([v for v in samples if v > 0 and math.isfinite(v)], dtype=float)
    if x.size < 2:
        return np.full(n, float(np.median(x)) if x.size else math.nan)
    return np.median(x[rng.integers(0, x.size, (n, x.size))], axis=1)


def class_ratios(
    samples: dict[str, dict[str, list[float]]],
    methods,
    confidence: float = CONFIDENCE,
    n_boot: int = BOOTSTRAP,
    seed: int = 0,
) -> tuple[dict[str, Interval], dict[str, bool]]:
    """Class cost ratios with bootstrap intervals, and which methods are tied with the one of smallest ratio.

    Parameters
    ----------
    samples
        problem -> method -> the timed samples of its cheapest configuration reaching the target
        there (every method that reaches it on that problem: the per-problem cheapest is among them).
    methods
        The methods reaching the target on every problem of ``samples``; their ratios are returned.

    Returns
    -------
    (ratios, tied)
        ``ratios[m]``: the geometric mean over the problems of ``m``'s median cost over the
        cheapest median cost there, with its percentile bootstrap interval at ``confidence``;
        ``tied[m]``: whether ``m`` cannot be told from the method of smallest ratio (the interval
        of their quotient holds 1, or a cost either rests on has fewer than two samples). The
        method of smallest ratio is tied with itself.
    """
    rng = np.random.default_rng(seed)
    problems = list(samples)
    # per problem, method -> its bootstrap medians (one per resample), and the cheapest of each resample
    boot = {p: {m: _resampled_medians(samples[p][m], rng, n_boot) for m in sorted(samples[p])} for p in problems}
    cheapest = {p: np.min(np.vstack(list(boot[p].values())), axis=0) for p in problems}
    point = {p: {m: float(np.median(samples[p][m])) for m in samples[p]} for p in problems}
    lo_q, hi_q = (1.0 - confidence) / 2.0, (1.0 + confidence) / 2.0
    ratios = {}
    for m in methods:
        estimate = np.mean([math.log(point[p][m] / min(point[p].values())) for p in problems])
        draws = np.mean([np.log(boot[p][m] / cheapest[p]) for p in problems], axis=0)
        ratios[m] = Interval(
            math.exp(estimate),
            float(np.exp(np.quantile(draws, lo_q))),
            float(np.exp(np.quantile(draws, hi_q))),
            confidence,
        )
    first = min(methods, key=lambda m: (ratios[m].estimate, m))
    tied = {}
    for m in methods:
        few = any(len(samples[p][x]) < 2 for p in problems for x in (m, first))
        quotient = np.mean([np.log(boot[p][m] / boot[p][first]) for p in problems], axis=0)
        low, high = np.quantile(quotient, [lo_q, hi_q])
        tied[m] = m == first or few or bool(low <= 0.0 <= high)
    return ratios, tied


def _ratio_text(est: Interval) -> str:
    """``'1.23 [1.05-1.60]'``; the estimate alone where the interval is a point (the only method everywhere)."""
    if est.low == est.high == est.estimate:
        return f"{est.estimate:.2f}"
    return f"{est.estimate:.2f} [{est.low:.2f}-{est.high:.2f}]"


def class_summary(frame: pd.DataFrame, targets) -> pd.DataFrame:
    """One row per (class, target): the cheapest method over the class's problems (module docstring).

    Columns: ``class``, ``problems`` (the graded problems' labels), ``target``,
    ``cheapest`` (``'tied: a, b'`` when the method of smallest ratio cannot be told
    from others: :func:`class_ratios`), ``ratio`` (its class cost ratio with the
    ratio's interval, text), ``runner_up`` (the next method and its ratio with its
    interval, ``', tied'`` when tied), ``wins`` (on how many of the problems it is the
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
        problems = [
            (label, rows_)
            for label, rows_ in problem_groups(group)
            if (rows_["reference_status"] == ReferenceStatus.OK).any()
        ]
        for target in targets:
            costs: dict[str, dict[str, float]] = {}  # problem -> method -> cheapest reaching time
            samples: dict[str, dict[str, list[float]]] = {}  # ... and that run's timed samples
            graded = []
            for label, rows_ in problems:
                limit, _ = grading_floor(rows_[rows_["reference_status"] == ReferenceStatus.OK])
                if target < limit:
                    continue
                graded.append(label)
                hit = rows_[reached_mask(rows_, target)]
                fastest = {name: runs.loc[runs["wall_time"].idxmin()] for name, runs in hit.groupby("integrator")}
                costs[label] = {name: float(row_["wall_time"]) for name, row_ in fastest.items()}
                samples[label] = {name: samples_of(row_) for name, row_ in fastest.items()}
            row = {
                "class": klass,
                "problems": ", ".join(graded),
                "target": f"{target:.0e}",
                "cheapest": "",
                "ratio": "",
                "runner_up": "",
                "wins": "",
                "not_on_every_problem": "",
            }
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
            ratios, tied = class_ratios({p: samples[p] for p in graded}, sorted(everywhere))
            order = sorted(everywhere, key=lambda m: (ratios[m].estimate, m))
            first = order[0]
            wins = sum(costs[p][first] == best[p] for p in graded)
            # where another method is cheaper, is the difference within the timing noise (summary.tied_with)?
            ties = sum(
                costs[p][first] != best[p]
                and tied_with(samples[p][min(costs[p], key=costs[p].__getitem__)], samples[p][first], CONFIDENCE)
                for p in graded
            )
            won = f"{wins} of {len(graded)}" + (f" (tied on {ties} more)" if ties else "")
            level = [m for m in order if tied[m]]
            runner = order[1] if len(order) > 1 else ""
            row.update(
                cheapest=first if len(level) == 1 else "tied: " + ", ".join(level),
                ratio=_ratio_text(ratios[first]),
                wins=won,
                runner_up=(f"{runner} ({_ratio_text(ratios[runner])}" + (", tied)" if tied[runner] else ")"))
                if runner
                else "",
            )
    return pd.DataFrame(rows, columns=COLUMNS)


def class_findings(summary: pd.DataFrame) -> list[str]:
    """One sentence per class: its cheapest method at each target."""
    out = []
    for klass, rows in summary.groupby("class", sort=False):
        parts = []
        for _, r in rows.iterrows():
            if r["ratio"] and r["cheapest"].startswith("tied: "):
                names = r["cheapest"][len("tied: ") :]
                parts.append(
                    f"at {r['target']} no method is distinguishably the cheapest: {names} are tied "
                    f"(their class cost ratios' intervals overlap; {names.split(', ')[0]} "
                    f"{r['ratio']}, cheapest on {r['wins']})"
                )
            elif r["ratio"]:
                parts.append(f"at {r['target']} {r['cheapest']} (cost ratio {r['ratio']}, cheapest on {r['wins']})")
            else:
                parts.append(f"at {r['target']} {r['cheapest']}")
        out.append(f"**{klass}** ({rows['problems'].iloc[0] or 'no graded problem'}): " + "; ".join(parts) + ".")
    return out


def display(summary: pd.DataFrame) -> pd.DataFrame:
    """The table as the report shows it."""
    return summary.rename(
        columns={
            "ratio": "class cost ratio",
            "runner_up": "runner-up (ratio)",
            "wins": "cheapest on",
            "not_on_every_problem": "reaches it on some problems only",
        }
    )
