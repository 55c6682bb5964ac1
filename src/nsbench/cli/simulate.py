"""``nsbench simulate PROBLEM ...``: one run, its event log, trajectory and plot."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from nsbench.cli._common import (
    add_factory_limit,
    add_problem_arguments,
    check_figure_path,
    factory_fault,
    problem_from_args,
)
from nsbench.inputs import check_fixed_step, check_output_file, parse_count, parse_options, parse_real
from nsbench.errors import ConfigError


#: Step budget of a run (the engine's default): a fixed step that needs more is refused up front.
MAX_STEPS = 5_000_000


def add_parser(sub) -> None:
    p = sub.add_parser("simulate", help="integrate one problem with one integrator through every event")
    add_problem_arguments(p)
    add_factory_limit(p)
    p.add_argument(
        "--integrator",
        default=None,
        help="registered integrator (default: exact for linear problems, scipy-dop853 otherwise); "
        "with 'reference' the log's certified error is printed and written as a column",
    )
    p.add_argument("--rtol", default=None, help="relative tolerance (adaptive integrators)")
    p.add_argument("--atol", default=None, help="absolute tolerance (adaptive integrators)")
    p.add_argument("--h", default=None, help="step size (fixed-step integrators)")
    p.add_argument(
        "--option", action="append", default=[], metavar="NAME=VALUE", help="any other integrator option (repeatable)"
    )
    p.add_argument("--t-end", default="300", help="end time in the problem's units (default 300)")
    p.add_argument(
        "--samples",
        default="3001",
        help="evenly spaced times of the trajectory (--trajectory-out/--plot) and, always, of the "
        "check for crossings stepped over (default 3001)",
    )
    p.add_argument("--events-out", default=None, metavar="FILE.csv", help="write the event log")
    p.add_argument("--trajectory-out", default=None, metavar="FILE.csv", help="write the trajectory")
    p.add_argument("--plot", default=None, metavar="FILE.png", help="plot time series and phase plane")
    p.set_defaults(handler=main)


def main(args: argparse.Namespace) -> int:
    # every option is checked before the problem is built and anything is integrated
    options = parse_options(args.option)
    for flag in ("rtol", "atol", "h"):
        text = getattr(args, flag)
        if text is not None:
            if flag in options:
                raise ConfigError(f"--{flag} and --option {flag}=... are both given; give it once")
            options[flag] = parse_real(text, f"--{flag}", low=0.0, low_open=True)
    t_end = parse_real(args.t_end, "--t-end", bound="MAX_SPAN")  # t_end > t0 is the engine's check
    samples = parse_count(args.samples, "--samples", low=2, bound="MAX_SAMPLES")
    for flag in ("events_out", "trajectory_out"):
        if getattr(args, flag):
            check_output_file(getattr(args, flag), "--" + flag.replace("_", "-"))
    if args.plot:
        check_figure_path(args.plot, "--plot")
    # a plug-in problem's factory runs first in a worker under --setup-limit: one that loops, crashes or
    # raises is one line and exit 1, never a hang or a traceback of this process
    fault = factory_fault(args)
    if fault is not None:
        print(f"nsbench: simulate: {fault}; nothing was run", file=sys.stderr)
        return 1
    problem = problem_from_args(args)
    name = args.integrator or ("exact" if problem.is_linear else "scipy-dop853")
    from nsbench.engine import simulate
    from nsbench.integrators import get_integrator

    integrator = get_integrator(name, **options)  # an unknown option or a bad value: one line now
    check_fixed_step(
        integrator,
        problem,
        t_end,
        f"--t-end {t_end:g}",
        MAX_STEPS,
        given=type(integrator).capabilities.step_option in options,
    )
    want_traj = bool(args.trajectory_out or args.plot)
    grid = np.linspace(0.0, t_end, samples) if want_traj and t_end > 0 else None
    # the samples are also where the core checks each guard's sign (a crossing pair inside one step ends
    # the run 'event missed'), with or without a trajectory written: never a silent false success
    checks = samples if t_end > 0 else 0
    result = simulate(problem, integrator, t_end, t_eval=grid, max_steps=MAX_STEPS, check_points=checks)
    print(result.summary())
    if "t_located" in result.events:  # a whole-system method that locates switches itself (fesd, Siconos's)
        print(_located_line(result.events))
    if not result.ok:  # the reason is in the summary; one line on stderr says the run fell short
        print(
            f"nsbench: simulate: the run ended at t = {result.t_final:g} of {t_end:g}: {result.status.value}"
            + (f": {result.message}" if result.message else ""),
            file=sys.stderr,
        )
    if name == "reference" and result.ok and len(result.events):
        # the reference's log says how far it can be trusted: an independent quad-precision check
        from nsbench.certify import CERTIFIED, certified_errors

        errors, note = certified_errors(problem, result.events, 0.0, t_end)
        result.events[CERTIFIED] = errors
        finite = errors[np.isfinite(errors)]
        # each value bounds |t - t_true|: the difference from the check plus the check's own error and an ulp
        worst = "no event certified" if not finite.size else f"at most {finite.max():.2g}"
        print(f"certified error of this log: {worst} over {finite.size} of {errors.size} events ({note})")
        if finite.size:
            print(f"certified error by kind: {_by_kind(result.events['kind'], errors)}")
    if args.events_out:
        _write(result.events, args.events_out)
        print(f"events      -> {args.events_out}")
    if args.trajectory_out:
        _write(result.trajectory, args.trajectory_out)
        print(f"trajectory  -> {args.trajectory_out}")
    if args.plot:
        from nsbench.plotting import plot_simulation

        plot_simulation(result, args.plot)
        print(f"plot        -> {args.plot}")
    return 0 if result.ok else 1


def _by_kind(kinds, errors: np.ndarray) -> str:
    """The largest certified error of each event kind, ``'impact 9.9e-14, stick 5.1e-12'`` (kinds in the
    order of the log; a kind with no certified event says so)."""
    parts = []
    for kind in dict.fromkeys(kinds):
        mine = errors[np.asarray(kinds) == kind]
        mine = mine[np.isfinite(mine)]
        parts.append(f"{kind} {mine.max():.2g}" if mine.size else f"{kind} not certified")
    return ", ".join(parts)


def _write(frame, path: str) -> None:
    frame.to_csv(Path(path), index=False, float_format="%.17g")


def _located_line(events) -> str:
    """How many of the log's events the method located itself, by kind, and how far from the inferred times."""
    own = np.isfinite(events["t_located"].to_numpy(dtype=float))
    if not own.any():
        return f"located     0 of {own.size} events by the integrator itself (the log's t_located)"
    kinds = events["kind"][own].value_counts(sort=False)
    by_kind = ", ".join(f"{kind}: {count}" for kind, count in kinds.items())
    gap = float(np.max(np.abs(events["t_located"][own].to_numpy(float) - events["t"][own].to_numpy(float))))
    return (
        f"located     {int(own.sum())} of {own.size} events by the integrator itself ({by_kind}; the log's "
        f"t_located, at most {gap:.2g} from the inferred t)"
    )
