"""``nsbench bifurcation PROBLEM --case N --sweep NAME=START:STOP:COUNT ...``: a bifurcation sweep."""

from __future__ import annotations

import argparse
import math
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from nsbench.bifurcation.cluster import connect as connect_dask
from nsbench.cli._common import shared_params
from nsbench.inputs import check_fixed_step, check_output_dir, parse_count, parse_number, parse_options, parse_real
from nsbench.errors import ConfigError


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


def add_parser(sub) -> None:
    p = sub.add_parser("bifurcation", help="sweep one parameter and draw the bifurcation diagram")
    p.add_argument("problem", metavar="PROBLEM", help="registered problem, e.g. two-dof")
    p.add_argument("--case", default="1", help="preset 1..4 (default 1)")
    p.add_argument(
        "--sweep",
        required=True,
        metavar="NAME=START:STOP:COUNT",
        help="swept dimensionless parameter (v0, omega_r, inv_omega_r, r_f, F, Omega, h1, ...)",
    )
    p.add_argument(
        "--param", action="append", default=[], metavar="NAME=VALUE", help="fixed parameter override (repeatable)"
    )
    p.add_argument("--n", default=None, help="number of blocks of a chain problem (same as --param n=N)")
    p.add_argument(
        "--integrator",
        action="append",
        default=[],
        metavar="NAME",
        help="registered integrator; repeat to compare several (default: exact for "
        "linear problems, henon-rk4 otherwise)",
    )
    p.add_argument("--h", default=None, help="step size of fixed-step integrators")
    p.add_argument(
        "--option",
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="integrator option (repeatable; applies to every integrator that has it)",
    )
    p.add_argument(
        "--section",
        default=None,
        metavar="SECTION",
        help="recorded points: peaks, strobe, stick, mapping, or event:KIND (the states at the problem's KIND "
        "events); default: strobe if forced, else peaks",
    )
    p.add_argument("--transient", default="1500", help="time integrated before recording (default 1500)")
    p.add_argument("--record", default="100", help="section points recorded per value (default 100)")
    p.add_argument(
        "--window", default=None, help="longest recording time after the transient (default 40 * record + 400)"
    )
    grp = p.add_mutually_exclusive_group()
    grp.add_argument("--workers", default=None, help="local processes (default: all cores)")
    grp.add_argument("--dask", default=None, metavar="ADDRESS", help="Dask scheduler, e.g. tcp://host:8786")
    p.add_argument("--out", default=None, help="results folder (default bifurcation/<problem>[-n<N>]-case<C>-<NAME>)")
    p.add_argument(
        "--fresh",
        action="store_true",
        help="discard the sweep stored in --out (default: resume, computing only missing values)",
    )
    p.add_argument("--refine", action="store_true", help="refine candidate bifurcation points by bisection")
    p.add_argument(
        "--portrait",
        action="append",
        default=[],
        metavar="VALUE",
        help="also draw the locus of sticking phase and phase portraits at this value, inside the swept "
        "range (repeatable)",
    )
    p.add_argument(
        "--pair",
        default=None,
        metavar="A,B",
        help="two different blocks whose positions the locus and portraits show (default 1,2)",
    )
    p.add_argument("--formats", default="png,svg,pdf", help="figure formats (default png,svg,pdf)")
    p.add_argument(
        "--point-limit",
        default="600",
        metavar="SECONDS",
        help="hard limit of one parameter value, on local workers and on Dask: past it the worker "
        "is ended and the value stored with status 'time limit' (default 600)",
    )
    p.add_argument(
        "--setup-limit",
        default="1800",
        metavar="SECONDS",
        help="hard limit of the integrator's set-up in each worker (construction, setup, compiling "
        "or loading its compiled code): past it every value not computed yet is stored with "
        "status 'time limit' (default 1800)",
    )
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(handler=main)


def _spec(request: _Request, section: str | None, problem_probe, integrator: str, options: dict):
    from nsbench.bifurcation.sweep import SweepSpec, default_section

    name, start, stop, count = request.sweep
    params = request.params
    section = section or default_section(problem_probe(name, start, params), problem_probe(name, stop, params))
    return SweepSpec(
        problem=request.problem,
        case=request.case,
        name=name,
        start=start,
        stop=stop,
        count=count,
        integrator=integrator,
        options=options,
        section=section,
        transient=request.transient,
        record=request.record,
        window=request.window,
        params=params,
    )


