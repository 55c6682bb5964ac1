"""The ``nsbench bifurcation`` command as a function: :func:`run_sweeps` runs a :class:`SweepRequest`.

One request (:class:`nsbench.bifurcation.request.SweepRequest`, checked at its construction) in,
one :class:`SweepOutcome` out: the sweep folder, each integrator's features, candidate points and
diagram, and the one line saying why the command exits 1 (a plug-in problem's factory failed, or
values failed or fell short). Refused input raises a :class:`~nsbench.errors.ConfigError` before
the first value is computed (the command exits 2). The command line
(:mod:`nsbench.cli.bifurcation`) maps its arguments onto the request and prints the outcome;
the progress of the sweep and what it wrote are printed here, as they come.

The local worker processes start first (:func:`run_sweeps`), while this process checks the
request against the problem and the integrators: they import nsbench and load the compiled core
meanwhile. Every import of this module that is not light is deferred to the function that needs it.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from nsbench.bifurcation.request import SweepRequest
from nsbench.errors import ConfigError

if TYPE_CHECKING:  # pragma: no cover
    import pandas as pd

    from nsbench.bifurcation.sweep import SweepSpec

#: Step budget of one value's run (nsbench.bifurcation.sweep gives run_hybrid max_steps=50_000_000).
SWEEP_MAX_STEPS = 50_000_000
#: What the command writes in a sweep folder besides the store (``meta.json``, ``points/``).
WRITTEN = (
    "features.csv",
    "candidates.csv",
    "compare.md",
    "agreement.csv",
    "diagram.*",
    "locus_*",
    "portrait_*",
    "worker-errors.log",
)


@dataclass(frozen=True)
class IntegratorSweep:
    """One integrator's sweep, computed and written to :attr:`folder`."""

    integrator: str
    folder: Path
    #: The stored section points (:func:`nsbench.bifurcation.parallel.run_sweep`).
    points: pd.DataFrame
    #: One row per value (``features.csv``, :func:`nsbench.bifurcation.detect.classify`).
    features: pd.DataFrame
    #: Candidate bifurcation points (``candidates.csv``), refined if asked.
    candidates: pd.DataFrame
    #: The diagram's files, one per format.
    diagram: tuple[Path, ...]
    seconds: float
    values: int
    #: Values that failed or ended incomplete (their status is in ``features.csv``).
    failed: int


@dataclass(frozen=True)
class SweepOutcome:
    """What :func:`run_sweeps` did: the folder, each integrator's sweep, or why nothing ran."""

    #: The results folder (``None`` when nothing was run).
    folder: Path | None
    sweeps: tuple[IntegratorSweep, ...] = ()
    #: ``compare.md`` of several integrators.
    comparison: Path | None = None
    #: A plug-in problem's factory that failed in its probe (one line): nothing was run.
    fault: str | None = None

    @property
    def failure(self) -> str | None:
        """One line saying why the command fails (exit 1), or ``None``."""
        if self.fault is not None:
            return f"{self.fault}; nothing was run"
        short = [s for s in self.sweeps if s.failed]
        if not short:
            return None
        detail = ", ".join(f"{s.integrator} {s.failed} of {s.values}" for s in short)
        return f"values failed or incomplete ({detail}); each value's status is in the sweep's features.csv"

    @property
    def exit_code(self) -> int:
        """0, or 1: nothing ran, or the diagrams are written but some values fell short (as bench
        exits 1 for a failed case)."""
        return 0 if self.failure is None else 1


def run_sweeps(request: SweepRequest) -> SweepOutcome:
    """Run the sweep of ``request`` for each of its integrators; write tables, diagrams, portraits.

    Parameters
    ----------
    request
        The sweep, checked at its construction.

    Returns
    -------
    SweepOutcome
        The folder and each integrator's sweep; :attr:`SweepOutcome.failure` names what failed.

    Raises
    ------
    ConfigError
        What the request asks cannot be run (an option no integrator has, a fixed step the span
        cannot take, a block pair or portrait value the problem has not, an unwritable folder, a
        section or integrator the problem refuses, an unreachable Dask scheduler): before any
        value is computed.
    """
    # the local workers first: they start while the request is checked against the problem
    pool = _start_workers(request.workers) if request.dask is None else None
    try:
        return _run(request)
    except BaseException as exc:
        if pool is not None:  # started for this sweep, which failed: they are not kept
            from nsbench.workers.jobs import drop_shared

            # input refused before any value ran: end them at once, not after their imports
            drop_shared(pool, at_once=isinstance(exc, ConfigError))
        raise


