"""``nsbench continuation PROBLEM --sweep NAME=START:STOP ...``: periodic orbits followed in one parameter.

The arguments map onto one :class:`nsbench.bifurcation.request.ContinuationRequest` (every value
checked there, once) and one call of :func:`nsbench.bifurcation.continuation_command.run_continuation`,
whose outcome gives the exit status: 0, 1 (nothing ran, the flow's set-up failed or the run
stopped before its end) or 2 (refused input).
"""

from __future__ import annotations

import argparse
import sys

from nsbench.bifurcation.request import TIME_LIMIT, ContinuationRequest
from nsbench.cli._common import shared_params

SECTIONS = ("peaks", "strobe", "stick", "mapping")


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


def main(args: argparse.Namespace) -> int:
    from nsbench.bifurcation.continuation_command import run_continuation

    outcome = run_continuation(request(args))
    if outcome.failure is not None:
        print(f"nsbench: continuation: {outcome.failure}", file=sys.stderr)
    return outcome.exit_code


def request(args: argparse.Namespace) -> ContinuationRequest:
    """The continuation the command line asks for."""
    return ContinuationRequest(
        sweep=args.sweep,
        time_limit=args.time_limit,
        setup_limit=args.setup_limit,
        steps=args.steps,
        transient=args.transient,
        case=args.case,
        origin=args.origin,
        params=shared_params(args),
        formats=args.formats,
        problem=args.problem,
        section=args.section,
        integrator=args.integrator,
        doubling=not args.no_doubling,
        diagram=args.diagram,
        out=args.out,
        progress=not args.no_progress,
    )
