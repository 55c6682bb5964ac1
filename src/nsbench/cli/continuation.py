"""``nsbench continuation PROBLEM --sweep NAME=START:STOP ...``: periodic orbits followed in one parameter."""

from __future__ import annotations

import argparse
import math
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from nsbench.cli._common import shared_params
from nsbench.errors import ConfigError
from nsbench.inputs import check_output_dir, parse_count, parse_number, parse_real
from nsbench.status import OutcomeKind

SECTIONS = ("peaks", "strobe", "stick", "mapping")
#: Default hard limit of the whole continuation in its worker, in seconds (``--time-limit``).
TIME_LIMIT = 3600.0


def add_parser(sub) -> None:
    p = sub.add_parser("continuation", help="follow periodic orbits in one parameter; locate their bifurcations")
    p.add_argument("problem", metavar="PROBLEM", help="registered problem, e.g. two-dof")
    p.add_argument("--case", default="1", help="preset 1..4, or a named case (default 1)")
    p.add_argument(
        "--param", action="append", default=[], metavar="NAME=VALUE", help="fixed parameter override (repeatable)"
    )
    p.add_argument("--n", default=None, help="number of blocks of a chain problem (same as --param n=N)")
    p.add_argument(
        "--sweep",
        required=True,
        metavar="NAME=START:STOP",
        help="continued dimensionless parameter and its range (v0, inv_omega_r, r_f, F, ...)",
    )
    p.add_argument(
        "--steps",
        default="200",
        help="continuation steps over the range at the largest step size (default 200; halved where needed)",
    )
    p.add_argument(
        "--section",
        default=None,
        metavar="SECTION",
        help=f"section points drawn and stored: {', '.join(SECTIONS)} or event:KIND (the states at the "
        "problem's KIND events); default strobe if forced, else peaks, else event:KIND of the problem's "
        "first event kind (a problem without a position, such as the relay)",
    )
    p.add_argument(
        "--integrator",
        default=None,
        help="integrator of the flow (default: exact for linear problems, heyoka otherwise)",
    )
    p.add_argument(
        "--transient", default="1500", help="time integrated from rest before the first orbit is sought (default 1500)"
    )
    p.add_argument(
        "--origin",
        default=None,
        metavar="VALUE",
        help="find the first orbit from rest at this value and continue it to START (for an orbit "
        "that coexists with another attractor at START)",
    )
    p.add_argument("--no-doubling", action="store_true", help="do not follow period-doubled branches")
    p.add_argument(
        "--diagram",
        default=None,
        metavar="DIR",
        help="a brute-force sweep folder (from nsbench bifurcation) to draw beneath the branches",
    )
    p.add_argument("--out", default=None, help="results folder (default continuation/<problem>-case<C>-<NAME>)")
    p.add_argument("--formats", default="png,svg,pdf", help="figure formats (default png,svg,pdf)")
    p.add_argument(
        "--time-limit",
        default=f"{TIME_LIMIT:g}",
        metavar="SECONDS",
        help="hard limit of the whole continuation, which runs in a supervised worker: past it the worker "
        f"is ended, the branches complete before are written and the run fails (default {TIME_LIMIT:g})",
    )
    p.add_argument(
        "--setup-limit",
        default="1800",
        metavar="SECONDS",
        help="hard limit of the flow's set-up (the integrator's construction and setup, compiling "
        "included) and of a plug-in problem's factory (default 1800)",
    )
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(handler=main)


def parse_range(text: str) -> tuple[str, float, float]:
    """``NAME=START:STOP`` as ``(name, start, stop)`` with two different finite numbers."""
    name, sep, rng = text.partition("=")
    parts = [p.strip() for p in rng.split(":")]
    if not sep or not name.strip() or len(parts) != 2:
        raise ConfigError(f"--sweep expects NAME=START:STOP, got {text!r}")
    start = parse_number(parts[0], f"--sweep {text!r}: START")
    stop = parse_number(parts[1], f"--sweep {text!r}: STOP")
    if not (math.isfinite(start) and math.isfinite(stop)) or start == stop:
        raise ConfigError(f"--sweep {text!r}: START and STOP must be two different finite numbers")
    return name.strip(), start, stop