def _start_workers(workers: int | None):
    """The local worker processes of the sweep, started now: they import nsbench and load the
    compiled core while this process prepares (about a second of a short sweep's wall time).
    Returns the pool if this call started them, ``None`` if they were running (kept from an
    earlier sweep of this process)."""
    from nsbench.workers.jobs import Job, default_workers, shared_pool  # no more: the sooner they start, the better

    pool = shared_pool(workers or default_workers())
    return pool if pool.start(Job("prepare", "nsbench.bifurcation.parallel:prepare_job")) else None


def _run(request: SweepRequest) -> SweepOutcome:
    from nsbench.bifurcation import figures
    from nsbench.bifurcation.cluster import connect
    from nsbench.bifurcation.parallel import default_workers

    fault = _probe_factory(request, dask=request.dask is not None)
    if fault is not None:
        return SweepOutcome(None, fault=fault)
    specs = _specs(request)
    pair = _check_blocks(request, specs)
    base = _folder(request, specs)
    # every integrator refuses now what it would refuse later: not after a whole sweep. What needs no
    # compiled code first (sections, whole-system methods), for every integrator, then the set-ups,
    # which may evaluate the problem's compiled field: no refusal follows a compile notice
    for spec in specs:
        spec.check_section()
    for spec in specs:
        spec.check_integrator(setup=False)
    for spec in specs:
        spec.check_integrator()
    # a closed port, a bad address or a cluster without workers: one line now, not a hang later
    dask = connect(request.dask) if request.dask is not None else None
    local_workers = request.workers or default_workers()  # refinements and portraits reuse the sweep's kept workers
    figures.preload(request.formats)  # while the values are computed
    sweeps = []
    for spec in specs:
        from nsbench.bench.storage import file_name  # plug-in names are data: checked before they name a folder

        out = base if len(specs) == 1 else base / file_name(spec.integrator, "integrator name")
        sweeps.append(_sweep(request, spec, out, dask, pair, local_workers))
    comparison = None
    if len(specs) > 1:
        from nsbench.bifurcation import compare

        frames = {s.integrator: s.points for s in sweeps}
        comparison = base / "compare.md"
        comparison.write_text(compare.report(frames, {s.integrator: s.seconds for s in sweeps}))
        compare.agreement(frames).to_csv(base / "agreement.csv", index=False)
        print(f"comparison -> {comparison}")
    if dask is not None:
        dask.close()
    return SweepOutcome(base, tuple(sweeps), comparison)


def _probe_factory(request: SweepRequest, dask: bool) -> str | None:
    """A plug-in problem built first at both ends of the sweep in a worker, under ``setup_limit``
    (:func:`nsbench.factory_probe.probe_problem`): a factory that loops or raises is one line, not a
    hang or a traceback of this process. ``None`` when it built (or the problem is built-in)."""
    from nsbench.factory_probe import is_plugin_problem, probe_problem

    if not is_plugin_problem(request.problem):
        return None
    name, start, stop, _ = request.sweep
    calls = [{"case": request.case, **request.params, name: value} for value in (start, stop)]
    pool = None
    if not dask:  # the sweep's own kept workers, started already: no other to start
        from nsbench.workers.jobs import default_workers, shared_pool

        pool = shared_pool(request.workers or default_workers())
    return probe_problem(request.problem, calls, request.setup_limit, pool)


def _problem_at(request: SweepRequest):
    """``build(name, value, params)``: the request's problem with ``name = value`` over ``params``."""
    from nsbench.problems import get_problem

    def build(name, value, params):
        return get_problem(request.problem, case=request.case, **{**params, name: value})

    return build


