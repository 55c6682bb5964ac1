"""``nsbench lyapunov PROBLEM ...``: largest Lyapunov exponent of the mapping-point return map.

The command maps its arguments onto a :class:`nsbench.bifurcation.request.LyapunovRequest` (every
value checked there) and runs it with :func:`nsbench.bifurcation.lyapunov_command.run_lyapunov`.
"""

from __future__ import annotations

import argparse
import sys

from nsbench.bifurcation.request import LyapunovRequest
from nsbench.cli._common import add_factory_limit, add_problem_arguments, shared_params


def add_parser(sub) -> None:
    p = sub.add_parser("lyapunov", help="largest Lyapunov exponent of the mapping points (ensemble of Benettin runs)")
    add_problem_arguments(p)
    add_factory_limit(p)
    p.add_argument(
        "--integrator",
        default=None,
        help="registered integrator (default: exact for linear problems, henon-rk4 otherwise)",
    )
    p.add_argument("--h", default=None, help="step size of henon-rk4")
    p.add_argument(
        "--transient", default="1000", help="time each member runs before its first mapping point used (default 1000)"
    )
    p.add_argument(
        "--iterations",
        default="10000",
        help="return-map iterations in all, split evenly over the members (default 10000)",
    )
    p.add_argument(
        "--members",
        default="32",
        help="independent estimates from perturbed starts; their spread gives the "
        "standard error (default 32, at least 4)",
    )
    p.add_argument("--d0", default="1e-8", help="renormalised separation (default 1e-8; from 1e-12 to 0.01)")
    p.add_argument("--seed", default="0", help="seed of the start perturbations and directions (default 0)")
    p.add_argument("--workers", default="1", help="processes running members at once (default 1)")
    p.add_argument(
        "--member-limit",
        default="1800",
        metavar="SECONDS",
        help="hard limit of one member's run: past it its worker is ended and the member "
        "counts as failed (default 1800, compilation included)",
    )
    p.add_argument(
        "--out",
        default=None,
        metavar="FILE.csv",
        help="write log(d/d0) per member and iteration (and FILE.csv.worker-errors.log, the tracebacks of members that raised)",
    )
    p.set_defaults(handler=main)


def main(args: argparse.Namespace) -> int:
    from nsbench.bifurcation.lyapunov_command import run_lyapunov

    outcome = run_lyapunov(request(args))
    if outcome.failure is not None:
        print(f"nsbench: lyapunov: {outcome.failure}", file=sys.stderr)
    return outcome.exit_code


def request(args: argparse.Namespace) -> LyapunovRequest:
    """The estimate the command line asks for."""
    return LyapunovRequest(
        transient=args.transient,
        members=args.members,
        iterations=args.iterations,
        d0=args.d0,
        seed=args.seed,
        workers=args.workers,
        h=args.h,
        member_limit=args.member_limit,
        out=args.out,
        setup_limit=args.setup_limit,
        problem=args.problem,
        case=args.case,
        params=shared_params(args),
        dimensional=args.dimensional,
        integrator=args.integrator,
    )
