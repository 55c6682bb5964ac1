"""``nsbench bench`` and ``nsbench run`` as functions: :func:`run_bench` runs a :class:`BenchRequest`,
:func:`run_main_job` a :class:`RunRequest` (the packaged default suite into ``reports/latest``).

One request (checked at its construction: the figure formats, the worker count, the output folder,
the suite and its size, in that order) in, one :class:`BenchOutcome` out: the run's
:class:`~nsbench.bench.runner.RunSummary`, the report written, the sentences it opens with, and the
line saying why the command exits 1 (a case crashed, a reference could not be computed, or a plug-in
problem could not be built). Refused input raises a :class:`~nsbench.errors.ConfigError` before
anything runs (the command exits 2). The command lines (:mod:`nsbench.cli.bench`,
:mod:`nsbench.cli.run`) map their arguments onto the request and exit with the outcome's code; the plan,
the counts, the paths written, the answer and the failure line (``INCOMPLETE: ...``) are printed
here, as they come.
"""

from __future__ import annotations

import shlex
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from nsbench.inputs import check_output_dir, parse_count

if TYPE_CHECKING:  # pragma: no cover
    import pandas as pd

    from nsbench.bench.runner import RunSummary
    from nsbench.bench.suite import Suite

#: The figure formats of a report when none are asked for.
DEFAULT_FORMATS = "png"


@dataclass(frozen=True)
class BenchRequest:
    """One suite run into one folder, then its report, as asked.

    Each value may be the command line's text (``workers="2"``, ``formats="png,svg"``) or a Python
    value (``workers=2``, ``formats=("png",)``, ``suite=Suite(...)``); the construction parses and
    checks each once and keeps the parsed value, so that a bad one is refused before any case runs.

    Attributes
    ----------
    suite
        A suite TOML path, a packaged suite's name, a dict or a :class:`~nsbench.bench.suite.Suite`;
        kept as the loaded suite (a grid too large to expand is refused here).
    out
        Results folder (created if missing; an unwritable one is refused).
    workers
        Worker processes (``None``: all cores).
    resume
        Compute only the cases missing from ``out`` (``False``: discard them first).
    progress
        Draw the progress bar (the plan line is said either way).
    report
        Write the report after the run.
    resume_command
        The command that computes what this run leaves missing: a partial report names it.
    formats
        The report's figure formats.
    """

    suite: Any
    out: str | Path
    workers: int | str | None = None
    resume: bool = True
    progress: bool = True
    report: bool = True
    resume_command: str = ""
    formats: str | tuple[str, ...] = DEFAULT_FORMATS

    def __post_init__(self) -> None:
        from nsbench.bench.figures import parse_formats
        from nsbench.bench.suite import load_suite

        def keep(name: str, value: Any) -> None:
            object.__setattr__(self, name, value)

        keep("formats", parse_formats(self.formats))
        if self.workers is not None:
            keep("workers", parse_count(str(self.workers), "--workers", low=1, bound="MAX_WORKERS"))
        check_output_dir(self.out, "--out")
        suite = load_suite(self.suite)
        suite.check_size()  # a grid of 10^9 cases is refused here, not expanded
        keep("suite", suite)


@dataclass(frozen=True)
class BenchOutcome:
    """What :func:`run_bench` did: the run (``None`` when nothing ran), the report's page (``None``:
    none written), the report's opening sentences, and why the command exits 1 (``None``: it exits 0)."""

    summary: RunSummary | None
    report: Path | None = None
    answer: tuple[str, ...] = ()
    failure: str | None = None

    @property
    def exit_code(self) -> int:
        return 0 if self.failure is None else 1


