"""``nsbench lyapunov PROBLEM ...``: largest Lyapunov exponent of the mapping-point return map."""

from __future__ import annotations

import argparse
import sys

from nsbench.cli._common import add_factory_limit, add_problem_arguments, factory_fault, problem_from_args
from nsbench.inputs import MIN_D0, check_fixed_step, check_output_file, parse_count, parse_real
from nsbench.status import Status


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
    from nsbench.bifurcation.lyapunov import largest_exponent

    # every option is checked before the problem is built or anything integrated
    transient = parse_real(args.transient, "--transient", low=0.0, bound="MAX_SPAN")  # inf would never end
    members = parse_count(args.members, "--members", low=4, bound="MAX_MEMBERS")
    iterations = parse_count(args.iterations, "--iterations", low=1, bound="MAX_ITERATIONS")
    d0 = parse_real(args.d0, "--d0", low=MIN_D0, high=0.01, high_open=True)
    seed = parse_count(args.seed, "--seed", low=0, bound="MAX_SEED")
    workers = parse_count(args.workers, "--workers", low=1, bound="MAX_WORKERS")
    options = {"h": parse_real(args.h, "--h", low=0.0, low_open=True)} if args.h is not None else {}
    member_limit = parse_real(args.member_limit, "--member-limit", low=0.0, low_open=True, bound="MAX_TIME_LIMIT")
    if args.out:
        check_output_file(args.out, "--out")
    # a plug-in problem's factory runs first in a worker under --setup-limit: one that loops, crashes or
    # raises is one line and exit 1, never a hang or a traceback of this process
    fault = factory_fault(args)
    if fault is not None:
        print(f"nsbench: lyapunov: {fault}; nothing was run", file=sys.stderr)
        return 1
    problem = problem_from_args(args)
    name = args.integrator or ("exact" if problem.is_linear else "henon-rk4")
    from nsbench.integrators import get_integrator

    # the transient is one run with the core's default step budget (5_000_000 steps); the whole run is
    # longer (mapping points after it), so the step is not compared with the transient itself
    check_fixed_step(get_integrator(name, **options), problem, transient, f"--transient {transient:g}", 5_000_000)
    res = largest_exponent(
        problem,
        name,
        options=options,
        transient=transient,
        iterations=iterations,
        members=members,
        d0=d0,
        seed=seed,
        workers=workers,
        member_limit=member_limit,
        worker_log=f"{args.out}.worker-errors.log" if args.out else None,  # else a temporary file
    )
    print(f"{problem!r} with {name}")
    print(res.summary())
    if res.message:
        print(res.message)
    if args.out:
        import numpy as np
        import pandas as pd

        members, per = res.logs.shape
        pd.DataFrame(
            {
                "member": np.repeat(np.arange(members), per),
                "iteration": np.tile(np.arange(1, per + 1), members),
                "log_growth": res.logs.ravel(),
            }
        ).to_csv(args.out, index=False)
        print(f"log growth per member and iteration -> {args.out}")
    if res.status != Status.SUCCESS:  # the members' reasons are printed above; one line on stderr says so
        failed = res.message.count("member ") or "some"
        print(f"nsbench: lyapunov: no exponent: {failed} member(s) failed (reasons above)", file=sys.stderr)
        return 1
    return 0
