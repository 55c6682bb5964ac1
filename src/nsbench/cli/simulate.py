"""``nsbench simulate PROBLEM ...``: one run, its event log, trajectory and plot.

The command maps its arguments onto a :class:`nsbench.simulation.SimulationRequest` (every value
checked there) and runs it with :func:`nsbench.simulation.run_simulation`.
"""

from __future__ import annotations

import argparse
import sys

from nsbench.cli._common import add_factory_limit, add_problem_arguments, shared_params
from nsbench.simulation import SimulationRequest


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
    from nsbench.simulation import run_simulation

    outcome = run_simulation(request(args))
    if outcome.failure is not None:
        print(f"nsbench: simulate: {outcome.failure}", file=sys.stderr)
    return outcome.exit_code


def request(args: argparse.Namespace) -> SimulationRequest:
    """The run the command line asks for."""
    return SimulationRequest(
        options=args.option,
        rtol=args.rtol,
        atol=args.atol,
        h=args.h,
        t_end=args.t_end,
        samples=args.samples,
        events_out=args.events_out,
        trajectory_out=args.trajectory_out,
        plot=args.plot,
        setup_limit=args.setup_limit,
        problem=args.problem,
        case=args.case,
        params=shared_params(args),
        dimensional=args.dimensional,
        integrator=args.integrator,
    )