def _specs(request: SweepRequest) -> list[SweepSpec]:
    """One spec per integrator, its options those it has; a fixed step the span or the force cannot
    take is refused now, in one line, not in a sweep of failures."""
    from nsbench.bifurcation.sweep import SweepSpec, default_section
    from nsbench.inputs import check_fixed_step
    from nsbench.integrators import get_integrator, integrator_class

    probe = _problem_at(request)
    names, extra = request.integrators, request.options
    name, start, stop, count = request.sweep
    specs = []
    for integrator in names:
        if integrator is None:
            integrator = "exact" if probe(name, start, {}).is_linear else "henon-rk4"
        allowed = integrator_class(integrator).options
        unknown = [k for k in extra if all(k not in integrator_class(n).options for n in names if n)]
        if unknown:
            raise ConfigError(f"option(s) {', '.join(unknown)} belong to none of the integrators")
        section = request.section or default_section(
            probe(name, start, request.params), probe(name, stop, request.params)
        )
        specs.append(
            SweepSpec(
                problem=request.problem,
                case=request.case,
                name=name,
                start=start,
                stop=stop,
                count=count,
                integrator=integrator,
                options={k: v for k, v in extra.items() if k in allowed},
                section=section,
                transient=request.transient,
                record=request.record,
                window=request.window,
                params=request.params,
            )
        )
    for spec in specs:
        integ = get_integrator(spec.integrator, **spec.options)
        span = spec.transient + spec.record_window
        for value in (spec.start, spec.stop):
            check_fixed_step(
                integ,
                spec.problem_at(value),
                span,
                f"a value's run over {span:g} (transient and window)",
                SWEEP_MAX_STEPS,
                given=type(integ).capabilities.step_option in spec.options,
            )
    return specs


def _check_blocks(request: SweepRequest, specs: list[SweepSpec]) -> tuple[int, int]:
    """The block pair of the locus and portraits, checked on the problem with every portrait value:
    a bad one fails now, not after the sweep."""
    from nsbench.problems.base import problem_traits

    given, problem_name = request.pair_text, request.problem
    pair = request.pair or (1, 2)
    first = specs[0]
    n_blocks = getattr(first.problem_at(first.start), "n_blocks", None)
    if given is not None and n_blocks is None:
        raise ConfigError(f"--pair {given} names blocks of a friction oscillator; {problem_name} has none")
    if given is not None and n_blocks is not None and any(not 1 <= b <= n_blocks for b in pair):
        raise ConfigError(f"--pair {given}: {problem_name} has blocks 1 to {n_blocks}")
    low, high = sorted((first.start, first.stop))
    for value in request.portraits:
        if not low <= value <= high:
            raise ConfigError(
                f"--portrait {value:g} lies outside the swept range {first.name} = {low:g} to {high:g}; "
                "give a value inside it"
            )
        problem = first.problem_at(value)
        if not problem_traits(problem).belt_blocks:
            raise ConfigError(
                "--portrait draws the locus of sticking phase of a friction oscillator (blocks on a belt); "
                f"{problem_name} does not declare the belt_blocks trait"
            )
        if any(not 1 <= b <= problem.n_blocks for b in pair):
            raise ConfigError(f"--pair {given or '1,2'}: {problem_name} has blocks 1 to {problem.n_blocks}")
    return pair


def _folder(request: SweepRequest, specs: list[SweepSpec]) -> Path:
    """The results folder, checked writable; the tables and figures written there replace what is
    there: never through a link (one folder per integrator of a comparison)."""
    from nsbench.bench.storage import file_name
    from nsbench.files import refuse_links
    from nsbench.inputs import check_output_dir

    first = specs[0]
    blocks = f"-n{int(first.params['n'])}" if "n" in first.params else ""
    case = f"-case{first.case}" if case_text(first) else ""
    base = Path(request.out or f"bifurcation/{request.problem}{blocks}{case}-{first.name}")
    check_output_dir(base, "--out")
    members = tuple(file_name(s.integrator, "integrator name") for s in specs) if len(specs) > 1 else ()
    refuse_links(base, WRITTEN + members)
    for name in members:
        refuse_links(base / name, WRITTEN)
    return base


def case_text(spec: Any) -> str:
    """``' case 1'`` for a problem with presets, ``''`` for one without (the bouncing ball has no case 1)."""
    return f" case {spec.case}" if spec.problem_at(spec.start).cases else ""


