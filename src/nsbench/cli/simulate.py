"""``nsbench simulate PROBLEM ...``: one run, its event log, trajectory and plot."""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from nsbench.cli._common import (add_problem_arguments, check_figure_path, check_output_file, parse_assignment,
                                 parse_count, parse_real, parse_value, problem_from_args)


def add_parser(sub) -> None:
    p = sub.add_parser("simulate", help="integrate one problem with one integrator through every event")
    add_problem_arguments(p)
    p.add_argument("--integrator", default=None,
                   help="registered integrator (default: exact for linear problems, scipy-dop853 otherwise); "
                        "with 'reference' the log's certified error is printed and written as a column")
    p.add_argument("--rtol", default=None, help="relative tolerance (adaptive integrators)")
    p.add_argument("--atol", default=None, help="absolute tolerance (adaptive integrators)")
    p.add_argument("--h", default=None, help="step size (fixed-step integrators)")
    p.add_argument("--option", action="append", default=[], metavar="NAME=VALUE",
                   help="any other integrator option (repeatable)")
    p.add_argument("--t-end", default="300", help="end time in the problem's units (default 300)")
    p.add_argument("--samples", default="3001", help="trajectory points for --trajectory-out/--plot (default 3001)")
    p.add_argument("--events-out", default=None, metavar="FILE.csv", help="write the event log")
    p.add_argument("--trajectory-out", default=None, metavar="FILE.csv", help="write the trajectory")
    p.add_argument("--plot", default=None, metavar="FILE.png", help="plot time series and phase plane")
    p.set_defaults(handler=main)


def main(args: argparse.Namespace) -> int:
    # every option is checked before the problem is built and anything is integrated
    options = {}
    for flag in ("rtol", "atol", "h"):
        text = getattr(args, flag)
        if text is not None:
            options[flag] = parse_real(text, f"--{flag}", low=0.0, low_open=True)
    for text in args.option:
        key, value = parse_assignment(text, "--option")
        options[key] = parse_value(value)
    t_end = parse_real(args.t_end, "--t-end")  # t_end > t0 is the engine's check
    samples = parse_count(args.samples, "--samples", low=2, bound="MAX_SAMPLES")
    for flag in ("events_out", "trajectory_out"):
        if getattr(args, flag):
            check_output_file(getattr(args, flag), "--" + flag.replace("_", "-"))
    if args.plot:
        check_figure_path(args.plot, "--plot")
    problem = problem_from_args(args)
    name = args.integrator or ("exact" if problem.is_linear else "scipy-dop853")
    from nsbench.engine import simulate

    want_traj = bool(args.trajectory_out or args.plot)
    grid = np.linspace(0.0, t_end, samples) if want_traj and t_end > 0 else None
    result = simulate(problem, name, t_end, options=options, t_eval=grid)
    print(result.summary())
    if name == "reference" and result.ok and len(result.events):
        # the reference's log says how far it can be trusted: an independent quad-precision check
        from nsbench.bench.reference import certified_errors

        errors, note = certified_errors(problem, result.events, 0.0, t_end)
        result.events["certified_error"] = errors
        finite = errors[np.isfinite(errors)]
        # each value bounds |t - t_true|: the difference from the check plus one ulp of t
        worst = "no event certified" if not finite.size else f"at most {finite.max():.2g}"
        print(f"certified error of this log: {worst} over {finite.size} of {errors.size} events ({note})")
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


def _write(frame, path: str) -> None:
    frame.to_csv(Path(path), index=False, float_format="%.17g")
