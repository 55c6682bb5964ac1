"""The ``nsbench continuation`` command as a function: :func:`run_continuation` runs a :class:`ContinuationRequest`.

One request (:class:`nsbench.bifurcation.request.ContinuationRequest`, checked at its construction)
in, one :class:`ContinuationOutcome` out: the branches and section points received, the files
written, and the one line saying why the command exits 1 (a plug-in problem's factory or the
flow's set-up failed, or the run stopped before its end). Refused input raises a
:class:`~nsbench.errors.ConfigError` before the flow runs (the command exits 2). The command line
(:mod:`nsbench.cli.continuation`) maps its arguments onto the request and prints the outcome's
failure; the branches, bifurcations and files are printed here, as they come.

The continuation runs in a supervised worker of its own (:func:`nsbench.periodic.supervised.continuation_job`):
the flow runs the integrator, a plug-in's possibly, whose loop cannot be stopped in this process.
The command lives beside the sweeps because it reads them: a sweep folder drawn beneath the
branches, and the sweeps' sections (:mod:`nsbench.periodic` imports no part of :mod:`nsbench.bifurcation`).
"""

from __future__ import annotations

import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from nsbench.errors import ConfigError
from nsbench.bifurcation.request import ContinuationRequest
from nsbench.status import OutcomeKind

if TYPE_CHECKING:  # pragma: no cover
    from nsbench.periodic.continuation import Continuation

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


@dataclass(frozen=True)
class ContinuationOutcome:
    """What :func:`run_continuation` did: the branches received and the files written, or why not."""

    #: The results folder (``None`` when nothing was run).
    folder: Path | None
    #: The branches, bifurcations and gaps received (``None`` when nothing was run).
    result: Continuation | None = None
    #: The section points of the branches (a ``pandas.DataFrame``).
    points: Any = None
    #: The flow's integrator.
    integrator: str = ""
    seconds: float = 0.0
    #: The tables written (:func:`nsbench.periodic.output.write`) and the figure's files.
    files: dict[str, Path] = field(default_factory=dict)
    figure: tuple[Path, ...] = ()
    #: One line saying why the command fails (exit 1), or ``None``.
    failure: str | None = None

    @property
    def exit_code(self) -> int:
        """0, or 1: nothing ran, the flow's set-up failed, or the run stopped before its end."""
        return 0 if self.failure is None else 1


def run_continuation(request: ContinuationRequest) -> ContinuationOutcome:
    """Follow the periodic orbits of ``request`` over its range; write branches, bifurcations, figure.

    Parameters
    ----------
    request
        The continuation, checked at its construction.

    Returns
    -------
    ContinuationOutcome
        The branches and files; :attr:`ContinuationOutcome.failure` names what failed. A run
        stopped by its time limit writes the branches complete before it, and says so.

    Raises
    ------
    ConfigError
        What the request asks cannot be run (a parameter or value the problem refuses, a section
        that does not apply, an unwritable folder, a ``diagram`` that is no sweep of the same
        parameter, a first orbit that cannot be sought): before the flow runs, or as it starts.
    """
    from nsbench.factory_probe import probe_problem

    name, start, stop = request.sweep
    case, params = request.case, request.params
    # a plug-in problem's factory is built first in a worker under the set-up limit: one that loops or
    # raises is one line here, not a hang or a traceback of this process
    values = [start, stop] + ([request.origin] if request.origin is not None else [])
    calls = [{"case": case, **params, name: float(v)} for v in values]
    fault = probe_problem(request.problem, calls, request.setup_limit)
    if fault is not None:
        return ContinuationOutcome(None, failure=f"{fault}; nothing was run")
    ends, out, diagram, section = _checked(request)
    run = {
        "problem": request.problem,
        "case": case,
        "params": params,
        "name": name,
        "start": start,
        "stop": stop,
        "steps": request.steps,
        "transient": request.transient,
        "doubling": 2 if request.doubling else 0,
        "origin": request.origin,
        "integrator": request.integrator,
        "section": section,
    }
    from nsbench.progress import Progress

    tic = time.perf_counter()
    with Progress(request.steps, label=name, enabled=request.progress) as bar:
        traced = _supervised(run, bar, request.time_limit, request.setup_limit)
    seconds = time.perf_counter() - tic
    if traced.refused is not None:
        raise ConfigError(traced.refused)
    if traced.setup_failed is not None:
        which = request.integrator or "the default integrator"
        failure = f"{which} failed in its set-up on {request.problem}: {traced.setup_failed}"
        return ContinuationOutcome(None, failure=failure)
    if traced.stopped is not None and not traced.result.branches:
        failure = f"stopped: {traced.stopped}; no branch was complete, nothing written"
        return ContinuationOutcome(None, traced.result, failure=failure)
    return _written(request, traced, out, diagram, ends, section, seconds)