def _case_text(spec) -> str:
    """``' case 1'`` for a problem with presets, ``''`` for one without (the bouncing ball has no case 1)."""
    return f" case {spec.case}" if spec.problem_at(spec.start).cases else ""


def _probe(problem: str, case: int):
    from nsbench.problems import get_problem

    def build(name, value, params):
        return get_problem(problem, case=case, **{**params, name: value})

    return build


def _probe_factory(request: _Request, dask: bool) -> str | None:
    """A plug-in problem built first at both ends of the sweep in a worker, under ``--setup-limit``
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


def main(args: argparse.Namespace) -> int:
    workers = None if args.workers is None else parse_count(args.workers, "--workers", low=1, bound="MAX_WORKERS")
    # the workers first (a bad number below ends them at once): the checks import numpy, a tenth
    # of a second in which the workers start instead
    pool = _start_workers(workers) if args.dask is None else None
    try:
        request = _request(args, workers)  # every option once, before any problem is built or value computed
        return _main(args, request)
    except BaseException as exc:
        if pool is not None:  # started for this command, which failed: they are not kept
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


def _main(args: argparse.Namespace, request: _Request) -> int:
    from nsbench.bifurcation import detect, figures
    from nsbench.bifurcation.parallel import run_sweep, supervised
    from nsbench.bifurcation.storage import SweepStore, points_summary
    from nsbench.integrators import integrator_class

    fault = _probe_factory(request, dask=args.dask is not None)
    if fault is not None:
        print(f"nsbench: bifurcation: {fault}; nothing was run", file=sys.stderr)
        return 1
    probe = _probe(request.problem, request.case)
    names, extra, formats, workers = request.integrators, request.options, request.formats, request.workers
    specs = []
    for name in names:
        if name is None:
            sw, start, _, _ = request.sweep
            name = "exact" if probe(sw, start, {}).is_linear else "henon-rk4"
        allowed = integrator_class(name).options
        unknown = [k for k in extra if all(k not in integrator_class(n).options for n in names if n)]
        if unknown:
            raise ConfigError(f"option(s) {', '.join(unknown)} belong to none of the integrators")
        specs.append(_spec(request, args.section, probe, name, {k: v for k, v in extra.items() if k in allowed}))
    for spec in specs:  # a fixed step the span or the force cannot take: one line now, not a sweep of failures
        from nsbench.integrators import get_integrator

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
    pair = request.pair or (1, 2)
    n_blocks = getattr(specs[0].problem_at(specs[0].start), "n_blocks", None)
    if args.pair is not None and n_blocks is None:
        raise ConfigError(f"--pair {args.pair} names blocks of a friction oscillator; {args.problem} has none")
    if args.pair is not None and n_blocks is not None and any(not 1 <= b <= n_blocks for b in pair):
        raise ConfigError(f"--pair {args.pair}: {args.problem} has blocks 1 to {n_blocks}")
    portraits = request.portraits
    low, high = sorted((specs[0].start, specs[0].stop))
    for value in portraits:  # a bad portrait value or block pair fails now, not after the sweep
        if not low <= value <= high:
            raise ConfigError(
                f"--portrait {value:g} lies outside the swept range {specs[0].name} = {low:g} to {high:g}; "
                "give a value inside it"
            )
        problem = specs[0].problem_at(value)
        from nsbench.problems.base import problem_traits

        if not problem_traits(problem).belt_blocks:
            raise ConfigError(
                "--portrait draws the locus of sticking phase of a friction oscillator (blocks on a belt); "
                f"{args.problem} does not declare the belt_blocks trait"
            )
        if any(not 1 <= b <= problem.n_blocks for b in pair):
            raise ConfigError(f"--pair {args.pair or '1,2'}: {args.problem} has blocks 1 to {problem.n_blocks}")
    blocks = f"-n{int(specs[0].params['n'])}" if "n" in specs[0].params else ""
    case = f"-case{specs[0].case}" if _case_text(specs[0]) else ""
    base = Path(args.out or f"bifurcation/{args.problem}{blocks}{case}-{specs[0].name}")
    check_output_dir(base, "--out")
    from nsbench.bench.storage import file_name
    from nsbench.files import refuse_links

    # the tables and figures written below replace what is there: never through a link
    members = tuple(file_name(s.integrator, "integrator name") for s in specs) if len(specs) > 1 else ()
    refuse_links(base, WRITTEN + members)
    for name in members:
        refuse_links(base / name, WRITTEN)
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
    dask = connect_dask(args.dask) if args.dask is not None else None
    frames, walls = {}, {}
    short: dict[str, tuple[int, int]] = {}  # integrator -> (values failed or incomplete, values)
    from nsbench.bifurcation.parallel import default_workers

    local_workers = workers or default_workers()  # refinements and portraits reuse the sweep's kept workers
    figures.preload(formats)  # while the values are computed
    for spec in specs:
        from nsbench.bench.storage import file_name  # plug-in names are data: checked before they name a folder

        out = base if len(specs) == 1 else base / file_name(spec.integrator, "integrator name")
        tic = time.perf_counter()
        point_limit, setup_limit = request.point_limit, request.setup_limit
        frame = run_sweep(
            spec,
            out,
            workers=workers,
            dask=dask,
            progress=not args.no_progress,
            fresh=args.fresh,
            point_limit=point_limit,
            setup_limit=setup_limit,
        )
        walls[spec.integrator] = time.perf_counter() - tic
        frames[spec.integrator] = frame
        feats = detect.classify(frame)
        from nsbench.problems.base import problem_traits

        cands = detect.candidates(feats, problem_traits(spec.problem_at(spec.start)).belt_blocks)
        if args.refine and len(cands):
            # in a supervised worker: a plug-in that hangs or dies there costs that refinement only
            refined = []
            from nsbench.workers.jobs import WORKER_LOG, WorkerLog

            log = WorkerLog(out / WORKER_LOG, f"the refinements of the {spec.name} sweep")
            for r in cands.itertuples():
                job = (spec.to_dict(), r.left, r.right, r.kind, point_limit, setup_limit)
                found, why = supervised("refine_job", job, local_workers, log)
                if found is None:
                    print(f"  refinement of the {r.kind} change in [{r.left:.6g}, {r.right:.6g}] failed: {why}")
                    found = {"left": math.nan, "right": math.nan, "value": math.nan}
                refined.append(found)
            log.report()
            cands["refined_left"] = [r["left"] for r in refined]
            cands["refined_right"] = [r["right"] for r in refined]
            cands["refined_value"] = [r["value"] for r in refined]
        feats.to_csv(out / "features.csv", index=False)
        cands.to_csv(out / "candidates.csv", index=False)
        summary = points_summary(frame)
        title = (
            f"{spec.problem}{_case_text(spec)}: {spec.name} sweep, {spec.integrator}, "
            f"{spec.section}, transient {spec.transient:g}, {spec.record} points"
        )
        written = figures.diagram(frame, out / "diagram", title=title, candidates=cands, formats=formats)
        for value in portraits:
            _portrait(spec, value, out, formats, pair, point_limit, local_workers, setup_limit)
        from nsbench.bifurcation.sweep import OK_STATUSES

        n_bad = int((~summary["status"].isin(OK_STATUSES)).sum())
        if n_bad:
            short[spec.integrator] = (n_bad, len(summary))
        print(
            f"{spec.integrator}: {len(summary)} values ({n_bad} failed or incomplete) in {walls[spec.integrator]:.1f} s "
            f"-> {out}"
        )
        print(f"  diagram -> {written[0]}")
        if len(cands):
            print(f"  candidate bifurcation points ({len(cands)}):")
            for r in cands.itertuples():
                ref = f" refined {r.refined_value:.6g}" if "refined_value" in cands else ""
                print(f"    {spec.name} in [{r.left:.6g}, {r.right:.6g}]{ref}: {r.kind}: {r.description}")
        elif n_bad == len(summary):
            print("  no value ended in success or rest: nothing to read along the sweep")
        else:
            print("  no qualitative change along the sweep")
        SweepStore(out)  # the folder is complete and readable
    if len(specs) > 1:
        from nsbench.bifurcation import compare

        (base / "compare.md").write_text(compare.report(frames, walls))
        compare.agreement(frames).to_csv(base / "agreement.csv", index=False)
        print(f"comparison -> {base / 'compare.md'}")
    if dask is not None:
        dask.close()
    if short:  # the diagrams are written, but some values fell short: exit 1, as bench does for a failed case
        detail = ", ".join(f"{name} {bad} of {n}" for name, (bad, n) in short.items())
        print(
            f"nsbench: bifurcation: values failed or incomplete ({detail}); each value's status is in the sweep's features.csv",
            file=sys.stderr,
        )
        return 1
    return 0


@dataclass(frozen=True)
class _Request:
    """The command line of one ``nsbench bifurcation``, every option parsed and checked once (:func:`_request`)."""

    problem: str
    case: int
    sweep: tuple[str, float, float, int]  # name, start, stop, count
    params: dict[str, Any]
    integrators: tuple[str | None, ...]  # None: the default for the problem (exact or henon-rk4)
    options: dict[str, Any]  # --option and --h
    formats: tuple[str, ...]
    record: int
    transient: float
    window: float | None
    workers: int | None
    point_limit: float
    setup_limit: float
    portraits: tuple[float, ...]
    pair: tuple[int, int] | None  # None: not given (the locus takes blocks 1 and 2)


def _request(args: argparse.Namespace, workers: int | None) -> _Request:
    """Every option of ``args`` parsed and checked once, before any problem is built or value computed."""
    from nsbench.bifurcation import figures
    from nsbench.bifurcation.sweep import parse_sweep

    sweep = parse_sweep(args.sweep)
    _check_swept_name(sweep[0])
    try:
        whole = float(args.case).is_integer()
    except ValueError:
        whole = False
    if not whole:
        raise ConfigError(f"--case = {args.case!r} must be a case number such as 1, 2, 3 or 4")
    record = parse_count(args.record, "--record", low=1, bound="MAX_RECORD")
    transient = parse_real(args.transient, "--transient", low=0.0, bound="MAX_SPAN")
    window = None
    if args.window is not None:
        window = parse_real(args.window, "--window", low=0.0, low_open=True, bound="MAX_SPAN")
    options = parse_options(args.option)
    if args.h is not None:
        h = parse_real(args.h, "--h", low=0.0, low_open=True)
        if "h" in options:
            raise ConfigError("--h and --option h=... are both given; give it once")
        options["h"] = h
    point_limit = parse_real(args.point_limit, "--point-limit", low=0.0, low_open=True, bound="MAX_TIME_LIMIT")
    setup_limit = parse_real(args.setup_limit, "--setup-limit", low=0.0, low_open=True, bound="MAX_TIME_LIMIT")
    portraits = tuple(parse_real(text, "--portrait") for text in args.portrait)
    pair = _pair(args.pair) if args.pair is not None else None
    twice = sorted({n for n in args.integrator if args.integrator.count(n) > 1})
    if twice:  # the same sweep twice, and a comparison of a method with itself
        raise ConfigError(f"--integrator {twice[0]} is given twice; give each integrator once")
    formats = tuple(f.strip() for f in args.formats.split(",") if f.strip())
    bad = [f for f in formats if f not in figures.FORMATS]
    if bad:
        raise ConfigError(f"--formats: {', '.join(bad)} not allowed; choose from {', '.join(figures.FORMATS)}")
    return _Request(
        problem=args.problem,
        case=int(parse_number(args.case, "--case")),
        sweep=sweep,
        params=shared_params(args),
        integrators=tuple(args.integrator) or (None,),
        options=options,
        formats=formats,
        record=record,
        transient=transient,
        window=window,
        workers=workers,
        point_limit=point_limit,
        setup_limit=setup_limit,
        portraits=portraits,
        pair=pair,
    )


def _check_swept_name(name: str) -> None:
    """Refuse a swept name that is not a parameter of the problem's state-preserving kind."""
    if name == "n":
        raise ConfigError("the number of blocks n cannot be swept (it changes the state); give --n")
    if name in ("case", "dimensional"):  # get_problem's own arguments, not parameters
        raise ConfigError(
            f"--sweep {name}=...: {name} is not a parameter and cannot be swept; give --case for the preset "
            "and sweep one of its parameters (v0, F, Omega, ...)"
        )


def _pair(text: str) -> tuple[int, int]:
    parts = [t.strip() for t in text.split(",")]
    if len(parts) != 2 or not all(p.isdigit() for p in parts):
        raise ConfigError(f"--pair expects two block numbers A,B (e.g. 1,2), got {text!r}")
    if parts[0] == parts[1] or int(parts[0]) == int(parts[1]):
        raise ConfigError(f"--pair {text}: the locus needs two different blocks A,B (e.g. 1,2)")
    return int(parts[0]), int(parts[1])


def _portrait(
    spec,
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
    figures.portrait(run, out / f"portrait_{tag}", title=f"{spec.problem}{_case_text(spec)}, {tag}", formats=formats)
    print(f"  locus and portrait at {tag} -> {out}")
