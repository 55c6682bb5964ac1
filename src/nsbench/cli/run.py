"""``nsbench run``: the main job. Runs the packaged default suite (every registered
integrator at its accuracy levels on the 1-DOF standard scenario and the 2-DOF
cases 1-4, tau in [0, 300], but the tightest levels of the slowest methods, which
``--suite full`` adds) and writes the report to ``reports/latest``. It says first
how many runs it will time and how long that should take. Like ``bench``
and ``bifurcation`` it resumes: only cases missing from the folder are computed
(``--fresh`` starts over). Exit status 1 when a case crashed or a reference could not
be computed. The arguments map onto one :class:`nsbench.bench.command.RunRequest` and one call of
:func:`nsbench.bench.command.run_main_job`."""

from __future__ import annotations

import argparse

from nsbench.bench.command import RunRequest
from nsbench.cli._common import add_report_formats


def add_parser(sub) -> None:
    p = sub.add_parser("run", help="run the default benchmark suite and write reports/latest (the main job)")
    p.add_argument(
        "--out",
        default=None,
        help="output directory (default reports/latest; reports/<suite> for another packaged suite)",
    )
    p.add_argument(
        "--suite",
        default="default",
        metavar="SUITE",
        help="a packaged suite by name (default; full: every level of every integrator; "
        "chain-scaling; families: one method per family of methods) or a suite TOML file",
    )
    p.add_argument("--workers", default=None, help="processes (default: all cores)")
    p.add_argument(
        "--fresh",
        action="store_true",
        help="discard the cases already stored in --out (default: resume, computing only missing cases)",
    )
    p.add_argument("--resume", action="store_true", help=argparse.SUPPRESS)  # the default now; kept for scripts
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    add_report_formats(p)
    p.set_defaults(handler=main)


def main(args: argparse.Namespace) -> int:
    from nsbench.bench.command import run_main_job

    return run_main_job(request(args)).exit_code


def request(args: argparse.Namespace) -> RunRequest:
    """The main job the command line asks for (``--out`` unset: the suite's default folder)."""
    return RunRequest(
        args.suite,
        args.out,
        args.workers,
        fresh=args.fresh,
        progress=not args.no_progress,
        formats=args.formats,
    )
