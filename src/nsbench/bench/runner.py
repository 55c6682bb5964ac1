"""The suite runner: expand a suite into cases, run the missing ones, store each row as it
finishes, export the results.

The cases run in worker processes (:mod:`nsbench.workers.worker`, started with
:mod:`subprocess`, so the user's script is never re-imported), in the phases of
:mod:`nsbench.bench.scheduler`: references and warm-ups (compilation, first use)
first, then the timed repeats, never both at once. Even with ``workers=1`` the
cases run in a child process, so that a case past its time limit can be stopped
and a crash cannot end the run. The one exception: a component registered from
``__main__`` (a class defined in the script or notebook itself), which no other
process can import; then everything runs in this process, with a warning.

An interruption keeps every finished row; the next run with ``resume`` computes
only the rest.
"""

from __future__ import annotations

import os
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TextIO

import pandas as pd

from nsbench.bench import storage
from nsbench.bench.execute import run_case
from nsbench.workers.pool import importable
from nsbench.progress import Progress
from nsbench.bench.reference import (
    Reference,
    candidates,
    compute_reference,
    failed_status,
    load_reference,
    reference_key,
    save_reference,
)
from nsbench.bench.scheduler import ReferenceTask, Scheduler, TaskRecord
from nsbench.bench.suite import Case, Suite, load_suite
from nsbench.errors import ConfigError
from nsbench.status import ReferenceStatus, Status


@dataclass
class RunSummary:
    """What a run did, and whether every case and reference could be computed.

    Attributes
    ----------
    out
        The output directory.
    n_cases, n_resumed, n_computed
        Cases of the suite, already stored before this run, computed by this run.
    results
        Every stored row (this run's and the resumed ones).
    in_process
        The cases ran in this process (a component defined in ``__main__``), not in workers.
    timeline
        Every task of the workers (start, reference, warm-up, time) with its slot and times.
    bifurcations
        The bifurcation-target rows (:mod:`nsbench.bench.targets`), ``None`` if the suite names no target.
    """

    out: Path
    n_cases: int
    n_resumed: int
    n_computed: int
    results: pd.DataFrame
    in_process: bool = False
    timeline: list[TaskRecord] = field(default_factory=list)
    bifurcations: pd.DataFrame | None = None

    @property
    def crashed(self) -> pd.DataFrame:
        """Rows of cases whose worker process died."""
        return self.results[self.results["status"] == Status.CRASHED]

    @property
    def reference_failures(self) -> dict[str, str]:
        """Problem label -> why its reference run failed (raised, failed or crashed)."""
        if "reference_status" not in self.results:  # no row at all
            return {}
        bad = self.results[self.results["reference_status"].map(failed_status)]
        return dict(zip(bad["problem_label"], bad["reference_status"]))

    @property
    def ok(self) -> bool:
        """No case crashed and every reference that a candidate accepted was computed."""
        return not self.problems()

    def problems(self) -> list[str]:
        """One line per failure that makes the run not :attr:`ok`."""
        lines = [
            f"the reference of {label} could not be computed: {why}" for label, why in self.reference_failures.items()
        ]
        if self.bifurcations is not None and len(self.bifurcations):
            b = self.bifurcations
            bad = b[(b["reference_status"] != ReferenceStatus.OK) & (b["reference_status"] != "")]
            for name, why in dict(zip(bad["target"], bad["reference_status"])).items():
                lines.append(f"the reference of bifurcation target {name} could not be computed: {why}")
            crashed = b[b["status"] == Status.CRASHED]
            if len(crashed):
                lines.append(
                    f"{len(crashed)} bifurcation-target location(s) crashed their worker: "
                    + ", ".join(sorted(crashed["target"] + " " + crashed["integrator"]))
                )
        if not self.crashed.empty:
            lines.append(
                f"{len(self.crashed)} case(s) crashed their worker: "
                + ", ".join(sorted(self.crashed["problem_label"] + " " + self.crashed["integrator"]))
            )
        return lines


