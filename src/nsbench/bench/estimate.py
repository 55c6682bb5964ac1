"""How long a suite run will take, said before it starts, and the weight of each task in its progress bar.

The packaged suites come with the cost of every task measured on one machine
(``nsbench/suites/costs.json``: seconds of a worker for each case's warm-up,
its first timing task (the calibration run, the first sample and the metrics)
and each later timed sample, each reference, each bifurcation-target location,
and the report). Before a run, a short fixed workload (:func:`calibrate`) says how much
slower or faster this machine is, and the load average says how many of its
cores other programs hold; the measured costs scaled by both, spread over the
workers, are the estimate. A task the table does not know (a plug-in, a suite
of one's own) counts as the median known task and is named in the statement.

The same costs weigh the steps of the progress bar, so that its estimate of the
time left (the work left over the rate at which work got done so far) holds
when long and short tasks mix and when the machine gets busier or quieter.

``python -m nsbench.bench.remeasure OUT SECONDS`` writes the table from a
finished run of ``nsbench run --suite full --fresh --out OUT`` on an idle
machine with two workers, ``SECONDS`` its wall time without the report; with
``--merge default`` after it, from a run of the default suite, it adds that run's
tasks to the table and keeps its overhead and report time as the default's own
(a short suite's fixed costs are not the full one's).
"""

from __future__ import annotations

import json
import math
import os
import statistics
import time
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any, Iterable

#: The table of measured costs shipped with the packaged suites.
COSTS_FILE = "costs.json"


def calibrate(seconds: float = 0.5) -> float:
    """Seconds of a fixed workload like the bench's (scipy's DOP853 on a forced oscillator): the best of
    its repeats over ``seconds``.

    It exercises what most cases of the default suite spend their time in (the
    Python interpreter driving numpy) and takes about 0.03 s on a current core.
    The first repeats of a process run up to twice slower (first use, the
    processor's clock rising), so it repeats for a stated time, not a count.
    """
    import numpy as np
    from scipy.integrate import solve_ivp

    def field(t, y):
        return np.array([y[1], -y[0] - 0.05 * y[1] + 0.3 * np.cos(0.9 * t)])

    best, start = math.inf, time.perf_counter()
    while True:
        tic = time.perf_counter()
        solve_ivp(field, (0.0, 150.0), [0.0, 0.0], method="DOP853", rtol=1e-10, atol=1e-12)
        toc = time.perf_counter()
        best = min(best, toc - tic)
        if toc - start >= seconds:
            return best


def other_load(cores: int) -> float:
    """Runnable processes of other programs, from the 1-minute load average (0 where it is unknown)."""
    try:
        return max(0.0, float(os.getloadavg()[0]))
    except (AttributeError, OSError):  # pragma: no cover - platforms without a load average
        return 0.0


