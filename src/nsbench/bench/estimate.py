"""How long a suite run will take, said before it starts, and the weight of each task in its progress bar.

The packaged suites come with the cost of every task measured on one machine
(``nsbench/suites/costs.json``: seconds of a worker for each case's warm-up,
its first timing task (the calibration run, the first sample and the metrics)
and each later timed sample, each reference, each bifurcation-target location,
and the report). Before a run, a short fixed workload (:func:`calibrate`) says how much
slower or faster this machine is, and the load average says how many of its
cores other programs hold; the measured costs scaled by both, spread over the
workers, are the estimate. A case the table does not know (a plug-in, a suite
of one's own) counts as the cheapest known case until its *probe* measures it: a short
warm run after its warm-up (:func:`nsbench.bench.execute.probe_run`, :class:`Probe`), so the
first statement says "at least" and names how many such cases there are, and a revised one
(:meth:`Plan.revision`) follows as the timing starts, when every probe has come back. The
plan has three phases, said apart: preparing (references and warm-ups), timing, then the
bifurcation targets and the report; a compilation the compiled core still needs on this
machine is its own, said as it happens (:mod:`nsbench.compiling`).

The same costs weigh the steps of the progress bar (worker seconds on this machine now), so
that its estimate of the time left holds when long and short tasks mix; the bar gives a
time left only for the timing phase (:meth:`nsbench.progress.Progress.begin`), never
extrapolating from the warm-ups, whose time is mostly compilation and first use.

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

from nsbench.progress import clock

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

    def cheapest(self) -> tuple[float, float, float]:
        """The least warm-up, first timing task and later timed sample over the table's cases: what a case the
        table does not know costs at least (a plan counting it so is a lower bound)."""
        if not self.run:
            return 0.0, TASK_SECONDS, TASK_SECONDS
        return (
            min(self.warm_up.get(k, v) for k, v in self.run.items()),
            min(self.first.get(k, v) for k, v in self.run.items()),
            min(self.run.values()),
        )

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


#: Seconds of a worker per timing task beyond its runs (sending it, collecting the garbage, the row): the
#: cheapest task of the packaged table, a 50 ms sample, costs 58 ms.
TASK_SECONDS = 0.01


@dataclass(frozen=True)
class Probe:
    """The cost of a case the table does not know, from a short warm run after its warm-up.

    ``call``: seconds of one whole warm run over the case's span (the engine's run and what surrounds
    it, the warm integrator's set-up and the result), on this machine now, beside the load the run
    meets; ``wall``: of it, the engine's run clock, which sets the runs per timed sample.
    """

    call: float
    wall: float

    @classmethod
    def of(cls, warm: Any) -> "Probe | None":
        """The probe of a warm-up result (:class:`nsbench.bench.execute.WarmResult`), ``None`` without one.

        The probe ran ``probe_span`` of the span in ``probe_wall`` engine seconds and a call of
        ``probe_call``: the run scales with the span, the call's remainder (set-up, result) does not.
        """
        span, wall, call = (float(getattr(warm, k, math.nan)) for k in ("probe_span", "probe_wall", "probe_call"))
        if not (span > 0 and math.isfinite(wall) and math.isfinite(call) and wall >= 0):
            return None
        run = wall / span
        return cls(call=max(0.0, call - wall) + run, wall=run)

    def costs(self, min_sample_time: float) -> tuple[float, float]:
        """Worker seconds of the case's first timing task and of each later one.

        A sample is ``loops`` runs (:func:`nsbench.bench.timing.loops_for`), the first task adds the
        calibration run where it is not itself a sample, and half a run for the metrics (the order on a
        smooth arc reruns a part of the span).
        """
        from nsbench.bench.timing import loops_for

        loops = loops_for(self.wall, min_sample_time)
        sample = loops * self.call + TASK_SECONDS
        calibration = self.call if loops > 1 else 0.0
        return calibration + sample + 0.5 * self.call, sample


@dataclass
class Plan:
    """What a run will do and how long it should take (see :func:`plan`)."""

    n_cases: int
    n_runs: int  # timed samples (the warm-ups, calibration runs and references come on top)
    n_locations: int
    n_unknown: int  # tasks the cost table does not know (see ``unmeasured``)
    workers: int
    seconds: float  # the estimate on this machine now
    speed: float  # this machine's time for the calibration workload / the table's
    load: float  # other programs' runnable processes
    cores: int
    #: case label -> worker seconds of its warm-up and of one timing round, the mean of its rounds, on this
    #: machine now (the table's scaled to it, or the probe's)
    weights: dict[str, tuple[float, float]] = field(default_factory=dict)
    #: the estimate if every case's samples spread widely and each gets its extra samples, up to its
    #: ``max_repeats`` (what a machine whose load changes during the run may cost); NaN without a table
    seconds_most: float = math.nan
    #: labels of the cases neither the table nor a probe measured: counted at the cheapest measured case's
    #: costs, so that ``seconds`` is a lower bound
    unmeasured: tuple[str, ...] = ()
    n_probed: int = 0  # cases costed from their probes
    #: seconds of the phases: preparing (references, warm-ups), timing, then the targets and the report
    prepare: float = math.nan
    timing: float = math.nan
    after: float = math.nan

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
        n_targets = self.n_unknown - len(self.unmeasured)
        if n_targets:
            why += f"; {n_targets} target location(s) of unmeasured cost counted as typical"
        phases = (
            f"preparing {_duration(self.prepare)} (references and warm-ups, without a compilation the compiled "
            f"core may still need here), timing {_duration(self.timing)}, then {_duration(self.after)}"
        )
        if self.unmeasured:
            return (
                f"{head}; estimated at least {_duration(self.seconds)}: {phases} ({why}); "
                f"{len(self.unmeasured)} case(s) of unmeasured cost, counted as the cheapest measured one "
                "until a short probe after each one's warm-up measures it: a revised plan follows as the timing starts"
            )
        return f"{head}; estimated {_duration(self.seconds)}{self._most()}: {phases} ({why})"

    def _most(self, seconds: float | None = None) -> str:
        low = self.seconds if seconds is None else seconds
        most = low + self.seconds_most - self.seconds
        if not math.isfinite(most) or _duration(most) == _duration(low):
            return ""
        return (
            ", " + _duration(most).removesuffix(" (long)").replace("about ", "up to about ") + " if the timings spread"
        )

    def revision(self, elapsed: float) -> str:
        """The line said as the timing starts, ``elapsed`` seconds into the run: this plan (of the timing and
        what follows it, made with the probes) and the run's whole time."""
        total = elapsed + self.timing + self.after
        probed = f" with the probes of {self.n_probed} case(s)" if self.n_probed else ""
        if self.unmeasured:
            probed += f", {len(self.unmeasured)} case(s) without one counted as the cheapest measured"
        return (
            f"revised{probed}: {_duration(total)} in all{self._most(total)} "
            f"(timing {_duration(self.timing)} from now, then {_duration(self.after)}; {clock(elapsed)} so far)"
        )