# ---------------------------------------------------------------------- the __main__ rule
def _components(cases: list[Case], suite: Suite) -> tuple[dict[str, dict[str, Any]], list[str]]:
    """Runtime registrations the workers can import, and those of the suite they cannot."""
    from nsbench import registry

    used = {
        "integrators": {c.integrator for c in cases} | set(suite.reference),
        "problems": {c.problem["name"] for c in cases},
    }
    shareable: dict[str, dict[str, Any]] = {}
    local = []
    for kind, objs in registry.runtime_components().items():
        shareable[kind] = {}
        for name, obj in objs.items():
            if importable(obj):
                shareable[kind][name] = obj
            elif name in used.get(kind, ()):
                local.append(f"{kind[:-1]} {name!r}")
    return shareable, local


# ---------------------------------------------------------------------- references
class _References:
    """The references of the pending cases: cached ones, the ones to compute, and rows waiting for them."""

    def __init__(self, suite: Suite, pending: list[Case], out: Path) -> None:
        self.cands = candidates(suite.reference)
        self.suite, self.dir = suite, out / "references"
        self.known: dict[str, Reference] = {}
        self.todo: dict[str, ReferenceTask] = {}
        for case in pending:  # each over its case's span (a problem may have its own, Suite.problem_spans)
            key = self.key(case)
            if key in self.known or key in self.todo:
                continue
            cached = load_reference(self.dir, key)
            if cached is not None and not cached.failed:
                self.known[key] = cached
            else:
                self.todo[key] = ReferenceTask(key, case.problem, self.cands, case.t0, case.t_end, suite.dense_points)

    def key(self, case: Case) -> str:
        return reference_key(case.problem, self.cands, case.t0, case.t_end, self.suite.dense_points)

    def of(self, case: Case) -> Reference:
        return self.known[self.key(case)]

    def add(self, key: str, ref: Reference) -> None:
        if not ref.failed:  # a failure is not cached: the next run tries again
            save_reference(self.dir, ref)
        self.known[key] = ref


def _with_reference(row: dict[str, Any], ref: Reference) -> dict[str, Any]:
    """Fill the reference columns of a row built without them (failures, crashes)."""
    import json

    if not row.get("reference_status"):
        row.update(reference_config=json.dumps(ref.config, sort_keys=True, default=float), **ref.columns())
    return row


def _warn_other_version(out: Path, prov: dict[str, Any], err: TextIO) -> None:
    """One line when the stored cases come from another nsbench (version or commit): resuming mixes them."""
    try:
        old = storage.read_provenance(out)
    except ConfigError:  # truncated or edited: this run writes it again from the stored cases
        print(
            f"nsbench: warning: {out / 'provenance.json'} is damaged; the stored cases are kept and "
            "checked as usual, and the file is written again at the end of this run",
            file=err,
        )
        return
    keys = ("version_nsbench", "git_commit")
    if old and any(old.get(k) != prov.get(k) for k in keys if old.get(k) is not None):
        was = ", ".join(f"{k} {old.get(k)}" for k in keys if old.get(k) is not None)
        print(
            f"nsbench: warning: {out} holds cases of another nsbench ({was}); resuming keeps them: "
            "use --fresh to compute every case with this one",
            file=err,
        )


