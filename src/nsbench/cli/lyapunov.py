"""``nsbench lyapunov PROBLEM ...``: largest Lyapunov exponent of the mapping-point return map."""

from __future__ import annotations

import argparse

from nsbench.cli._common import add_problem_arguments, parse_number, problem_from_args


def add_parser(sub) -> None:
    p = sub.add_parser("lyapunov", help="largest Lyapunov exponent of the mapping points (Benettin)")
    add_problem_arguments(p)
    p.add_argument("--integrator", default=None,
                   help="compiled integrator: exact-jit (linear problems, default) or henon-rk4-jit")
    p.add_argument("--h", default=None, help="step size of henon-rk4-jit")
    p.add_argument("--transient", default="1000", help="time before the first mapping point used (default 1000)")
    p.add_argument("--iterations", default="10000", help="return-map iterations (default 10000)")
    p.add_argument("--d0", default="1e-8", help="renormalised separation (default 1e-8)")
    p.add_argument("--seed", default="0", help="seed of the initial direction (default 0)")
    p.add_argument("--out", default=None, metavar="FILE.csv", help="write log(d/d0) per iteration")
    p.set_defaults(handler=main)


def main(args: argparse.Namespace) -> int:
    from nsbench.bifurcation.lyapunov import largest_exponent

    problem = problem_from_args(args)
    name = args.integrator or ("exact-jit" if problem.is_linear else "henon-rk4-jit")
    options = {"h": parse_number(args.h, "--h")} if args.h is not None else {}
    iterations = parse_number(args.iterations, "--iterations")
    res = largest_exponent(problem, name, options=options,
                           transient=parse_number(args.transient, "--transient"),
                           iterations=int(iterations), d0=parse_number(args.d0, "--d0"),
                           seed=int(parse_number(args.seed, "--seed")))
    print(f"{problem!r} with {name}")
    print(res.summary())
    if res.message:
        print(res.message)
    if args.out:
        import pandas as pd

        pd.DataFrame({"iteration": range(1, len(res.logs) + 1), "log_growth": res.logs}).to_csv(args.out, index=False)
        print(f"log growth per iteration -> {args.out}")
    return 0 if res.status == "success" else 1
