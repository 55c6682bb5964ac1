"""``nsbench lyapunov PROBLEM ...``: largest Lyapunov exponent of the mapping-point return map."""

from __future__ import annotations

import argparse

from nsbench.cli._common import add_problem_arguments, parse_number, problem_from_args
from nsbench.errors import ConfigError


def add_parser(sub) -> None:
    p = sub.add_parser("lyapunov", help="largest Lyapunov exponent of the mapping points (ensemble of Benettin runs)")
    add_problem_arguments(p)
    p.add_argument("--integrator", default=None,
                   help="registered integrator (default: exact for linear problems, henon-rk4 otherwise)")
    p.add_argument("--h", default=None, help="step size of henon-rk4")
    p.add_argument("--transient", default="1000",
                   help="time each member runs before its first mapping point used (default 1000)")
    p.add_argument("--iterations", default="10000",
                   help="return-map iterations in all, split evenly over the members (default 10000)")
    p.add_argument("--members", default="32",
                   help="independent estimates from perturbed starts; their spread gives the "
                        "standard error (default 32, at least 4)")
    p.add_argument("--d0", default="1e-8", help="renormalised separation (default 1e-8)")
    p.add_argument("--seed", default="0", help="seed of the start perturbations and directions (default 0)")
    p.add_argument("--workers", default="1", help="processes running members at once (default 1)")
    p.add_argument("--out", default=None, metavar="FILE.csv", help="write log(d/d0) per member and iteration")
    p.set_defaults(handler=main)


def _integer(text: str, what: str) -> int:
    value = parse_number(text, what)
    if not value.is_integer():  # also refuses inf and nan
        raise ConfigError(f"{what} = {text!r} is not an integer")
    return int(value)


def main(args: argparse.Namespace) -> int:
    from nsbench.bifurcation.lyapunov import largest_exponent

    problem = problem_from_args(args)
    name = args.integrator or ("exact" if problem.is_linear else "henon-rk4")
    options = {"h": parse_number(args.h, "--h")} if args.h is not None else {}
    res = largest_exponent(problem, name, options=options,
                           transient=parse_number(args.transient, "--transient"),
                           iterations=_integer(args.iterations, "--iterations"),
                           members=_integer(args.members, "--members"),
                           d0=parse_number(args.d0, "--d0"),
                           seed=_integer(args.seed, "--seed"),
                           workers=_integer(args.workers, "--workers"))
    print(f"{problem!r} with {name}")
    print(res.summary())
    if res.message:
        print(res.message)
    if args.out:
        import numpy as np
        import pandas as pd

        members, per = res.logs.shape
        pd.DataFrame({"member": np.repeat(np.arange(members), per),
                      "iteration": np.tile(np.arange(1, per + 1), members),
                      "log_growth": res.logs.ravel()}).to_csv(args.out, index=False)
        print(f"log growth per member and iteration -> {args.out}")
    return 0 if res.status == "success" else 1