def run_bench(request: BenchRequest) -> BenchOutcome:
    """Run the request's suite across the workers, print a summary, write the report.

    A plug-in problem's factory is built first in a worker under the suite's set-up limit: one that
    loops, crashes or raises costs its own rows (one line each on standard error), not the run. The
    results and the report are written even when a case crashed or a reference failed; the outcome's
    failure then names them.
    """
    from nsbench.bench.runner import run_suite
    from nsbench.factory_probe import probe_suite

    suite: Suite = request.suite
    suite, left_out = probe_suite(suite)
    for line in left_out:
        print(f"nsbench: bench: {line}", file=sys.stderr, flush=True)
    if left_out and not suite.problems:
        return _said(BenchOutcome(None, failure="no problem of the suite could be built; nothing was run"))
    extra = {"resume_command": request.resume_command} if request.resume_command else None
    # the plan line is said with or without the bar: a log or a script wants it too
    summary = run_suite(
        suite,
        request.out,
        workers=request.workers,  # type: ignore[arg-type]  # parsed to an int at construction
        resume=request.resume,
        progress=request.progress,
        provenance_extra=extra,
        plan=True,
    )
    counts = summary.results["status"].value_counts().to_dict() if len(summary.results) else {}
    print(
        f"{summary.n_cases} cases: {summary.n_computed} computed, {summary.n_resumed} already stored; "
        + ", ".join(f"{k}: {v}" for k, v in counts.items())
    )
    print(f"results -> {summary.out / 'results.parquet'} (and results.csv)")
    page = None
    if request.report and len(summary.results):
        from nsbench.bench.report import write_report

        formats: tuple[str, ...] = request.formats  # type: ignore[assignment]  # parsed at construction
        if request.progress:
            print("nsbench: writing the report (tables, figures)", file=sys.stderr, flush=True)
        page = write_report(summary.out, summary.results, formats).html
        print(f"report  -> {page} (and report.md, table.tex, figures/ as {', '.join(formats).upper()})")
    words = tuple(answer(summary.out, summary.results)) if len(summary.results) else ()
    if words:  # the report's first sentences: the answer, where a log shows it
        print("the answer:")
        for line in words:
            print(f"  - {line}")
    short = [*left_out, *summary.problems()] if not summary.ok or left_out else []
    return _said(BenchOutcome(summary, page, words, "; ".join(short) if short else None))


def _said(outcome: BenchOutcome) -> BenchOutcome:
    """The outcome, its failure said as the command says it (the log's last word on a short run)."""
    if outcome.failure is not None:
        print(f"INCOMPLETE: {outcome.failure}")
    return outcome


def answer(out: str | Path, results: pd.DataFrame) -> list[str]:
    """The sentences the report opens with (:func:`nsbench.bench.summary.findings`), for the console."""
    from nsbench.bench import storage
    from nsbench.bench.summary import conditioning_table, findings, problem_summary, wrong_sequences
    from nsbench.bench.tables import DEFAULT_TARGETS

    targets = tuple(storage.read_provenance(out).get("suite", {}).get("targets", DEFAULT_TARGETS))
    summary = problem_summary(results, targets)
    return findings(summary, wrong_sequences(results), conditioning_table(results)) if len(summary) else []


@dataclass(frozen=True)
class RunRequest:
    """``nsbench run``: a packaged suite (or a suite file) into its default folder.

    ``out`` defaults to ``reports/latest`` for the default suite and for a suite file, and to
    ``reports/<suite>`` for another packaged suite. The :class:`BenchRequest` it stands for is
    built (and so every value checked) at the construction, with the command that resumes it.

    Attributes
    ----------
    suite, out, workers, formats, progress
        As in :class:`BenchRequest` (``out=None``: the default folder).
    fresh
        Discard the cases already stored in the folder.
    bench
        The run asked for (set at the construction).
    """

    suite: str | Path = "default"
    out: str | Path | None = None
    workers: int | str | None = None
    fresh: bool = False
    progress: bool = True
    formats: str | tuple[str, ...] = DEFAULT_FORMATS
    bench: BenchRequest = field(init=False)

    def __post_init__(self) -> None:
        from nsbench.bench.suite import packaged_suites

        suite = str(self.suite)
        out = self.out
        if out is None:
            packaged = suite in packaged_suites() and suite != "default"
            out = f"reports/{suite}" if packaged else "reports/latest"
        again = ["nsbench", "run"] + (["--suite", suite] if suite != "default" else [])
        again += ["--out", str(self.out)] if self.out is not None else []
        formats = self.formats if isinstance(self.formats, str) else ",".join(self.formats)
        again += ["--formats", formats] if formats != DEFAULT_FORMATS else []
        request = BenchRequest(
            suite,
            out,
            self.workers,
            resume=not self.fresh,
            progress=self.progress,
            report=True,
            resume_command=shlex.join(again),
            formats=self.formats,
        )
        object.__setattr__(self, "bench", request)


def run_main_job(request: RunRequest) -> BenchOutcome:
    """Run the request's suite and write its report (:func:`run_bench`), then say how long it took."""
    tic = time.perf_counter()
    outcome = run_bench(request.bench)
    print(f"nsbench run took {time.perf_counter() - tic:.0f} s")
    return outcome