# ---------------------------------------------------------------------- running
def run_suite(
    suite: Suite | str | Path | dict,
    out: str | Path,
    *,
    workers: int | None = None,
    resume: bool = True,
    progress: bool = True,
    stream: TextIO | None = None,
    provenance_extra: dict[str, Any] | None = None,
    plan: bool | None = None,
) -> RunSummary:
    """Run every case of ``suite`` that ``out`` does not hold yet, and export the results.

    Parameters
    ----------
    suite
        A :class:`Suite`, a TOML path, a dict, or ``'default'``.
    out
        Output directory (see :mod:`nsbench.bench.storage` for its layout).
    workers
        Worker processes, a whole number from 1 to 1024 (default: all cores). With 1,
        the cases still run in one child process (so that the time limit can stop them).
    resume
        Keep the cases already stored in ``out`` (default); ``False`` discards them first.
    progress, stream
        Show a progress bar and warnings on ``stream`` (default stderr).
    plan
        Say first, in one line on ``stream``, what the run will do and how long it should take
        (:mod:`nsbench.bench.estimate`; default: as ``progress``). The commands always say it,
        ``--no-progress`` or not.

    Returns
    -------
    RunSummary
        Counts, the results, and :attr:`RunSummary.ok`: ``False`` when a case
        crashed or a reference could not be computed (the CLI then exits with 1).
    """
    from nsbench.workers.jobs import check_count
    from nsbench.provenance import provenance

    check_count("workers", workers, 1)
    started = time.monotonic()
    err = stream or sys.stderr
    suite = load_suite(suite)
    out = storage.check_out(out)
    if not resume:
        storage.clear_cases(out)
    storage.make_out(out)
    cases = list({c.case_id: c for c in suite.cases()}.values())
    prov = {**provenance(), "suite": suite.to_dict(), **(provenance_extra or {})}
    # the integrators this run selected: a report counts the cases the run planned, not those the suite
    # would select among the integrators registered when the report is written (a plug-in added later)
    prov["integrators_selected"] = sorted({c.integrator for c in cases})
    for name, reason in suite.unavailable().items():
        prov.setdefault("unavailable_integrators", {})[name] = reason
        print(f"nsbench: warning: integrator {name!r} left out: {reason}", file=err)
    # named in one line each, then computed again; a row must hold the parameters its id stands for
    storage.discard_damaged(out, err, expect={c.case_id: _identity(c) for c in cases})
    done = storage.done_ids(out)
    if done:
        _warn_other_version(out, prov, err)
    # a run interrupted between timing rounds left successful rows with fewer runs: their samples are
    # kept, and only the rounds they lack are timed (after a warm-up, as any case)
    short = storage.short_of_repeats(out, {c.case_id: c.repeats for c in cases if c.case_id in done})
    done -= short.keys()
    pending = [c for c in cases if c.case_id not in done]
    pending.sort(key=lambda c: -c.level)  # tight (slow) levels first: the best start for the balance
    shareable, local = _components(pending, suite)
    if local:  # run in this process (run_case): a case is timed from its first round, its stored samples not kept
        short = {}
    if len(pending) < len(cases) or short:  # say in words what a resumed run does, before it does it
        kept = f" ({len(short)} of them keep the samples of their finished rounds)" if short else ""
        print(
            f"nsbench: resuming {out}: {len(pending)} of {len(cases)} cases to run{kept}, "
            f"{len(cases) - len(pending)} stored (--fresh starts over)",
            file=err,
            flush=True,
        )
    rounds_left = {
        c.case_id: c.repeats - int(short[c.case_id]["n_repeats"]) if c.case_id in short else c.repeats for c in pending
    }
    workers = max(1, int(workers or os.cpu_count() or 1))
    prov["workers"] = 1 if local else min(workers, max(1, len(pending)))
    refs = _References(suite, pending, out)
    # One step per reference, and per case one for its first warm-up and one per timing round,
    # each weighted by its expected seconds (so the time left holds when long and short tasks mix).
    costs = _Costs.of(
        suite, pending, len(refs.todo), prov["workers"], out, err, progress if plan is None else plan, resume
    )
    warm_weight, weight, ref_weight = costs.warm, costs.round, costs.ref
    bar = Progress(
        len(refs.todo) * ref_weight + sum(warm_weight(c) + rounds_left[c.case_id] * weight(c) for c in pending),
        label="cases",
        stream=err,
        enabled=progress,
        weighted=True,
    )
    if not local:  # the warm-ups are mostly compilation and first use: no time left from them
        bar.hold("preparing", len(refs.todo) + len(pending))
    waiting: dict[str, list[tuple[dict[str, Any], int]]] = {}

    def store(row: dict[str, Any], stored: bool = False, steps: int = 1) -> None:
        case = row_case[row["case_id"]]
        key = refs.key(case)
        if key not in refs.known:  # a row from the warm-ups can come before its reference
            waiting.setdefault(key, []).append((row, steps))
            return
        if not stored:
            storage.append_row(out, _with_reference(row, refs.known[key]), prov)
        bar.update(steps * weight(case), case.label)

    def reference_done(key: str, ref: Reference) -> None:
        refs.add(key, ref)
        bar.update(ref_weight, "reference", tick=True)
        for row, steps in waiting.pop(key, []):
            store(row, steps=steps)

    def timing_starts(warm: dict[str, Any]) -> None:
        """Every warm-up and probe is done: re-plan the timing with the probes, and count it in the bar."""
        left = [row_case[i] for i in warm]
        revised = costs.revise(left, warm)
        bar.reweigh(sum(rounds_left[c.case_id] * weight(c) for c in left))
        bar.begin(1.0 / prov["workers"] if costs.plan is not None else None)  # a weight is a worker's seconds
        if revised is not None:
            bar.say(f"nsbench: suite {suite.name!r}: {revised.revision(time.monotonic() - started)}")

    row_case = {c.case_id: c for c in pending}
    timeline: list[TaskRecord] = []
    loads: list[float] = []
    try:
        if local:
            print(
                f"nsbench: warning: {', '.join(local)} is defined in __main__, which worker processes "
                "cannot import: running every case in this process (no parallelism, time limit checked "
                "between arcs only, a crash ends the run); define it in an importable module to use workers",
                file=err,
            )
            _run_in_process(pending, refs, suite.name, store, reference_done, bar, warm_weight, loads)
        elif pending:
            scheduler = Scheduler(
                pending,
                list(refs.todo.values()),
                refs.of,
                reference_done,
                store,
                _hello(shareable, out, prov),
                prov["workers"],
                suite.name,
                on_warm=lambda case: bar.update(warm_weight(case), case.label, tick=True),
                on_phase=bar.phase,
                on_extra=lambda case: bar.grow(weight(case)),
                resumed=short,
                probe={c.case_id for c in pending if c.label in costs.unmeasured},
                on_timing=timing_starts,
            )
            timeline = scheduler.timeline
            loads = scheduler.loads
            scheduler.run()
    finally:
        bar.close()
        if timeline:  # kept after an interruption too: where did the time go
            storage.write_timeline(out, timeline)
    kept_timing = (
        storage.read_provenance(out, damaged_ok=True).get("timing") if not loads else None
    )  # nothing timed: keep the last
    prov["timing"] = kept_timing or timing_provenance(suite, prov["workers"], loads)
    results = storage.export(out, prov) if (out / "cases").exists() else storage.to_frame([])
    bifurcations = None
    if suite.target_list():  # the bifurcation targets: after every case, never while a case is timed
        from nsbench.bench.targets import run_targets

        if progress:
            print(
                f"nsbench: bifurcation targets: {len(suite.target_list())} target(s), each located by every "
                "configuration with its own simulations",
                file=err,
                flush=True,
            )
        bifurcations = run_targets(
            suite,
            out,
            prov,
            workers=workers,
            in_process=bool(local),
            components=shareable,
            resume=resume,
            stream=err,
            progress=progress,
        )
    summary = RunSummary(
        out=out,
        n_cases=len(cases),
        n_resumed=len(cases) - len(pending),
        n_computed=len(pending),
        results=results,
        in_process=bool(local),
        timeline=timeline,
        bifurcations=bifurcations,
    )
    for line in summary.problems():
        print(f"nsbench: warning: {line}", file=err)
    return summary


