"""``nsbench bench SUITE.toml --out DIR``: run a suite across all cores, then write its report.

Exit status 1 when a case crashed or a reference could not be computed (see
:attr:`nsbench.bench.RunSummary.ok`); the results and the report are written anyway.
"""

from __future__ import annotations

import argparse
import shlex
import sys

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


def run_and_report(
    suite,
    out: str,
    workers: str | int | None,
    resume: bool,
    progress: bool,
    report: bool,
    resume_command: str = "",
    formats: str = "png",
) -> int:
    """Shared by ``bench`` and ``run``: run, print a summary, write the report.

    ``workers`` is the ``--workers`` text (or a count). Bad input (workers, an
    unwritable ``out``, a bad suite, too many cases) is refused before anything runs.
    ``resume_command`` is the command that computes what this run leaves missing: a partial
    report names it (:func:`nsbench.bench.report.completeness`). ``formats`` is the ``--formats`` text.

    Returns 0, or 1 when a case crashed or a reference could not be computed
    (the results and the report are written all the same).
    """
    from nsbench.bench import load_suite, run_suite
    from nsbench.cli._common import parse_report_formats
    from nsbench.inputs import check_output_dir, parse_count

    figure_formats = parse_report_formats(formats)  # refused before anything runs

    if workers is not None:
        workers = parse_count(str(workers), "--workers", low=1, bound="MAX_WORKERS")
    check_output_dir(out, "--out")
    suite = load_suite(suite)
    suite.check_size()  # a grid of 10^9 cases is refused here, not expanded
    # a plug-in problem's factory is built first in a worker under the suite's set-up limit: one that
    # loops, crashes or raises costs its own rows (one line each), not the run
    from nsbench.factory_probe import probe_suite

    suite, left_out = probe_suite(suite)
    for line in left_out:
        print(f"nsbench: bench: {line}", file=sys.stderr, flush=True)
    if left_out and not suite.problems:
        print("INCOMPLETE: no problem of the suite could be built; nothing was run")
        return 1
    extra = {"resume_command": resume_command} if resume_command else None
    # the plan line is said with or without the bar: a log or a script wants it too
    summary = run_suite(
        suite, out, workers=workers, resume=resume, progress=progress, provenance_extra=extra, plan=True
    )
    counts = summary.results["status"].value_counts().to_dict() if len(summary.results) else {}
    print(
        f"{summary.n_cases} cases: {summary.n_computed} computed, {summary.n_resumed} already stored; "
        + ", ".join(f"{k}: {v}" for k, v in counts.items())
    )
    print(f"results -> {summary.out / 'results.parquet'} (and results.csv)")
    if report and len(summary.results):
        from nsbench.bench.report import write_report

        if progress:
            print("nsbench: writing the report (tables, figures)", file=sys.stderr, flush=True)
        rep = write_report(summary.out, summary.results, figure_formats)
        print(f"report  -> {rep.html} (and report.md, table.tex, figures/ as {', '.join(figure_formats).upper()})")
    words = answer(summary.out, summary.results) if len(summary.results) else []
    if words:  # the report's first sentences: the answer, where a log shows it
        print("the answer:")
        for line in words:
            print(f"  - {line}")
    if not summary.ok or left_out:
        print("INCOMPLETE: " + "; ".join([*left_out, *summary.problems()]))
        return 1
    return 0


def answer(out, results) -> list[str]:
    """The sentences the report opens with (:func:`nsbench.bench.summary.findings`), for the console."""
    from nsbench.bench import storage
    from nsbench.bench.summary import conditioning_table, findings, problem_summary, wrong_sequences
    from nsbench.bench.tables import DEFAULT_TARGETS

    targets = tuple(storage.read_provenance(out).get("suite", {}).get("targets", DEFAULT_TARGETS))
    summary = problem_summary(results, targets)
    return findings(summary, wrong_sequences(results), conditioning_table(results)) if len(summary) else []


def main(args: argparse.Namespace) -> int:
    again = shlex.join(  # resuming is the default
        ["nsbench", "bench", args.suite, "--out", args.out]
        + (["--formats", args.formats] if args.formats != "png" else [])
    )
    return run_and_report(
        args.suite,
        args.out,
        args.workers,
        not args.fresh,
        not args.no_progress,
        not args.no_report,
        again,
        args.formats,
    )