def _duration(seconds: float) -> str:
    if seconds < 90:
        return f"about {max(5, round(seconds / 5) * 5):.0f} s"
    return f"about {seconds / 60:.0f} min" if seconds < 600 else f"about {seconds / 60:.0f} min (long)"


@dataclass
class _Work:
    """Worker seconds of the cases, by phase, on this machine now (see :func:`_case_work`)."""

    warm: float = 0.0
    timing: float = 0.0
    extra: float = 0.0  # the samples up to max_repeats
    unmeasured: list[str] = field(default_factory=list)
    probed: int = 0
    weights: dict[str, tuple[float, float]] = field(default_factory=dict)


def _case_work(cases: list, table: CostTable, suite: str | None, scale: float, probes: dict[str, Probe]) -> _Work:
    """The cases' work: the table's costs times ``scale`` (this machine's speed over a worker's share of the
    cores), a probe's as measured, the cheapest measured case's for the rest (a lower bound)."""
    work, cheapest = _Work(), table.cheapest()
    for c in cases:
        costs = table.costs(c.label, suite)
        probe = probes.get(c.label)
        if costs is not None:
            warm, first, later = (x * scale for x in costs)
        elif probe is not None:
            first, later = probe.costs(float(getattr(c, "min_sample_time", 0.05)))
            warm, work.probed = 0.0, work.probed + 1  # its warm-up has run: the probe came with it
        else:
            work.unmeasured.append(c.label)
            warm, first, later = (x * scale for x in cheapest)
        timing = first + (c.repeats - 1) * later
        work.weights[c.label] = (warm, timing / max(1, c.repeats))
        work.warm += warm
        work.timing += timing
        # a case whose samples spread gets more of them, one per round, up to max_repeats
        work.extra += max(0, (getattr(c, "max_repeats", None) or c.repeats) - c.repeats) * later
    return work