def _identity(case: Case) -> dict[str, Any]:
    """The columns of a stored row that say which computation it is (see ``execute.base_row``)."""
    from nsbench.bench.keys import jsonable

    return {
        "problem_config": jsonable(case.problem),
        "integrator": case.integrator,
        "options": jsonable(case.options),
        "t0": float(case.t0),
        "t_end": float(case.t_end),
    }


def _hello(components: dict[str, dict[str, Any]], out: Path, prov: dict[str, Any]):
    from nsbench.workers.pool import hello

    return hello(components, out, prov)


@dataclass
class _Costs:
    """The weights of the progress bar's steps, each the expected worker seconds on this machine now (a
    case's warm-up, one of its timing rounds, a reference; 1 each without a plan), and the plan they come
    from, revised by the probes as the timing starts (:meth:`revise`)."""

    plan: Any = None  # the estimate.Plan said first, None when nothing was planned
    weights: dict[str, tuple[float, float]] = field(default_factory=dict)
    ref: float = 1.0
    again: dict[str, Any] = field(default_factory=dict)  # the arguments of the revised plan

    @property
    def unmeasured(self) -> set[str]:
        return set(self.plan.unmeasured) if self.plan is not None else set()

    def warm(self, case: Case) -> float:
        return self.weights.get(case.label, (1.0, 1.0))[0]

    def round(self, case: Case) -> float:
        return self.weights.get(case.label, (1.0, 1.0))[1]

    @classmethod
    def of(
        cls,
        suite: Suite,
        pending: list[Case],
        n_references: int,
        workers: int,
        out: Path,
        err: TextIO,
        announce: bool,
        resume: bool = True,
    ) -> "_Costs":
        """With ``announce``, say first what the run will do and how long it should take
        (:mod:`nsbench.bench.estimate`); the weights come from that plan."""
        if not (announce and pending):
            return cls()
        from nsbench.bench import estimate
        from nsbench.bench.targets import done_rows, locations

        table = estimate.CostTable.packaged()
        done = done_rows(out) if suite.target_list() and resume else set()  # a fresh run locates every target again
        todo = [loc for loc in locations(suite) if loc.row_id not in done] if suite.target_list() else []
        plan = estimate.plan(pending, todo, n_references, workers, table=table, suite=suite.name)
        print(f"nsbench: suite {suite.name!r}: {plan.statement()}", file=err, flush=True)
        if table is None:
            return cls(plan)
        share = min(1.0, plan.cores / (plan.load + plan.workers))  # as the plan's for the workers
        # the revision keeps this plan's machine: the load average then counts the run's own workers
        again = dict(
            locations=todo,
            workers=workers,
            table=table,
            calibration=plan.speed * table.calibration,
            load=plan.load,
            cores=plan.cores,
            suite=suite.name,
        )
        return cls(plan, dict(plan.weights), table.fixed(suite.name)[2] * plan.speed / share, again)

    def revise(self, left: list[Case], warm: dict[str, Any]):
        """The plan of the timing of ``left`` (and what follows it) with the probes in ``warm`` (case id ->
        its first warm-up): its weights replace the planned ones; the plan, where the first one had
        unmeasured cases (else ``None``: the first plan stands)."""
        if self.plan is None or not self.again:
            return None
        from nsbench.bench import estimate

        probes = {}
        for case in left:
            probe = estimate.Probe.of(warm[case.case_id])
            if probe is not None and case.label in self.unmeasured:
                probes[case.label] = probe
        revised = estimate.plan(left, probes=probes, **self.again)
        for label, (_, timing) in revised.weights.items():
            self.weights[label] = (self.weights.get(label, (0.0, 0.0))[0], timing)
        return revised if self.plan.unmeasured else None


