"""Shared fixtures of the pytest-benchmark suites (generic: any benchmark module may use them).

``nsbench_references`` caches one reference run per problem for the whole
session; ``nsbench_bench(problem_config, integrator, options)`` times a case and
stores its tidy row (configs, counters, accuracy metrics) in ``extra_info``,
which ``nsbench ingest`` reads back. Run with ``pytest benchmarks/ --benchmark-only``.

Speed is recorded, never asserted: ``nsbench_baseline.record(...)`` stores a
benchmark's figures in ``extra_info``, compares its primary figure with the
measured baseline ``benchmarks/baseline.json`` (``baseline_ratio`` = this run /
baseline, so above 1 is slower) and prints one line per benchmark at the end of
the session. The compared figure is always a ratio measured in the same run, so
that a baseline holds on a machine of another speed: a benchmark's own ratio (to
another integrator timed in the session, a wall time over its workers' time), or
an absolute time divided by a calibration workload timed beside it
(``<figure>_per_calibration``, with ``calibration_s``). Environment variables:

``NSBENCH_BENCH_MAX_RATIO=R``
    opt-in gate: a benchmark whose ratio to the baseline exceeds ``R`` fails.
``NSBENCH_BENCH_WRITE_BASELINE=1``
    write the figures of the passing benchmarks of this run into the baseline
    (merged with its other entries when the machine is the same, replacing the
    file otherwise); the gate is off in such a run.
``NSBENCH_BENCH_BASELINE=PATH``
    another baseline file (default ``benchmarks/baseline.json``).
"""

from __future__ import annotations

import datetime as _dt
import json
import math
import os
import platform
import subprocess
from pathlib import Path
from typing import Any

import pytest

from nsbench.bench.pytest_bench import bench_case

BASELINE_ENV, MAX_RATIO_ENV, WRITE_ENV = (
    "NSBENCH_BENCH_BASELINE",
    "NSBENCH_BENCH_MAX_RATIO",
    "NSBENCH_BENCH_WRITE_BASELINE",
)
ROOT = Path(__file__).resolve().parents[1]


def _cpu_model() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.lower().startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def machine() -> dict[str, Any]:
    """What the figures depend on: CPU model, cores available to this process, platform."""
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    return {
        "cpu": _cpu_model(),
        "cores": cores,
        "logical_cpus": os.cpu_count(),
        "platform": platform.platform(),
        "python": platform.python_version(),
    }


def commit() -> dict[str, Any]:
    """Git commit of the checkout and whether it had uncommitted changes."""

    def git(*args: str) -> str:
        return subprocess.run(["git", *args], cwd=ROOT, capture_output=True, text=True, timeout=30).stdout.strip()

    try:
        return {"commit": git("rev-parse", "HEAD"), "dirty": bool(git("status", "--porcelain", "-uno"))}
    except (OSError, subprocess.SubprocessError):
        return {"commit": None, "dirty": None}


def _finite(value: Any) -> Any:
    """JSON-safe figure: NaN/inf become None (pytest-benchmark writes extra_info as JSON)."""
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value.item() if hasattr(value, "item") else value


#: Seconds spent timing the calibration workload beside each absolute figure (the best of its repeats).
CALIBRATION_S = 0.3


def is_seconds(figure: str) -> bool:
    """Whether ``figure`` is an absolute time (seconds, or nanoseconds per step), not a ratio."""
    return figure == "seconds" or figure.endswith("_s") or figure.endswith("_ns_per_step")


def entry_key(nodeid: str, config: dict[str, Any]) -> str:
    """Baseline key: the test id and the size of the run (figures of other sizes do not compare)."""
    return nodeid + " | " + ",".join(f"{k}={config[k]}" for k in sorted(config))