def _target_work(locations: list, table: CostTable, suite: str | None) -> tuple[float, int]:
    """Table seconds of the bifurcation-target locations and how many the table does not know (its median)."""
    known = list(table.target.values())
    typical = statistics.median(known) if known else (table.typical()[0] + table.typical()[2]) * 4
    seconds, unknown = 0.0, 0
    for loc in locations:
        cost = table.target_cost(location_label(loc.target.name, loc.integrator, loc.options), suite)
        if cost is None:
            unknown, cost = unknown + 1, typical
        seconds += cost
    return seconds, unknown


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
    probes: dict[str, Probe] | None = None,
) -> Plan:
    """The :class:`Plan` of a run of ``cases`` (suite cases) and ``locations`` (bifurcation-target locations).

    ``calibration`` (:func:`calibrate` here), ``load`` and ``cores`` default to
    this machine's; ``table`` to the packaged one. ``suite``: the suite's name, whose own task costs,
    overhead, report and reference times the table may hold (:attr:`CostTable.suites`). ``probes``: case
    label -> the :class:`Probe` of a case the table does not know (its warm-up done: it costs its timing).
    """
    cases, locations = list(cases), list(locations)
    table = table if table is not None else CostTable.packaged()
    cores = int(cores or os.cpu_count() or 1)
    n_workers = max(1, min(int(workers), cores))
    n_runs = sum(c.repeats for c in cases)
    if table is None:
        n = len(cases) + len(locations)
        return Plan(len(cases), n_runs, len(locations), n, n_workers, math.inf, math.nan, math.nan, cores)
    load = other_load(cores) if load is None else max(0.0, load)
    calibration = calibrate() if calibration is None else calibration
    # The calibration is the best of many 30 ms repeats: one of them runs within a scheduler time
    # slice even beside other programs, so it measures the core's own speed, not the share the load
    # leaves (measured on 2 cores kept busy by two loops, load 2.2: the best repeat took the idle
    # time). Scale the table by that speed, then by the share of the cores that the workers (or the
    # one process that starts them and writes the report) will get beside the load. A probe ran
    # beside that load already: its seconds stand as measured.
    share_one = min(1.0, cores / (load + 1.0))
    share_workers = min(1.0, cores / (load + n_workers))
    speed = calibration / table.calibration
    work = _case_work(cases, table, suite, speed / share_workers, probes or {})
    overhead, report_time, reference = table.fixed(suite)
    if (suite or "") not in table.suites and table.run:
        # a suite of one's own: the fixed costs of the measured run (worker starts, the barriers between phases,
        # an idle tail; its report's tables and figures) grow with its cases, so a suite of a few cases gets its
        # share of them (measured: an 18-case plug-in suite's report took 6 s where the full suite's takes 23 s)
        share = min(1.0, len(cases) / len(table.run))
        overhead, report_time = overhead * share, report_time * share
    target_work, unknown_targets = _target_work(locations, table, suite)
    prepare = (work.warm + n_references * reference * speed / share_workers) / n_workers
    prepare += overhead * speed / share_one
    timing = work.timing / n_workers
    after = target_work * speed / (n_workers * share_workers) + (report_time * speed / share_one if report else 0.0)
    seconds = prepare + timing + after
    return Plan(
        len(cases),
        n_runs,
        len(locations),
        len(work.unmeasured) + unknown_targets,
        n_workers,
        seconds,
        speed,
        load,
        cores,
        work.weights,
        seconds + work.extra / n_workers,
        tuple(work.unmeasured),
        work.probed,
        prepare,
        timing,
        after,
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
