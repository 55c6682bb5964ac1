"""``nsbench bifurcation PROBLEM --case N --sweep NAME=START:STOP:COUNT ...``: a bifurcation sweep.

The arguments map onto one :class:`nsbench.bifurcation.request.SweepRequest` (every value checked
there, once) and one call of :func:`nsbench.bifurcation.sweep_command.run_sweeps`, whose outcome gives
the exit status: 0, 1 (nothing ran, or values failed or fell short) or 2 (refused input).
"""

from __future__ import annotations

import argparse
import sys

from nsbench.bifurcation.request import SweepRequest
from nsbench.cli._common import shared_params


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


def main(args: argparse.Namespace) -> int:
    from nsbench.bifurcation.sweep_command import run_sweeps

    outcome = run_sweeps(request(args))
    if outcome.failure is not None:
        print(f"nsbench: bifurcation: {outcome.failure}", file=sys.stderr)
    return outcome.exit_code


def request(args: argparse.Namespace) -> SweepRequest:
    """The sweep the command line asks for."""
    return SweepRequest(
        workers=args.workers,
        sweep=args.sweep,
        case=args.case,
        record=args.record,
        transient=args.transient,
        window=args.window,
        options=args.option,
        h=args.h,
        point_limit=args.point_limit,
        setup_limit=args.setup_limit,
        portraits=tuple(args.portrait),
        pair=args.pair,
        integrators=tuple(args.integrator),
        formats=args.formats,
        params=shared_params(args),
        problem=args.problem,
        section=args.section,
        dask=args.dask,
        out=args.out,
        fresh=args.fresh,
        refine=args.refine,
        progress=not args.no_progress,
    )
