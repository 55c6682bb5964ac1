"""``nsbench paper``: regenerate every sweep of the paper, the locus figures and the comparison report."""

from __future__ import annotations

import argparse

from nsbench.cli._common import parse_number


def add_parser(sub) -> None:
    p = sub.add_parser("paper", help="reproduce the paper's bifurcation diagrams into reports/paper")
    p.add_argument("--out", default="reports/paper", help="output folder (default reports/paper)")
    p.add_argument("--points", default="400", help="parameter values per sweep (default 400)")
    p.add_argument("--transient", default="1000", help="transient time per value (default 1000)")
    p.add_argument("--record", default="64", help="section points per value (default 64)")
    p.add_argument("--workers", default=None, help="local processes (default: all cores)")
    p.add_argument("--case", default=None, help="only this case (1..4)")
    p.add_argument("--no-progress", action="store_true", help="no progress bars")
    p.set_defaults(handler=main)


def main(args: argparse.Namespace) -> int:
    from nsbench.bifurcation.paper import run_paper
    from nsbench.errors import ConfigError

    points = int(parse_number(args.points, "--points"))
    record = int(parse_number(args.record, "--record"))
    if points < 2 or record < 4:
        raise ConfigError(f"--points = {points} must be >= 2 and --record = {record} >= 4")
    case = int(parse_number(args.case, "--case")) if args.case is not None else None
    if case is not None and case not in (1, 2, 3, 4):
        raise ConfigError(f"--case = {case} must be 1, 2, 3 or 4")
    workers = int(parse_number(args.workers, "--workers")) if args.workers is not None else None
    run_paper(args.out, points=points, transient=parse_number(args.transient, "--transient"), record=record,
              workers=workers, only_case=case, progress=not args.no_progress)
    return 0