def _sweep(
    request: SweepRequest, spec: SweepSpec, out: Path, dask: Any, pair: tuple[int, int], workers: int
) -> IntegratorSweep:
    """One integrator's sweep: its values, features, candidates (refined if asked), diagram and portraits."""
    from nsbench.bifurcation import detect, figures
    from nsbench.bifurcation.parallel import run_sweep
    from nsbench.bifurcation.storage import SweepStore, points_summary
    from nsbench.bifurcation.sweep import OK_STATUSES
    from nsbench.problems.base import problem_traits

    tic = time.perf_counter()
    frame = run_sweep(
        spec,
        out,
        workers=request.workers,
        dask=dask,
        progress=request.progress,
        fresh=request.fresh,
        point_limit=request.point_limit,
        setup_limit=request.setup_limit,
    )
    seconds = time.perf_counter() - tic
    feats = detect.classify(frame)
    cands = detect.candidates(feats, problem_traits(spec.problem_at(spec.start)).belt_blocks)
    if request.refine and len(cands):
        _refine(request, spec, out, cands, workers)
    feats.to_csv(out / "features.csv", index=False)
    cands.to_csv(out / "candidates.csv", index=False)
    summary = points_summary(frame)
    title = (
        f"{spec.problem}{case_text(spec)}: {spec.name} sweep, {spec.integrator}, "
        f"{spec.section}, transient {spec.transient:g}, {spec.record} points"
    )
    written = figures.diagram(frame, out / "diagram", title=title, candidates=cands, formats=request.formats)
    for value in request.portraits:
        _portrait(spec, value, out, request.formats, pair, request.point_limit, workers, request.setup_limit)
    n_bad = int((~summary["status"].isin(OK_STATUSES)).sum())
    done = IntegratorSweep(spec.integrator, out, frame, feats, cands, tuple(written), seconds, len(summary), n_bad)
    _say(done, spec)
    SweepStore(out)  # the folder is complete and readable
    return done


def _refine(request: SweepRequest, spec: SweepSpec, out: Path, cands: pd.DataFrame, workers: int) -> None:
    """Each candidate refined by bisection in a supervised worker (a plug-in that hangs or dies
    there costs that refinement only); the ``refined_*`` columns added to ``cands``."""
    from nsbench.bifurcation.parallel import supervised
    from nsbench.workers.jobs import WORKER_LOG, WorkerLog

    refined = []
    log = WorkerLog(out / WORKER_LOG, f"the refinements of the {spec.name} sweep")
    for r in cands.itertuples():
        job = (spec.to_dict(), r.left, r.right, r.kind, request.point_limit, request.setup_limit)
        found, why = supervised("refine_job", job, workers, log)
        if found is None:
            print(f"  refinement of the {r.kind} change in [{r.left:.6g}, {r.right:.6g}] failed: {why}")
            found = {"left": math.nan, "right": math.nan, "value": math.nan}
        refined.append(found)
    log.report()
    cands["refined_left"] = [r["left"] for r in refined]
    cands["refined_right"] = [r["right"] for r in refined]
    cands["refined_value"] = [r["value"] for r in refined]


def _say(done: IntegratorSweep, spec: SweepSpec) -> None:
    """The lines of one integrator's sweep: its values, its diagram, its candidate points."""
    cands = done.candidates
    print(
        f"{done.integrator}: {done.values} values ({done.failed} failed or incomplete) in {done.seconds:.1f} s "
        f"-> {done.folder}"
    )
    print(f"  diagram -> {done.diagram[0]}")
    if len(cands):
        print(f"  candidate bifurcation points ({len(cands)}):")
        for r in cands.itertuples():
            ref = f" refined {r.refined_value:.6g}" if "refined_value" in cands else ""
            print(f"    {spec.name} in [{r.left:.6g}, {r.right:.6g}]{ref}: {r.kind}: {r.description}")
    elif done.failed == done.values:
        print("  no value ended in success or rest: nothing to read along the sweep")
    else:
        print("  no qualitative change along the sweep")


def _portrait(
    spec: SweepSpec,
    value: float,
    out: Path,
    formats,
    pair: tuple[int, int] = (1, 2),
    point_limit: float | None = None,
    workers: int = 1,
    setup_limit: float | None = None,
) -> None:
    from nsbench.bifurcation import figures
    from nsbench.bifurcation.parallel import supervised

    tag = f"{spec.name}_{value:g}"
    # the run in a supervised worker, the figures here: a plug-in's fault costs this portrait only
    from nsbench.workers.jobs import SETUP_LIMIT, WORKER_LOG, WorkerLog

    log = WorkerLog(out / WORKER_LOG, f"the locus and portrait at {tag}")
    run, why = supervised(
        "locus_job",
        (spec.to_dict(), value, pair, point_limit, SETUP_LIMIT if setup_limit is None else setup_limit),
        workers,
        log,
    )
    log.report()
    if run is None:
        print(f"  locus and portrait at {tag} failed: {why}")
        return
    figures.locus(run, out / f"locus_{tag}", title=f"locus of sticking phase, {tag}", formats=formats)
    figures.portrait(run, out / f"portrait_{tag}", title=f"{spec.problem}{case_text(spec)}, {tag}", formats=formats)
    print(f"  locus and portrait at {tag} -> {out}")