class Baseline:
    """The measured baseline, this session's comparisons and the entries to write back."""

    def __init__(self, path: Path):
        self.path = path
        self.data: dict[str, Any] = {}
        if path.is_file():
            self.data = json.loads(path.read_text())
        self.entries: dict[str, Any] = self.data.get("entries", {})
        self.write = os.environ.get(WRITE_ENV, "") not in ("", "0")
        limit = os.environ.get(MAX_RATIO_ENV, "")
        self.max_ratio = float(limit) if limit and not self.write else None
        self.lines: list[str] = []
        self.new: dict[str, dict[str, Any]] = {}
        self.failed: set[str] = set()

    def record(
        self,
        request,
        benchmark,
        figures: dict[str, Any],
        primary: str,
        config: dict[str, Any],
        label: str | None = None,
    ) -> float | None:
        """Store ``figures`` in ``extra_info`` and compare ``figures[primary]`` with the baseline.

        Parameters
        ----------
        request, benchmark
            The test's pytest ``request`` and pytest-benchmark ``benchmark`` fixtures.
        figures
            Named figures of this run, lower is better for ``primary`` (seconds, or a
            ratio of seconds to another integrator timed in the same session).
        primary
            The figure compared with the baseline.
        config
            The size of the run (span, values, ...): part of the baseline key.
        label
            Short name for the printed comparison (default: the test id).

        Returns
        -------
        float or None
            This run's primary figure over the baseline's (None without a baseline
            entry for this test at this size).
        """
        figures = {k: _finite(v) for k, v in figures.items()}
        if is_seconds(primary) and figures.get(primary) is not None:
            # an absolute time says little on another machine: compare it as a ratio to a fixed
            # workload timed now, in this run (nsbench.bench.estimate.calibrate, as `nsbench run` does)
            from nsbench.bench.estimate import calibrate

            cal = calibrate(CALIBRATION_S)
            figures["calibration_s"] = cal
            primary = f"{primary}_per_calibration"
            figures[primary] = figures[primary.removesuffix("_per_calibration")] / cal
        key = entry_key(request.node.nodeid, config)
        base = (self.entries.get(key) or {}).get("figures", {}).get(primary)
        value = figures.get(primary)
        ratio = value / base if value is not None and base else None
        benchmark.extra_info.update(figures)
        benchmark.extra_info.update(
            baseline_figure=primary, baseline_value=base, baseline_ratio=ratio, baseline_key=key
        )
        name = label or request.node.name
        if ratio is None:
            self.lines.append(
                f"{name}: {primary} = {value:.4g} (no baseline at this size)"
                if value is not None
                else f"{name}: {primary} not measured"
            )
        else:
            self.lines.append(f"{name}: {primary} = {value:.4g}, baseline {base:.4g}, ratio {ratio:.2f}")
        if value is not None:
            # the load of a shared machine explains most of the spread between runs: keep it with the figure
            load = os.getloadavg()[0] if hasattr(os, "getloadavg") else None
            self.new[key] = {
                "test": request.node.nodeid,
                "config": config,
                "primary": primary,
                "figures": figures,
                "load_avg_1min": load,
            }
        if ratio is not None and self.max_ratio is not None and ratio > self.max_ratio:
            pytest.fail(
                f"{name}: {primary} = {value:.4g} is {ratio:.2f} x the baseline {base:.4g} "
                f"> {MAX_RATIO_ENV}={self.max_ratio:g}",
                pytrace=False,
            )
        return ratio

    def save(self) -> str:
        """Merge the entries of the passing benchmarks into the baseline file."""
        keep = {k: v for k, v in self.new.items() if v["test"] not in self.failed}
        if not keep:
            return f"nothing measured: {self.path} left unchanged"
        here = machine()
        same = not self.entries or (
            {k: self.data.get("machine", {}).get(k) for k in ("cpu", "cores")} == {k: here[k] for k in ("cpu", "cores")}
        )
        entries = dict(self.entries) if same else {}
        stamp = {"date": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"), **commit()}
        for key, entry in keep.items():
            entries[key] = {**entry, **stamp}
        data = {
            "description": (
                "Figures measured by the benchmarks/ suites on the machine below (measured "
                "data, not goals). Each entry: the test, the size of the run, the figure "
                "compared ('primary'; lower is better), and when, at which commit and "
                "under which 1-minute load average of the machine it was measured. "
                "Regenerate with NSBENCH_BENCH_WRITE_BASELINE=1 python -m pytest "
                "benchmarks/ --benchmark-only (see docs/bench.md)."
            ),
            "machine": here,
            "entries": dict(sorted(entries.items())),
        }
        self.path.write_text(json.dumps(data, indent=1) + "\n")
        return f"wrote {len(keep)} entries to {self.path}" + (
            "" if same else " (another machine: the previous entries were dropped)"
        )


_SESSION: dict[str, Baseline] = {}


@pytest.fixture(scope="session")
def nsbench_baseline() -> Baseline:
    """The session's :class:`Baseline`; ``record(request, benchmark, figures, primary, config)``."""
    if "baseline" not in _SESSION:
        _SESSION["baseline"] = Baseline(Path(os.environ.get(BASELINE_ENV) or Path(__file__).with_name("baseline.json")))
    return _SESSION["baseline"]


def pytest_runtest_logreport(report) -> None:
    # a benchmark that failed a correctness check (or the gate) gives no baseline entry
    if report.failed and "baseline" in _SESSION:
        _SESSION["baseline"].failed.add(report.nodeid)


def pytest_sessionfinish(session) -> None:
    base = _SESSION.get("baseline")
    if base is not None and base.write:
        base.lines.append(base.save())


def pytest_terminal_summary(terminalreporter) -> None:
    base = _SESSION.get("baseline")
    if base is None or not base.lines:
        return
    gate = f"; fails past {base.max_ratio:g} x" if base.max_ratio is not None else ""
    terminalreporter.write_sep("-", f"nsbench figures vs baseline {base.path.name} (ratio > 1: slower{gate})")
    for line in base.lines:
        terminalreporter.write_line(line)


@pytest.fixture(scope="session")
def nsbench_references() -> dict:
    return {}


@pytest.fixture
def nsbench_bench(benchmark, nsbench_references, nsbench_baseline, request):
    """``run(problem_config, integrator, options=None, *, t_end=None, rounds=3) -> row``.

    Besides the row, ``extra_info`` gets the figures ``seconds`` (median of the
    rounds) and ``events_per_s``, and ``seconds`` is compared with the baseline.
    """

    def run(problem: dict, integrator: str, options: dict | None = None, **kwargs):
        row = bench_case(benchmark, nsbench_references, problem, integrator, options, **kwargs)
        if benchmark.stats:  # None with --benchmark-disable: nothing timed
            seconds = benchmark.stats.stats.median
            nodeid_size = {"t_end": row["t_end"], "options": json.dumps(options or {}, sort_keys=True)}
            nsbench_baseline.record(
                request,
                benchmark,
                {"seconds": seconds, "events_per_s": row["n_events"] / seconds if seconds > 0 else None},
                "seconds",
                nodeid_size,
            )
        return row

    return run