def main(args: argparse.Namespace) -> int:
    from nsbench.bifurcation.figures import FORMATS
    from nsbench.factory_probe import probe_problem
    from nsbench.periodic.output import figure, write
    from nsbench.problems import get_problem
    from nsbench.progress import Progress
    from nsbench.provenance import provenance

    name, start, stop = parse_range(args.sweep)
    time_limit = parse_real(args.time_limit, "--time-limit", low=0.0, low_open=True, bound="MAX_TIME_LIMIT")
    setup_limit = parse_real(args.setup_limit, "--setup-limit", low=0.0, low_open=True, bound="MAX_TIME_LIMIT")
    steps = parse_count(args.steps, "--steps", low=1, high=100_000)
    transient = parse_real(args.transient, "--transient", low=0.0, bound="MAX_SPAN")
    text = str(args.case).strip()
    case: int | str = text
    if not (text[:1].isalpha()):  # a name (relay-feedback's published cases) is checked by the problem
        try:
            number = parse_number(args.case, "--case")
            if not float(number).is_integer():
                raise ValueError(number)
            case = int(number)
        except (ValueError, OverflowError):
            raise ConfigError(
                f"--case = {args.case!r} must be a case number such as 1, 2, 3 or 4, or a case name"
            ) from None
    origin = parse_real(args.origin, "--origin") if args.origin is not None else None
    params = shared_params(args)
    if name in params:
        raise ConfigError(f"parameter {name} is both continued (--sweep) and fixed (--param)")
    if name == "n":
        raise ConfigError("the number of blocks n cannot be continued (it changes the state)")
    formats = tuple(f.strip() for f in args.formats.split(",") if f.strip())
    bad = [f for f in formats if f not in FORMATS]
    if bad or not formats:
        raise ConfigError(f"--formats: {', '.join(bad) or 'none given'}; choose from {', '.join(FORMATS)}")

    def problem_at(value: float):
        return get_problem(args.problem, case=case, **{**params, name: float(value)})

    # a plug-in problem's factory is built first in a worker under the set-up limit: one that loops or
    # raises is one line here, not a hang or a traceback of this process
    values = [start, stop] + ([origin] if origin is not None else [])
    fault = probe_problem(args.problem, [{"case": case, **params, name: float(v)} for v in values], setup_limit)
    if fault is not None:
        print(f"nsbench: continuation: {fault}; nothing was run", file=sys.stderr)
        return 1
    ends = [problem_at(start), problem_at(stop)]  # a bad parameter or value fails here
    if origin is not None:
        problem_at(origin)
    from nsbench.bifurcation.sweep import check_section_name, orbit_section, refuse_section

    if args.section is not None:
        check_section_name(args.section)
    # the output folder and the diagram before the flow is built: a bad --out is refused before anything
    # compiles or runs (exit 2 means refused before anything ran)
    out = Path(args.out or f"continuation/{args.problem}-case{case}-{name}")
    check_output_dir(out, "--out")
    from nsbench.files import refuse_links

    refuse_links(out, WRITTEN)  # the tables and figures written there replace what is there: never through a link
    diagram = _diagram(args.diagram, name) if args.diagram else None
    # a section that applies is confirmed on the problem's field (peaks: which state is a position's
    # rate), which compiles it: after the cheap refusals, so that a bad --out is refused before that
    section = args.section or orbit_section(*ends)
    if section == "strobe" and not all(p.is_forced and p.forcing_frequency > 0 for p in ends):
        raise ConfigError("section strobe needs a harmonic force (F > 0, Omega > 0) at both ends of the range")
    if section != "strobe":  # strobe was checked at both ends just above
        refuse_section(ends[0], section, "--section: ")
    run = {
        "problem": args.problem,
        "case": case,
        "params": params,
        "name": name,
        "start": start,
        "stop": stop,
        "steps": steps,
        "transient": transient,
        "doubling": 0 if args.no_doubling else 2,
        "origin": origin,
        "integrator": args.integrator,
        "section": section,
    }
    tic = time.perf_counter()
    with Progress(steps, label=name, enabled=not args.no_progress) as bar:
        traced = _supervised(run, bar, time_limit, setup_limit)
    seconds = time.perf_counter() - tic
    if traced.refused is not None:
        raise ConfigError(traced.refused)
    if traced.setup_failed is not None:
        which = args.integrator or "the default integrator"
        print(
            f"nsbench: continuation: {which} failed in its set-up on {args.problem}: {traced.setup_failed}",
            file=sys.stderr,
        )
        return 1
    if traced.stopped is not None and not traced.result.branches:
        print(
            f"nsbench: continuation: stopped: {traced.stopped}; no branch was complete, nothing written",
            file=sys.stderr,
        )
        return 1
    result, points = traced.result, traced.points
    meta = {
        "problem": args.problem,
        "case": case,
        "params": params,
        "param": name,
        "origin": origin,
        "start": start,
        "stop": stop,
        "steps": steps,
        "section": section,
        "transient": transient,
        "integrator": traced.integrator,
        "newton_tolerance": 1e-11,
        "bisection_tolerance": 1e-11,
        "seconds": seconds,
        "provenance": provenance(),
    }
    if traced.stopped is not None:  # what was computed before the stop is written, and says it is partial
        meta["stopped"] = traced.stopped
    paths = write(out, result, points, meta)
    # "case 1" only where the problem has cases (a plug-in problem may have none)
    where = f" case {case}" if ends[0].cases else ""
    title = f"{args.problem}{where}: periodic orbits along {name} ({section} section, flow {traced.integrator})"
    variable = ends[0].state_names[0]  # x1 of the friction problems and the relay, x of the impact oscillator
    written = figure(result, points, out / "branches", variable=variable, diagram=diagram, title=title, formats=formats)
    n_steps = sum(len(b.values) for b in result.branches)
    print(
        f"{len(result.branches)} branch(es), {n_steps} orbits, {len(result.gaps)} value(s) without a periodic "
        f"orbit, in {seconds:.1f} s -> {out}"
    )
    for br in result.branches:
        print(
            f"  branch {br.label}: {name} {br.values[0]:.10g} .. {br.values[-1]:.10g}, {len(br.values)} steps; "
            f"{br.end_reason}"
        )
    bifs = [b for b in result.bifurcations if b.category != "none"]
    print(f"  bifurcations ({len(bifs)}; event-order swaps are in {paths['bifurcations'].name} only):")
    for b in bifs:
        print(f"    {name} = {b.value:.12g}: {b.kind} ({b.category})")
    print(f"  figure -> {written[0]}")
    if traced.stopped is not None:
        print(
            f"nsbench: continuation: stopped: {traced.stopped}; the {len(result.branches)} branch(es) complete "
            f"before are written to {out}",
            file=sys.stderr,
        )
        return 1
    return 0


