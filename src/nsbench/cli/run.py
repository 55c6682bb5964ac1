"""``nsbench run``: the main job. Runs the packaged default suite (every registered
integrator at its accuracy levels on the 1-DOF standard scenario and the 2-DOF
cases 1-4, tau in [0, 300], but the tightest levels of the slowest methods, which
``--suite full`` adds) and writes the report to ``reports/latest``. It says first
how many runs it will time and how long that should take. Like ``bench``
and ``bifurcation`` it resumes: only cases missing from the folder are computed
(``--fresh`` starts over). Exit status 1 when a case crashed or a reference could not
be computed."""

from __future__ import annotations

import argparse

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
    import shlex
    import time

    from nsbench.cli.bench import run_and_report

    from nsbench.bench.suite import packaged_suites

    out = args.out
    if out is None:
        packaged = args.suite in packaged_suites() and args.suite != "default"
        out = f"reports/{args.suite}" if packaged else "reports/latest"
    tic = time.perf_counter()
    again = ["nsbench", "run"] + (["--suite", args.suite] if args.suite != "default" else [])
    again += ["--out", args.out] if args.out is not None else []
    again += ["--formats", args.formats] if args.formats != "png" else []
    code = run_and_report(
        args.suite, out, args.workers, not args.fresh, not args.no_progress, True, shlex.join(again), args.formats
    )
    print(f"nsbench run took {time.perf_counter() - tic:.0f} s")
    return code