def _checked(request: ContinuationRequest) -> tuple[list, Path, Any, str]:
    """The problem at both ends (and the origin), the folder, the diagram's points and the section:
    each checked before the flow is built (the cheap refusals first: a bad ``out`` is refused
    before anything compiles or runs)."""
    from nsbench.bifurcation.sweep import check_section_name, orbit_section, refuse_section
    from nsbench.files import refuse_links
    from nsbench.inputs import check_output_dir
    from nsbench.problems import get_problem

    name, start, stop = request.sweep

    def problem_at(value: float):
        return get_problem(request.problem, case=request.case, **{**request.params, name: float(value)})

    ends = [problem_at(start), problem_at(stop)]  # a bad parameter or value fails here
    if request.origin is not None:
        problem_at(request.origin)
    if request.section is not None:
        check_section_name(request.section)
    # the output folder and the diagram before the flow is built (exit 2 means refused before anything ran)
    out = Path(request.out or f"continuation/{request.problem}-case{request.case}-{name}")
    check_output_dir(out, "--out")
    refuse_links(out, WRITTEN)  # the tables and figures written there replace what is there: never through a link
    diagram = _diagram(request.diagram, name) if request.diagram else None
    # a section that applies is confirmed on the problem's field (peaks: which state is a position's
    # rate), which compiles it: after the cheap refusals, so that a bad --out is refused before that
    section = request.section or orbit_section(*ends)
    if section == "strobe" and not all(p.is_forced and p.forcing_frequency > 0 for p in ends):
        raise ConfigError("section strobe needs a harmonic force (F > 0, Omega > 0) at both ends of the range")
    if section != "strobe":  # strobe was checked at both ends just above
        refuse_section(ends[0], section, "--section: ")
    return ends, out, diagram, section


def _written(
    request: ContinuationRequest, traced: _Traced, out: Path, diagram: Any, ends: list, section: str, seconds: float
) -> ContinuationOutcome:
    """The branches received, written to ``out`` with their figure, and said in a few lines."""
    from nsbench.periodic.output import figure, write
    from nsbench.provenance import provenance

    name, start, stop = request.sweep
    result, points = traced.result, traced.points
    meta = {
        "problem": request.problem,
        "case": request.case,
        "params": request.params,
        "param": name,
        "origin": request.origin,
        "start": start,
        "stop": stop,
        "steps": request.steps,
        "section": section,
        "transient": request.transient,
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
    where = f" case {request.case}" if ends[0].cases else ""
    title = f"{request.problem}{where}: periodic orbits along {name} ({section} section, flow {traced.integrator})"
    variable = ends[0].state_names[0]  # x1 of the friction problems and the relay, x of the impact oscillator
    formats = request.formats
    written = figure(result, points, out / "branches", variable=variable, diagram=diagram, title=title, formats=formats)
    _say(result, name, out, seconds, paths, written)
    failure = None
    if traced.stopped is not None:
        failure = (
            f"stopped: {traced.stopped}; the {len(result.branches)} branch(es) complete before are written to {out}"
        )
    return ContinuationOutcome(
        out, result, points, traced.integrator, seconds, dict(paths), tuple(written), failure=failure
    )


def _say(result: Continuation, name: str, out: Path, seconds: float, paths: dict, written: list) -> None:
    """The lines of a continuation: its branches, their bifurcations, its figure."""
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

    from nsbench.periodic.continuation import Continuation
    from nsbench.workers.jobs import Job, JobPool

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