@dataclass
class CostTable:
    """Measured seconds per task on the machine named in ``machine`` (see the module docstring)."""

    calibration: float
    machine: str = ""
    measured: str = ""
    warm_up: dict[str, float] = field(default_factory=dict)  # case label -> its first warm-up
    run: dict[str, float] = field(default_factory=dict)  # case label -> one later timed sample
    #: case label -> its first timing task: the calibration run, the first sample, the metrics (a table
    #: measured before samples were calibrated has none: its ``run`` stands for every timing task)
    first: dict[str, float] = field(default_factory=dict)
    target: dict[str, float] = field(default_factory=dict)  # location label -> the whole location
    reference: float = 1.5  # one reference run
    report: float = 15.0  # writing the report
    #: the rest of a run, not in any task: starting workers, the barriers between phases, the
    #: bifurcation targets' references (the measured run's time less its tasks over its workers)
    overhead: float = 0.0
    #: suite name -> its own tables where it was measured apart: ``overhead`` and ``report`` (a short suite's
    #: fixed costs are not the full one's) and ``warm_up``, ``first``, ``run``, ``target`` as above (a case
    #: label names no span: the default suite's ``one-dof/1 exact[]`` over [0, 100] is not the full one's
    #: over [0, 300]); the fields above stand for any other suite and any task a suite's own lack
    suites: dict[str, dict[str, Any]] = field(default_factory=dict)

    @classmethod
    def packaged(cls) -> "CostTable | None":
        """The table shipped with nsbench, or ``None`` if it is missing or unreadable."""
        try:
            data = json.loads(resources.files("nsbench.suites").joinpath(COSTS_FILE).read_text())
            return cls(**data)
        except (OSError, ValueError, TypeError):
            return None

    def to_json(self) -> str:
        return json.dumps(self.__dict__, indent=1, sort_keys=True)

    def costs(self, label: str, suite: str | None = None) -> tuple[float, float, float] | None:
        """Worker seconds of a case's warm-up, its first timing task and each later one, ``None`` if unknown.

        ``suite``'s own measurement first, if it has one (:attr:`suites`). A case measured with a warm-up and no
        timed sample (refused at ``setup``) costs only the warm-up.
        """
        own = self.suites.get(suite or "", {})
        for warm_up, first, runs in (
            (own.get("warm_up", {}), own.get("first", {}), own.get("run", {})),
            (self.warm_up, self.first, self.run),
        ):
            if label in warm_up or label in runs:
                run = runs.get(label, 0.0)
                return warm_up.get(label, run), first.get(label, run), run
        return None

    def target_cost(self, label: str, suite: str | None = None) -> float | None:
        """Worker seconds of a bifurcation-target location (``suite``'s own first), ``None`` if unknown."""
        own = self.suites.get(suite or "", {}).get("target", {})
        return own.get(label, self.target.get(label))

    def fixed(self, suite: str | None = None) -> tuple[float, float, float]:
        """Seconds of a run of ``suite`` outside its tasks, of writing its report and of one reference run: its
        own, else the table's."""
        own = self.suites.get(suite or "", {})
        return (
            float(own.get("overhead", self.overhead)),
            float(own.get("report", self.report)),
            float(own.get("reference", self.reference)),
        )

    def merged(self, other: "CostTable", suite: str) -> "CostTable":
        """This table with ``other``'s tasks (measured for ``suite``) added, in this table's time scale.

        ``other``'s seconds are scaled by the ratio of the two calibrations (the machines' speeds), so that one
        calibration holds for the whole table; its overhead and report become ``suite``'s own.
        """
        k = self.calibration / other.calibration

        def scaled(d: dict[str, float], digits: int = 4) -> dict[str, float]:
            return {label: round(v * k, digits) for label, v in d.items()}

        out = CostTable(**json.loads(self.to_json()))
        out.suites[suite] = {
            "measured": other.measured,
            "overhead": round(other.overhead * k, 1),
            "report": round(other.report * k, 1),
            "reference": round(other.reference * k, 3),
            "warm_up": scaled(other.warm_up),
            "first": scaled(other.first),
            "run": scaled(other.run),
            "target": scaled(other.target, 3),
        }
        return out

    def typical(self) -> tuple[float, float, float]:
        """The median warm-up, first timing task and later timed sample over the table's cases."""
        if not self.run:
            return 1.0, 1.0, 1.0
        return (
            statistics.median(self.warm_up.get(k, v) for k, v in self.run.items()),
            statistics.median(self.first.get(k, v) for k, v in self.run.items()),
            statistics.median(self.run.values()),
        )


def location_label(target: str, integrator: str, options: dict[str, Any]) -> str:
    """The key of a bifurcation-target location in the cost table (options in name order)."""
    opts = ",".join(f"{k}={v:g}" if isinstance(v, float) else f"{k}={v}" for k, v in sorted(options.items()))
    return f"{target} {integrator}[{opts}]"


