"""``nsbench bifurcation PROBLEM --case N --sweep NAME=START:STOP:COUNT ...``: a bifurcation sweep."""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

from nsbench.cli._common import (
    check_fixed_step,
    check_output_dir,
    parse_count,
    parse_number,
    parse_options,
    parse_real,
    shared_params,
)
from nsbench.cli._dask import connect as connect_dask
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


def _spec(args, problem_probe, integrator: str, options: dict):
    from nsbench.bifurcation.sweep import SweepSpec, default_section, parse_sweep

    name, start, stop, count = parse_sweep(args.sweep)
    params = shared_params(args)
    _check_swept_name(name)
    window = (
        parse_real(args.window, "--window", low=0.0, low_open=True, bound="MAX_SPAN")
        if args.window is not None
        else None
    )
    record = parse_count(args.record, "--record", low=1, bound="MAX_RECORD")
    section = args.section or default_section(problem_probe(name, start, params), problem_probe(name, stop, params))
    return SweepSpec(
        problem=args.problem,
        case=int(parse_number(args.case, "--case")),
        name=name,
        start=start,
        stop=stop,
        count=count,
        integrator=integrator,
        options=options,
        section=section,
        transient=parse_real(args.transient, "--transient", low=0.0, bound="MAX_SPAN"),
        record=record,
        window=window,
        params=params,
    )


def _case_text(spec) -> str:
    """``' case 1'`` for a problem with presets, ``''`` for one without (the bouncing ball has no case 1)."""
    return f" case {spec.case}" if spec.problem_at(spec.start).cases else ""


def _probe(problem: str, case: str):
    from nsbench.problems import get_problem

    def build(name, value, params):
        return get_problem(problem, case=case, **{**params, name: value})

    return build


def _probe_factory(args: argparse.Namespace, workers: int | None) -> str | None:
    """A plug-in problem built first at both ends of the sweep in a worker, under ``--setup-limit``
    (:func:`nsbench.cli._probe.probe_problem`): a factory that loops or raises is one line, not a
    hang or a traceback of this process. ``None`` when it built (or the problem is built-in)."""
    from nsbench.bifurcation.sweep import parse_sweep
    from nsbench.cli._probe import is_plugin_problem, probe_problem

    if not is_plugin_problem(args.problem):
        return None
    name, start, stop, _ = parse_sweep(args.sweep)
    if name in ("case", "dimensional"):  # refused below, with its own line
        return None
    limit = parse_real(args.setup_limit, "--setup-limit", low=0.0, low_open=True, bound="MAX_TIME_LIMIT")
    calls = [{"case": args.case, **shared_params(args), name: value} for value in (start, stop)]
    pool = None
    if args.dask is None:  # the sweep's own kept workers, started already: no other to start
        from nsbench.workers.jobs import default_workers, shared_pool

        pool = shared_pool(workers or default_workers())
    return probe_problem(args.problem, calls, limit, pool)


def main(args: argparse.Namespace) -> int:
    workers = None if args.workers is None else parse_count(args.workers, "--workers", low=1, bound="MAX_WORKERS")
    # the workers first (a bad number below ends them at once): the checks import numpy, a tenth
    # of a second in which the workers start instead
    pool = _start_workers(workers) if args.dask is None else None
    try:
        _check_numbers(args)  # every number and count before any problem is built or value computed
        return _main(args, workers)
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


def _main(args: argparse.Namespace, workers: int | None) -> int:
    from nsbench.bifurcation import detect, figures
    from nsbench.bifurcation.parallel import run_sweep, supervised
    from nsbench.bifurcation.storage import SweepStore, points_summary
    from nsbench.integrators import integrator_class

    fault = _probe_factory(args, workers)
    if fault is not None:
        print(f"nsbench: bifurcation: {fault}; nothing was run", file=sys.stderr)
        return 1
    probe = _probe(args.problem, args.case)
    names = args.integrator or [None]
    twice = sorted({n for n in args.integrator if args.integrator.count(n) > 1})
    if twice:  # the same sweep twice, and a comparison of a method with itself
        raise ConfigError(f"--integrator {twice[0]} is given twice; give each integrator once")
    formats = tuple(f.strip() for f in args.formats.split(",") if f.strip())
    bad = [f for f in formats if f not in figures.FORMATS]
    if bad:
        raise ConfigError(f"--formats: {', '.join(bad)} not allowed; choose from {', '.join(figures.FORMATS)}")
    extra = parse_options(args.option)
    if args.h is not None:
        if "h" in extra:
            raise ConfigError("--h and --option h=... are both given; give it once")
        extra["h"] = parse_real(args.h, "--h", low=0.0, low_open=True)
    specs = []
    for name in names:
        if name is None:
            from nsbench.bifurcation.sweep import parse_sweep

            sw, start, _, _ = parse_sweep(args.sweep)
            name = "exact" if probe(sw, start, {}).is_linear else "henon-rk4"
        allowed = integrator_class(name).options
        unknown = [k for k in extra if all(k not in integrator_class(n).options for n in names if n)]
        if unknown:
            raise ConfigError(f"option(s) {', '.join(unknown)} belong to none of the integrators")
        specs.append(_spec(args, probe, name, {k: v for k, v in extra.items() if k in allowed}))
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
    pair = _pair(args.pair or "1,2")
    n_blocks = getattr(specs[0].problem_at(specs[0].start), "n_blocks", None)
    if args.pair is not None and n_blocks is None:
        raise ConfigError(f"--pair {args.pair} names blocks of a friction oscillator; {args.problem} has none")
    if args.pair is not None and n_blocks is not None and any(not 1 <= b <= n_blocks for b in pair):
        raise ConfigError(f"--pair {args.pair}: {args.problem} has blocks 1 to {n_blocks}")
    portraits = [parse_real(text, "--portrait") for text in args.portrait]
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
        point_limit = parse_real(args.point_limit, "--point-limit", low=0.0, low_open=True, bound="MAX_TIME_LIMIT")
        setup_limit = parse_real(args.setup_limit, "--setup-limit", low=0.0, low_open=True, bound="MAX_TIME_LIMIT")
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


def _check_numbers(args: argparse.Namespace) -> None:
    """The sweep text and every numeric option, so that bad input fails before anything runs."""
    from nsbench.bifurcation.sweep import parse_sweep

    _check_swept_name(parse_sweep(args.sweep)[0])
    try:
        whole = float(args.case).is_integer()
    except ValueError:
        whole = False
    if not whole:
        raise ConfigError(f"--case = {args.case!r} must be a case number such as 1, 2, 3 or 4")
    parse_count(args.record, "--record", low=1, bound="MAX_RECORD")
    parse_real(args.transient, "--transient", low=0.0, bound="MAX_SPAN")
    if args.window is not None:
        parse_real(args.window, "--window", low=0.0, low_open=True, bound="MAX_SPAN")
    if args.h is not None:
        parse_real(args.h, "--h", low=0.0, low_open=True)
    if args.workers is not None:
        parse_count(args.workers, "--workers", low=1, bound="MAX_WORKERS")
    parse_real(args.point_limit, "--point-limit", low=0.0, low_open=True, bound="MAX_TIME_LIMIT")
    parse_real(args.setup_limit, "--setup-limit", low=0.0, low_open=True, bound="MAX_TIME_LIMIT")
    for text in args.portrait:
        parse_real(text, "--portrait")
    if args.pair is not None:
        _pair(args.pair)


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