def _run_in_process(
    pending: list[Case], refs: _References, suite: str, store, reference_done, bar, warm_weight, loads: list[float]
) -> None:
    """The fallback without workers: references, then each case warmed up and timed in turn."""
    for key, task in list(refs.todo.items()):
        reference_done(key, compute_reference(task.problem, task.candidates, task.t0, task.t_end, task.dense_points))
    for case in pending:
        bar.update(warm_weight(case), case.label)  # its warm-up step
        loads.extend(load_average())
        store(run_case(case, refs.of(case), suite), steps=case.repeats)


def load_average() -> list[float]:
    """``[the 1-minute load average]``, or ``[]`` where the platform has none."""
    try:
        return [float(os.getloadavg()[0])]
    except (AttributeError, OSError):  # pragma: no cover - platforms without a load average
        return []


def timing_provenance(suite: Suite, workers: int, loads: list[float]) -> dict[str, Any]:
    """How the cases were timed and how busy the machine was meanwhile (``provenance['timing']``).

    ``load`` summarises the 1-minute load average sampled each time a timed
    sample was sent to a worker (empty when this run timed nothing, e.g. a
    rerun that only rewrites the report): it counts the workers' own processes
    too, so ``load - workers`` is what other programs ran.
    """
    import statistics

    info: dict[str, Any] = {
        "samples": suite.repeats,
        "min_sample_time": suite.min_sample_time,
        "workers": workers,
        "cores": os.cpu_count(),
    }
    if loads:
        info["load"] = {"min": min(loads), "median": statistics.median(loads), "max": max(loads), "n": len(loads)}
    return info