#: What ``continuation`` writes in its ``--out`` folder (:func:`nsbench.periodic.output.write`, the figure).
WRITTEN = (
    "branch.csv",
    "points.csv",
    "bifurcations.csv",
    "gaps.csv",
    "meta.json",
    "README.md",
    "branches.*",
)


@dataclass
class _Traced:
    """What the supervised continuation gave: the branches (and section points) received, and how it ended."""

    result: Any
    #: The section points of the branches received (a ``pandas.DataFrame``).
    points: Any = None
    integrator: str = ""
    #: One line when the run stopped before its end (time limit, crash, an exception).
    stopped: str | None = None
    refused: str | None = None
    setup_failed: str | None = None


def _supervised(run: dict[str, Any], bar: Any, time_limit: float, setup_limit: float) -> _Traced:
    """Run :func:`nsbench.periodic.supervised.continuation_job` in a worker of its own.

    Why a worker: the flow runs the integrator, a plug-in's possibly, whose loop in ``setup`` or
    ``advance`` cannot be stopped in this process and whose ``os._exit`` would end it with no
    verdict. The branches it sends are kept whatever becomes of the worker.
    """
    import pandas as pd

    from nsbench.workers.jobs import Job, JobPool
    from nsbench.periodic.continuation import Continuation

    result = Continuation(run["name"], float(run["start"]), float(run["stop"]))
    traced = _Traced(result)
    frames: list[pd.DataFrame] = []
    h_max = abs(run["stop"] - run["start"]) / run["steps"]
    done = [0]
    with JobPool(1) as pool:
        pool.submit(Job("continuation", "nsbench.periodic.supervised:continuation_job", (run, setup_limit, time_limit)))
        for o in pool.outcomes():
            if o.kind is OutcomeKind.PARTIAL:
                _received(o.value, traced, frames, bar, run, h_max, done)
            elif o.kind is OutcomeKind.DONE:
                kind, value = o.value
                if kind == "done":
                    result.gaps = [tuple(g) for g in value]
                elif kind == "set-up failed":
                    traced.setup_failed = value
                elif kind == "no orbit":
                    traced.refused = (
                        f"no periodic orbit could be sought: {value} (is --transient {run['transient']:g} "
                        "longer than the flow's event budget allows?)"
                    )
                else:
                    traced.refused = value
            else:
                traced.stopped = _stop_reason(o, setup_limit, time_limit)
    traced.points = pd.concat(frames, ignore_index=True) if frames else pd.DataFrame()
    return traced


