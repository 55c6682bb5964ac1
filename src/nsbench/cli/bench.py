"""``nsbench bench SUITE.toml --out DIR``: run a suite across all cores, then write its report.

The arguments map onto one :class:`nsbench.bench.command.BenchRequest` (every value checked there,
once, before anything runs: exit 2 when refused) and one call of
:func:`nsbench.bench.command.run_bench`. Exit status 1 when a case crashed or a reference could not
be computed (see :attr:`nsbench.bench.RunSummary.ok`); the results and the report are written anyway.
"""

from __future__ import annotations

import argparse
import shlex

from nsbench.bench.command import BenchRequest
from nsbench.cli._common import add_report_formats


def add_parser(sub) -> None:
    p = sub.add_parser("bench", help="run a benchmark suite (TOML) into an output directory")
    p.add_argument("suite", metavar="SUITE.toml", help="suite file, or 'default' for the packaged suite")
    p.add_argument("--out", required=True, metavar="DIR", help="output directory (created if missing)")
    p.add_argument(
        "--workers", default=None, help="worker processes (default: all cores; 1: one worker, still a child process)"
    )
    p.add_argument(
        "--fresh",
        action="store_true",
        help="discard the cases already stored in DIR (default: resume, computing only missing cases)",
    )
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.add_argument("--no-report", action="store_true", help="do not write the report afterwards")
    add_report_formats(p)
    p.set_defaults(handler=main)


def main(args: argparse.Namespace) -> int:
    from nsbench.bench.command import run_bench

    return run_bench(request(args)).exit_code


def request(args: argparse.Namespace) -> BenchRequest:
    """The run the command line asks for, with the command that resumes it (resuming is the default)."""
    again = ["nsbench", "bench", args.suite, "--out", args.out]
    again += ["--formats", args.formats] if args.formats != "png" else []
    return BenchRequest(
        args.suite,
        args.out,
        args.workers,
        resume=not args.fresh,
        progress=not args.no_progress,
        report=not args.no_report,
        resume_command=shlex.join(again),
        formats=args.formats,
    )