@dataclass
class Plan:
    """What a run will do and how long it should take (see :func:`plan`)."""

    n_cases: int
    n_runs: int  # timed samples (the warm-ups, calibration runs and references come on top)
    n_locations: int
    n_unknown: int  # tasks the cost table does not know (counted as its median)
    workers: int
    seconds: float  # the estimate on this machine now
    speed: float  # this machine's time for the calibration workload / the table's
    load: float  # other programs' runnable processes
    cores: int
    #: case label -> worker seconds of its warm-up and of one timing round, the mean of its rounds
    #: (the table's, or typical ones)
    weights: dict[str, tuple[float, float]] = field(default_factory=dict)
    #: the estimate if every case's samples spread widely and each gets its extra samples, up to its
    #: ``max_repeats`` (what a machine whose load changes during the run may cost); NaN without a table
    seconds_most: float = math.nan

    def statement(self) -> str:
        """One sentence for the user before the run starts."""
        parts = [f"{self.n_cases} case(s): {self.n_runs} timed samples after a warm-up each"]
        if self.n_locations:
            parts.append(f"then {self.n_locations} bifurcation-target location(s)")
        head = ", ".join(parts) + f", on {self.workers} worker(s)"
        if not math.isfinite(self.seconds):
            return head + "; no estimate of the time (no measured costs)"
        why = f"this machine takes {self.speed:.2g}x the time of the one the costs were measured on"
        if self.load >= 0.5:
            why += f", load {self.load:.1f} on {self.cores} cores"
        unknown = f"; {self.n_unknown} task(s) of unmeasured cost counted as typical" if self.n_unknown else ""
        most = ""
        if math.isfinite(self.seconds_most) and _duration(self.seconds_most) != _duration(self.seconds):
            upper = _duration(self.seconds_most).removesuffix(" (long)").replace("about ", "up to about ")
            most = f", {upper} if the timings spread"
        return f"{head}; estimated {_duration(self.seconds)}{most} ({why}{unknown})"


def _duration(seconds: float) -> str:
    if seconds < 90:
        return f"about {max(5, round(seconds / 5) * 5):.0f} s"
    return f"about {seconds / 60:.0f} min" if seconds < 600 else f"about {seconds / 60:.0f} min (long)"


def plan(
    cases: Iterable,
    locations: Iterable = (),
    n_references: int = 0,
    workers: int = 1,
    table: CostTable | None = None,
    calibration: float | None = None,
    load: float | None = None,
    cores: int | None = None,
    report: bool = True,
    suite: str | None = None,
) -> Plan:
    """The :class:`Plan` of a run of ``cases`` (suite cases) and ``locations`` (bifurcation-target locations).

    ``calibration`` (:func:`calibrate` here), ``load`` and ``cores`` default to
    this machine's; ``table`` to the packaged one. ``suite``: the suite's name, whose own task costs,
    overhead, report and reference times the table may hold (:attr:`CostTable.suites`).
    """
    cases, locations = list(cases), list(locations)
    table = table if table is not None else CostTable.packaged()
    cores = int(cores or os.cpu_count() or 1)
    n_workers = max(1, min(int(workers), cores))
    n_runs = sum(c.repeats for c in cases)
    if table is None:
        return Plan(
            len(cases),
            n_runs,
            len(locations),
            len(cases) + len(locations),
            n_workers,
            math.inf,
            math.nan,
            math.nan,
            cores,
        )
    load = other_load(cores) if load is None else max(0.0, load)
    calibration = calibrate() if calibration is None else calibration
    # The calibration is the best of many 30 ms repeats: one of them runs within a scheduler time
    # slice even beside other programs, so it measures the core's own speed, not the share the load
    # leaves (measured on 2 cores kept busy by two loops, load 2.2: the best repeat took the idle
    # time). Scale the table by that speed, then by the share of the cores that the workers (or the
    # one process that starts them and writes the report) will get beside the load.
    share_one = min(1.0, cores / (load + 1.0))
    share_workers = min(1.0, cores / (load + n_workers))
    speed = calibration / table.calibration
    unknown, weights, work, extra = 0, {}, 0.0, 0.0
    overhead, report_time, reference = table.fixed(suite)
    for c in cases:
        costs = table.costs(c.label, suite)
        if costs is None:
            unknown += 1
            costs = table.typical()
        warm, first, later = costs
        timing = first + (c.repeats - 1) * later
        weights[c.label] = (warm, timing / max(1, c.repeats))
        work += warm + timing
        # a case whose samples spread gets more of them, one per round, up to max_repeats
        extra += max(0, (getattr(c, "max_repeats", None) or c.repeats) - c.repeats) * later
    known_targets = list(table.target.values())
    typical_target = (
        statistics.median(known_targets) if known_targets else (table.typical()[0] + table.typical()[2]) * 4
    )
    target_work = 0.0
    for loc in locations:
        cost = table.target_cost(location_label(loc.target.name, loc.integrator, loc.options), suite)
        if cost is None:
            unknown += 1
            cost = typical_target
        target_work += cost
    work += n_references * reference
    seconds = (work + target_work) * speed / (n_workers * share_workers)
    seconds += overhead * speed / share_one
    if report:
        seconds += report_time * speed / share_one  # one process
    seconds_most = seconds + extra * speed / (n_workers * share_workers)
    return Plan(
        len(cases), n_runs, len(locations), unknown, n_workers, seconds, speed, load, cores, weights, seconds_most
    )