def _received(item: tuple, traced: _Traced, frames: list, bar: Any, run: dict, h_max: float, done: list) -> None:
    """One item the worker sent: the flow's integrator, an accepted step (progress) or complete branches."""
    if item[0] == "flow":
        traced.integrator = item[1]
    elif item[0] == "step":
        now = min(run["steps"], int(round(abs(item[1] - run["start"]) / h_max)))
        if now > done[0]:
            bar.update(now - done[0], note=f"{run['name']} = {item[1]:.6g}")
            done[0] = now
    elif item[0] == "branches":
        _, branches, points, gaps = item
        traced.result.branches.extend(branches)
        traced.result.gaps = [tuple(g) for g in gaps]
        if len(points):
            frames.append(points)


def _stop_reason(o: Any, setup_limit: float, time_limit: float) -> str:
    """``time limit (N s) in <stage>``, ``crashed (exit code N) in <stage>`` or the job's exception."""
    from nsbench.periodic.supervised import SETUP_STAGE

    stage = o.stage or "worker start"
    if o.kind is OutcomeKind.TIME_LIMIT:
        return f"time limit ({setup_limit if stage == SETUP_STAGE else time_limit:g} s) in {stage}"
    if o.kind is OutcomeKind.CRASHED:
        head, sep, rest = o.reason.partition("(")
        return f"crashed ({rest.split(')')[0] if sep else o.reason}) in {stage}"
    return f"{o.reason} (in {stage})"


def _diagram(folder: str, name: str):
    """Points of a brute-force sweep folder, checked to sweep the same parameter."""
    from nsbench.bifurcation.storage import SweepStore

    path = Path(folder)
    if not (path / "meta.json").is_file():
        raise ConfigError(f"--diagram {folder}: not a sweep folder (no meta.json); run nsbench bifurcation first")
    store = SweepStore(path)
    if store.spec.name != name:
        raise ConfigError(f"--diagram {folder} sweeps {store.spec.name}, not {name}")
    points = store.load()
    missing = store.missing()
    if missing:  # a deleted chunk or an unfinished sweep: the overlay is partial, and says so
        print(
            f"nsbench: warning: --diagram {folder} holds {store.spec.count - len(missing)} of its "
            f"{store.spec.count} values ({len(missing)} missing: a chunk deleted or the sweep not finished); "
            f"the figure overlays those; the same nsbench bifurcation command with --out {folder} computes the rest",
            file=sys.stderr,
        )
    return points
