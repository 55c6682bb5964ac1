"""The sweep command as a user runs it: ``nsbench bifurcation`` end to end, as a whole process.

``nsbench bifurcation two-dof --case 1 --sweep v0=0.04:0.22:1000 --transient 1500
--record 100 --integrator NAME --workers 2`` is started from a shell-like subprocess and
timed from its start to its exit: the workers' start, their values, storing the chunks,
classifying the values, drawing the diagram (PNG, SVG and PDF), every import. Run with
``python -m pytest benchmarks/test_sweep_command.py --benchmark-only``.

Figures in ``extra_info`` (each round a fresh output folder, so nothing is resumed):

``wall_s``
    Seconds from the command's start to its exit (median of the rounds).
``parent_cpu_s``, ``parent_share``
    CPU seconds of the command's own process (not its workers), and that over
    ``wall_s``: what the command adds to its workers, as a share of what the user waits.
``values_s``, ``wall_over_values``
    The seconds the workers spent computing values (the sum of each value's
    ``wall_time`` in the stored table, over the number of workers), and ``wall_s``
    over it: 1 would be a command whose wall time is its workers' computing alone.
``ratio_to_exact`` (other integrators)
    ``wall_s`` over ``exact``'s, timed in the same session.
``batch_lanes``
    The values a worker runs together (:func:`nsbench.engine.batch_size`): heyoka's SIMD lanes,
    so ``heyoka``'s ratio is that of its batch mode (:mod:`nsbench.integrators._heyoka_batch`,
    each lane a value); 1 for an integrator that runs value by value.

The primary figure is a ratio measured in one run (``wall_over_values``; ``ratio_to_exact``
for the other integrators), so that the baseline holds on a machine of another speed.
The command runs with Python's usual bytecode cache (``PYTHONDONTWRITEBYTECODE`` is dropped from
its environment, so the untimed first run writes what an editable install has not yet written):
a user's shell caches bytecode, and a command that compiled every module of nsbench from its
source in each of its three processes would time that instead (about 0.4 s of the wall time).
``bytecode_cached`` in ``extra_info`` says so.

``NSBENCH_BENCH_T_END`` scales the sweep down as in ``test_sweep_speed.py`` (values,
recorded peaks); ``NSBENCH_COMMAND_INTEGRATORS`` (default ``exact,heyoka``) names the
integrators timed.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time

import pytest

from nsbench.bench.pytest_bench import bench_span

FULL_COUNT, FULL_TRANSIENT, FULL_RECORD, WORKERS = 1000, 1500.0, 100, 2
SCALE = bench_span(FULL_TRANSIENT) / FULL_TRANSIENT
TRANSIENT = FULL_TRANSIENT * SCALE
RECORD = FULL_RECORD if SCALE == 1 else max(5, round(FULL_RECORD * SCALE))
COUNT = FULL_COUNT if SCALE == 1 else max(10, round(FULL_COUNT * SCALE))
ROUNDS = 2
INTEGRATORS = [n.strip() for n in os.environ.get("NSBENCH_COMMAND_INTEGRATORS", "exact,heyoka").split(",") if n.strip()]
_walls: dict[str, float] = {}
#: The command's environment: this one, with Python's bytecode cache on (see the module's docstring).
ENV = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}

# The command run as `python -m nsbench ...` in this process's interpreter, with the process's own
# CPU seconds written at its exit (atexit runs after the command's sys.exit)
_WRAP = (
    "import atexit, json, resource, runpy, sys\n"
    "out = sys.argv.pop(1)\n"
    "atexit.register(lambda: open(out, 'w').write(json.dumps(resource.getrusage(resource.RUSAGE_SELF)[:2])))\n"
    "sys.argv[0] = 'nsbench'\n"
    "runpy.run_module('nsbench', run_name='__main__', alter_sys=True)\n"
)


def command(
    name: str,
    out,
    usage,
    count: int = COUNT,
    transient: float = TRANSIENT,
    record: int = RECORD,
    workers: int = WORKERS,
) -> list[str]:
    """The command line of the timed sweep, wrapped to record its own CPU seconds in ``usage``."""
    return [
        sys.executable,
        "-c",
        _WRAP,
        str(usage),
        "bifurcation",
        "two-dof",
        "--case",
        "1",
        "--sweep",
        f"v0=0.04:0.22:{count}",
        "--transient",
        f"{transient:g}",
        "--record",
        str(record),
        "--integrator",
        name,
        "--workers",
        str(workers),
        "--out",
        str(out),
        "--no-progress",
    ]


def run_command(name: str, out, usage) -> tuple[float, float, float]:
    """``(wall seconds, the command's own CPU seconds, the workers' computing seconds)`` of one run."""
    from nsbench.bifurcation.storage import SweepStore, points_summary

    tic = time.perf_counter()
    done = subprocess.run(command(name, out, usage), capture_output=True, text=True, env=ENV)
    wall = time.perf_counter() - tic
    assert done.returncode == 0, done.stderr[-2000:]
    cpu = sum(json.loads(usage.read_text()))
    summary = points_summary(SweepStore(out).load())
    assert len(summary) == COUNT and (summary["status"].isin(("success", "rest"))).all()
    return wall, cpu, float(summary["wall_time"].sum()) / WORKERS


@pytest.mark.parametrize("name", INTEGRATORS)
def test_sweep_command_end_to_end(benchmark, request, nsbench_baseline, tmp_path_factory, name):
    # the numba caches and heyoka's compilation of this machine, once, untimed
    warm = tmp_path_factory.mktemp("warm")
    subprocess.run(
        command(name, warm / "out", warm / "usage.json", count=2, transient=10.0, record=2, workers=1),
        capture_output=True,
        check=True,
        env=ENV,
    )
    runs = []

    def once():
        d = tmp_path_factory.mktemp(f"{name}-run")
        runs.append(run_command(name, d / "out", d / "usage.json"))

    benchmark.pedantic(once, rounds=ROUNDS, iterations=1)
    runs.sort()
    wall, cpu, values = runs[len(runs) // 2]
    figures = {
        "wall_s": wall,
        "parent_cpu_s": cpu,
        "parent_share": cpu / wall,
        "values_s": values,
        "wall_over_values": wall / values,
    }
    primary = "wall_over_values"
    _walls[name] = wall
    if name != "exact" and "exact" in _walls:
        figures["ratio_to_exact"] = wall / _walls["exact"]
        primary = "ratio_to_exact"
    from nsbench.engine import batch_size
    from nsbench.integrators import get_integrator

    lanes = batch_size(get_integrator(name))
    if name == "heyoka":  # the sweep goes through heyoka's batch mode: what this figure is about
        assert lanes > 1
    benchmark.extra_info.update(
        values=COUNT, transient=TRANSIENT, record=RECORD, workers=WORKERS, bytecode_cached=True, batch_lanes=lanes
    )
    nsbench_baseline.record(
        request,
        benchmark,
        figures,
        primary,
        {"values": COUNT, "transient": TRANSIENT, "record": RECORD, "workers": WORKERS},
        label=f"sweep command {name} ({COUNT} values, end to end)",
    )