# ---------------------------------------------------------------------- the table, from a finished run
def measure(out: str | Path, total: float, workers: int = 2, calibration: float | None = None) -> CostTable:
    """A :class:`CostTable` from a finished run's ``timeline.csv`` and ``bifurcation_targets.parquet``.

    Each case's warm-up and timing tasks are the worker-slot durations of its
    tasks in the timeline: its first timing task (calibration run, first sample,
    metrics) and the median of its later ones (one timed sample each); ``total``
    is the run's wall time on ``workers`` workers, report excluded.
    """
    import pandas as pd

    from nsbench.provenance import provenance

    out = Path(out)
    tl = pd.read_csv(out / "timeline.csv")
    tl["seconds"] = tl["end"] - tl["start"]
    warm = tl[tl["kind"] == "warm-up"].groupby("label")["seconds"].max().to_dict()
    timed = tl[tl["kind"] == "time"].sort_values("start", kind="stable")
    first = timed.groupby("label")["seconds"].first().to_dict()
    later = timed[timed.duplicated("label")].groupby("label")["seconds"].median().to_dict()
    runs = {label: later.get(label, seconds) for label, seconds in first.items()}
    refs = tl[tl["kind"] == "reference"]["seconds"]
    targets: dict[str, float] = {}
    bif = out / "bifurcation_targets.parquet"
    if bif.exists():
        rows = pd.read_parquet(bif)
        for r in rows.itertuples(index=False):
            options = json.loads(r.options) if isinstance(r.options, str) else dict(r.options or {})
            setup = float(r.setup_time) if r.setup_time == r.setup_time else 0.0
            targets[location_label(r.target, r.integrator, options)] = float(r.wall_time) + setup
    tasks = tl.loc[tl["kind"] != "start", "seconds"].sum() + sum(targets.values())
    prov = provenance()
    return CostTable(
        calibration=calibrate(2.0) if calibration is None else calibration,
        machine=f"{prov.get('cpu', '?')}, {prov.get('cpu_count', '?')} cores",
        measured=f"{time.strftime('%Y-%m-%d')} at {str(prov.get('git_commit', '?'))[:12]}",
        warm_up={k: round(float(v), 4) for k, v in warm.items()},
        run={k: round(float(v), 4) for k, v in runs.items()},
        first={k: round(float(v), 4) for k, v in first.items()},
        target={k: round(v, 3) for k, v in targets.items()},
        reference=round(float(refs.median()), 3) if len(refs) else 1.5,
        overhead=round(max(0.0, total - tasks / workers), 1),
    )
