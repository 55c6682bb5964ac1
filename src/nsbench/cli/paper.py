"""``nsbench paper``: regenerate every sweep of the paper, the locus figures and the comparison report."""

from __future__ import annotations

import argparse

from nsbench.bifurcation import MAX_SWEEP_POINTS
from nsbench.inputs import check_output_dir, parse_count, parse_real


def add_parser(sub) -> None:
    p = sub.add_parser("paper", help="reproduce the paper's bifurcation diagrams into reports/paper")
    p.add_argument("--out", default="reports/paper", help="output folder (default reports/paper)")
    p.add_argument("--points", default="400", help="parameter values per sweep (default 400)")
    p.add_argument("--transient", default="1000", help="transient time per value (default 1000)")
    p.add_argument("--record", default="64", help="section points per value (default 64)")
    p.add_argument("--workers", default=None, help="local processes (default: all cores)")
    p.add_argument("--case", default=None, help="only this case (1..4)")
    p.add_argument("--no-progress", action="store_true", help="no progress bars")
    p.add_argument(
        "--no-continuation",
        action="store_true",
        help="skip locating the named bifurcations by continuation of periodic orbits",
    )
    p.set_defaults(handler=main)


def main(args: argparse.Namespace) -> int:
    from nsbench.bifurcation.paper import run_paper

    points = parse_count(
        args.points, "--points", low=2, high=MAX_SWEEP_POINTS, bound="nsbench.bifurcation.MAX_SWEEP_POINTS"
    )
    record = parse_count(args.record, "--record", low=4, bound="MAX_RECORD")
    transient = parse_real(args.transient, "--transient", low=0.0, bound="MAX_SPAN")
    case = parse_count(args.case, "--case", low=1, high=4) if args.case is not None else None
    workers = None if args.workers is None else parse_count(args.workers, "--workers", low=1, bound="MAX_WORKERS")
    check_output_dir(args.out, "--out")
    run_paper(
        args.out,
        points=points,
        transient=transient,
        record=record,
        workers=workers,
        only_case=case,
        progress=not args.no_progress,
        continuation=not args.no_continuation,
    )
    return 0
