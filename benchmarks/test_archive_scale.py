"""The results archive at scale (issue 53, item 5): ``nsbench archive show`` and ``nsbench archive site``
over 1000 runs of the default suite, and ``nsbench.archive.load`` of them.

The archive is built once per session from one real run of the default suite (``nsbench bench default``,
a few minutes on 2 cores; ``NSBENCH_ARCHIVE_RUN=FOLDER`` reuses a results folder of it). The run is
added with ``archive add`` (every row re-graded against the archive's own references, its
bifurcation-target rows kept), then its archived files are copied ``N - 1`` times
(``NSBENCH_ARCHIVE_RUNS=N``, default 1000), each copy on one of four machine names so that the
leaderboard has four blocks. A copy is the run's re-graded rows, events and bifurcation rows with
its timestamps moved by ``k`` seconds, so that its rows differ and its id is the archive's own id of
them (:func:`nsbench.archive.layout.run_id`), written with the archive's own writer
(:func:`nsbench.archive.layout.write_run`: the values' checksums and the manifest's SHA-256 sealed
anew). Every grade in it is the one run's real grade, copied: nothing is graded anew or made up. Run with
``python -m pytest benchmarks/test_archive_scale.py --benchmark-only`` (``NSBENCH_ARCHIVE_RUNS=20``
for a quick look).

Timed, one round each (a round takes up to half a minute at N = 1000): ``load`` (events included, every
file checked), ``load(..., events=False)`` (what ``show`` and ``site`` read, less the rows' dense states
and event logs: ``bulky=False``), and ``nsbench archive
show`` and ``nsbench archive site`` as a user runs them, each a fresh process from its start to its
exit (the interpreter's start and every import included). Figures in ``extra_info``: ``seconds``,
``runs``, ``rows``, ``events`` and the machine's 1-minute load average when the round started. Speed
is recorded, never asserted (the budget, under a minute on 2 cores, is a benchmark, not a test):
only the tables' sizes are checked.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from dataclasses import replace
from pathlib import Path

import pandas as pd
import pytest

from nsbench.archive import add_run, layout, load

RUNS = int(os.environ.get("NSBENCH_ARCHIVE_RUNS", "1000"))
MACHINES = 4
if RUNS < 1:
    raise ValueError(f"NSBENCH_ARCHIVE_RUNS={RUNS}: give at least 1 run")


def _default_run(tmp: Path) -> Path:
    """The results folder of one run of the default suite: ``NSBENCH_ARCHIVE_RUN``, or run here."""
    given = os.environ.get("NSBENCH_ARCHIVE_RUN")
    if given:
        return Path(given)
    out = tmp / "default"
    done = subprocess.run(
        [sys.executable, "-m", "nsbench", "bench", "default", "--out", str(out), "--no-progress", "--no-report"],
        capture_output=True,
        text=True,
    )
    assert done.returncode == 0, done.stderr[-2000:]
    return out


def _shifted(frame: pd.DataFrame, seconds: int) -> pd.DataFrame:
    """``frame`` with its ``timestamp`` column (UTC ISO times) moved by ``seconds``."""
    if "timestamp" not in frame or frame.empty:
        return frame
    moved = pd.to_datetime(frame["timestamp"].astype(str), utc=True, format="ISO8601") + pd.Timedelta(seconds=seconds)
    return frame.assign(timestamp=moved.map(lambda t: t.isoformat(timespec="seconds")).astype("string"))


def copy_run(archive: Path, run: layout.Run, k: int, machine: str) -> layout.Run:
    """The ``k``-th copy of archived ``run`` (see the module's docstring), written with the archive's writer."""
    folder = layout.run_folder(archive, run.run_id)
    rows = _shifted(layout.read_table(folder / layout.ROWS), k)
    rid = layout.run_id(rows)
    rows = rows.assign(run_id=pd.array([rid] * len(rows), dtype="string"))
    events = layout.read_table(folder / layout.EVENTS).assign(run_id=rid)
    prov = json.loads((folder / layout.PROVENANCE).read_text(encoding="utf-8"))
    bif = None
    if layout.BIFURCATIONS in run.sha256:
        bif = _shifted(layout.read_table(folder / layout.BIFURCATIONS), k).assign(run_id=rid)
    entry = replace(run, run_id=rid, machine=machine, sha256={}, source=f"{run.source} (copy {k})")
    return layout.write_run(archive, entry, rows, events, prov, bif)


@pytest.fixture(scope="module")
def archive(tmp_path_factory) -> tuple[Path, layout.Run]:
    """An archive of :data:`RUNS` runs: one real run of the default suite and its copies."""
    tmp = tmp_path_factory.mktemp("archive-scale")
    path = tmp / "arch"
    outcome = add_run(_default_run(tmp), path, machine="machine-0")
    assert outcome.run is not None and not outcome.refused, outcome.refused[:5]
    tic = time.perf_counter()
    ids = {outcome.run.run_id}
    for k in range(1, RUNS):
        ids.add(copy_run(path, outcome.run, k, f"machine-{k % MACHINES}").run_id)
    assert len(ids) == RUNS  # every copy another id: none overwrote another
    print(f"\n{RUNS} runs built in {time.perf_counter() - tic:.1f} s ({path})")
    return path, outcome.run


def _record(request, benchmark, nsbench_baseline, seconds: float, load_avg: float, figures: dict) -> None:
    nsbench_baseline.record(
        request,
        benchmark,
        {"seconds": seconds, "load_avg_at_start": load_avg, **figures},
        "seconds",
        {"runs": RUNS},
        label=f"{request.node.name} ({RUNS} runs of the default suite)",
    )


def _timed(benchmark, fn):
    """``(result, seconds, load average at the start)`` of one round of ``fn``."""
    out: dict = {}

    def once():
        out["load"] = os.getloadavg()[0]
        tic = time.perf_counter()
        out["result"] = fn()
        out["seconds"] = time.perf_counter() - tic

    benchmark.pedantic(once, rounds=1, iterations=1)
    return out["result"], out["seconds"], out["load"]


@pytest.mark.parametrize("events", [True, False], ids=["with-events", "rows-only"])
def test_load(benchmark, request, nsbench_baseline, archive, events):
    path, run = archive
    tables, seconds, load_avg = _timed(benchmark, lambda: load(path, events=events))
    assert len(tables.runs) == RUNS and len(tables.rows) == RUNS * run.n_rows
    assert int(tables.rows["graded"].sum()) == RUNS * run.n_graded
    folder = layout.run_folder(path, run.run_id)
    n_events = len(layout.read_table(folder / layout.EVENTS))
    assert len(tables.events) == (RUNS * n_events if events else 0)
    if layout.BIFURCATIONS in run.sha256:
        assert len(tables.bifurcations) == RUNS * len(layout.read_table(folder / layout.BIFURCATIONS))
    _record(
        request,
        benchmark,
        nsbench_baseline,
        seconds,
        load_avg,
        {"runs": RUNS, "rows": len(tables.rows), "events": len(tables.events)},
    )


def _command(*argv: str) -> subprocess.CompletedProcess:
    done = subprocess.run([sys.executable, "-m", "nsbench", "archive", *argv], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr[-2000:]
    return done


def test_show(benchmark, request, nsbench_baseline, archive):
    path, run = archive
    done, seconds, load_avg = _timed(benchmark, lambda: _command("show", str(path)))
    out = done.stdout
    assert out.startswith(f"{RUNS} run(s) in {path}:")
    listed = [line for line in out.splitlines() if line.startswith("  ") and " commit " in line]
    assert len(listed) == RUNS
    for m in range(min(RUNS, MACHINES)):  # a leaderboard block per machine
        assert f", switching-time error <= 0.0001 (machine-{m}, {run.environment})" in out
    _record(request, benchmark, nsbench_baseline, seconds, load_avg, {"runs": RUNS, "lines": len(out.splitlines())})


def test_site(benchmark, request, nsbench_baseline, archive, tmp_path):
    path, run = archive
    done, seconds, load_avg = _timed(benchmark, lambda: _command("site", str(path), "--out", str(tmp_path / "site")))
    blocks = min(RUNS, MACHINES)
    assert f"({blocks} figure(s))" in done.stdout
    page = (tmp_path / "site" / "index.html").read_text(encoding="utf-8")
    # the runs table names every run: each id at least once
    ids = [r.run_id for r in layout.runs(path)]
    assert len(ids) == RUNS and all(rid in page for rid in ids)
    assert len(list((tmp_path / "site" / "figures").glob("*/runtime_distribution.png"))) == blocks
    _record(request, benchmark, nsbench_baseline, seconds, load_avg, {"runs": RUNS, "page_bytes": len(page.encode())})
