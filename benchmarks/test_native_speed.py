"""heyoka running the event loop itself (``loop = 'native'``, issue 47) against ``exact``, in one process.

``test_heyoka_native_against_exact``: ``nsbench.simulate`` on the 2-DOF case 1 over ``tau`` in
[0, 3000] (scaled by ``NSBENCH_BENCH_T_END``), ``exact``, ``heyoka`` (native) and ``heyoka``
with ``loop = 'per-arc'`` interleaved round by round, each with ``check_points=0`` (no state
inside a step: what the bench times) and with the defaults (3001 check points). Figures in
``extra_info`` (best of the rounds for each, then the ratio):

``native_over_exact_cp0``
    heyoka native's wall time over exact's, ``check_points=0`` (the goal: at most 1.5);
``native_over_exact``
    the same with the default check points (the goal: at most 2);
``per_arc_over_exact_cp0``, ``per_arc_over_exact``
    the per-arc path's, for comparison (7 and more before issue 47);
``outside_us_per_event``
    ``(wall_time - integrator_time) / events`` of the native run, ``check_points=0``: what the
    run costs outside heyoka's propagation (the callbacks' Python glue, the core's compiled
    steps, the run's setting up), per event (the goal: at most 1 us);
``native_cpu_over_exact_cp0``
    the ratio on the process's CPU clock (less sensitive to other programs on the machine).

``test_sweep_command_native_against_exact``: the 1000-value sweep ``nsbench bifurcation
two-dof --case 1 --sweep v0=0.04:0.22:1000 --transient 1500 --record 100 --workers 2`` from a
subprocess, with ``--integrator exact`` and ``--integrator heyoka`` alternately
(:mod:`benchmarks.test_sweep_command`'s command line); ``heyoka_over_exact`` is the ratio of
the best wall times (the goal: at most 1.2; 2.8 before issue 47).

``test_sundials_native_against_exact``: CVODE and IDA on their native path (issue 47: SUNDIALS'
C API from a compiled loop), ``nsbench.simulate`` on the same run with ``check_points=0``, for
``cvode-adams``, ``cvode-bdf`` and ``ida``, with ``exact`` and the same integrator on its per-arc
path (``loop = 'per-arc'``: one ``advance`` per arc through scikit-sundae) in the same rounds,
interleaved. Figures (best of the rounds for each run; the ratios of the bests):

``native_over_exact``
    wall time of the native run over ``exact``'s: the goal at most 10 for ``cvode-adams`` and
    ``cvode-bdf``, 20 for ``ida`` (174, 248 and 588 on the per-arc path when the issue was filed);
``native_over_exact_cpu``, ``per_arc_over_native_cpu``
    the same with the CPU time of the process (``cpu_time``): on a machine shared with other work
    a long run is preempted more often than a short one, so the wall ratio grows with the load and
    the CPU ratio much less;
``per_arc_over_exact``, ``per_arc_over_native``
    the per-arc path's wall time over ``exact``'s, and over the native run's;
``outside_us_per_event``
    ``(wall_time - integrator_time) / events`` of the native run: what the run costs outside
    SUNDIALS' steps and nsbench's checks on them (the core's steps at each event, the records,
    the run's set-up in Python); the goal: at most 1 us;
``native_ms``, ``exact_ms``, ``per_arc_ms``, ``events``, ``nsteps``.

Speed is recorded and compared with ``benchmarks/baseline.json``, never asserted.
"""

from __future__ import annotations

import os
import subprocess
import sys
import time

import pytest

import nsbench
from nsbench.bench.pytest_bench import bench_span
from nsbench.integrators import get_integrator

SPAN = bench_span(3000.0)
ROUNDS = 7


def _best(runs):
    return min(runs, key=lambda r: r.wall_time)


def test_heyoka_native_against_exact(benchmark, request, nsbench_baseline):
    problem = nsbench.get_problem("two-dof", case=1)
    integs = {
        "exact": get_integrator("exact"),
        "native": get_integrator("heyoka", loop="native"),
        "per-arc": get_integrator("heyoka", loop="per-arc"),
    }
    for integ in integs.values():  # set up, compile, load: untimed
        nsbench.simulate(problem, integ, min(SPAN, 50.0))
    runs: dict[tuple[str, int | None], list] = {(k, cp): [] for k in integs for cp in (0, None)}

    def one_round():
        for cp in (0, None):
            for name, integ in integs.items():
                runs[(name, cp)].append(nsbench.simulate(problem, integ, SPAN, check_points=cp))

    benchmark.pedantic(one_round, rounds=ROUNDS, iterations=1)
    assert all(r.ok for rs in runs.values() for r in rs)
    best = {key: _best(rs) for key, rs in runs.items()}
    native0, exact0 = best[("native", 0)], best[("exact", 0)]
    assert native0.loop == "native" and len(native0.events) == len(exact0.events)
    events = len(native0.events)
    figures = {
        "events": events,
        "exact_cp0_s": exact0.wall_time,
        "native_cp0_s": native0.wall_time,
        "native_over_exact_cp0": native0.wall_time / exact0.wall_time,
        "native_over_exact": best[("native", None)].wall_time / best[("exact", None)].wall_time,
        "per_arc_over_exact_cp0": best[("per-arc", 0)].wall_time / exact0.wall_time,
        "per_arc_over_exact": best[("per-arc", None)].wall_time / best[("exact", None)].wall_time,
        "outside_us_per_event": 1e6 * (native0.wall_time - native0.integrator_time) / events,
        "native_cpu_over_exact_cp0": min(r.cpu_time for r in runs[("native", 0)])
        / min(r.cpu_time for r in runs[("exact", 0)]),
    }
    benchmark.extra_info.update(problem="two-dof/1", t_end=SPAN, rounds=ROUNDS)
    nsbench_baseline.record(
        request,
        benchmark,
        figures,
        "native_over_exact_cp0",
        {"t_end": SPAN},
        label=(
            f"heyoka native 2-DOF case 1 [0, {SPAN:g}]: {figures['native_over_exact_cp0']:.2f}x exact "
            f"(check_points=0), {figures['native_over_exact']:.2f}x (defaults), "
            f"{figures['outside_us_per_event']:.2f} us/event outside heyoka"
        ),
    )


COUNT = 1000 if SPAN == 3000.0 else max(10, round(1000 * SPAN / 3000.0))
TRANSIENT = 1500.0 * SPAN / 3000.0
RECORD = 100 if SPAN == 3000.0 else max(5, round(100 * SPAN / 3000.0))
#: The command's environment: this one, with Python's bytecode cache on (as test_sweep_command.py).
ENV = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}


def _sweep(name: str, out) -> float:
    argv = [
        sys.executable,
        "-m",
        "nsbench",
        "bifurcation",
        "two-dof",
        "--case",
        "1",
        "--sweep",
        f"v0=0.04:0.22:{COUNT}",
        "--transient",
        f"{TRANSIENT:g}",
        "--record",
        str(RECORD),
        "--integrator",
        name,
        "--workers",
        "2",
        "--out",
        str(out),
        "--no-progress",
    ]
    tic = time.perf_counter()
    done = subprocess.run(argv, capture_output=True, text=True, env=ENV)
    wall = time.perf_counter() - tic
    assert done.returncode == 0, done.stderr[-2000:]
    return wall


@pytest.mark.parametrize("rounds", [2])
def test_sweep_command_native_against_exact(benchmark, request, nsbench_baseline, tmp_path_factory, rounds):
    walls: dict[str, list[float]] = {"exact": [], "heyoka": []}
    _sweep("heyoka", tmp_path_factory.mktemp("warm"))  # compiles and loads once per install: untimed
    counter = iter(range(10**6))

    def one_round():
        for name in walls:
            walls[name].append(_sweep(name, tmp_path_factory.mktemp(f"{name}{next(counter)}")))

    benchmark.pedantic(one_round, rounds=rounds, iterations=1)
    figures = {
        "exact_s": min(walls["exact"]),
        "heyoka_s": min(walls["heyoka"]),
        "heyoka_over_exact": min(walls["heyoka"]) / min(walls["exact"]),
    }
    benchmark.extra_info.update(values=COUNT, transient=TRANSIENT, record=RECORD, workers=2)
    nsbench_baseline.record(
        request,
        benchmark,
        figures,
        "heyoka_over_exact",
        {"values": COUNT, "transient": TRANSIENT, "record": RECORD},
        label=f"sweep command, {COUNT} values: heyoka {figures['heyoka_over_exact']:.2f}x exact",
    )


SUNDIALS_ROUNDS = 5


@pytest.mark.parametrize("name", ["cvode-adams", "cvode-bdf", "ida"])
def test_sundials_native_against_exact(benchmark, request, nsbench_baseline, name):
    problem = nsbench.get_problem("two-dof", case=1)
    integs = {
        "exact": get_integrator("exact"),
        "native": get_integrator(name),
        "per-arc": get_integrator(name, loop="per-arc"),
    }
    for integ in integs.values():
        nsbench.simulate(problem, integ, min(SPAN, 50.0), check_points=0)  # set up, compile, load
    runs: dict[str, list] = {key: [] for key in integs}

    def one_round():
        order = list(integs) if len(runs["exact"]) % 2 == 0 else list(integs)[::-1]
        for key in order:
            runs[key].append(nsbench.simulate(problem, integs[key], SPAN, check_points=0))

    benchmark.pedantic(one_round, rounds=SUNDIALS_ROUNDS, iterations=1)
    native, exact, per_arc = (min(runs[k], key=lambda r: r.wall_time) for k in ("native", "exact", "per-arc"))
    assert native.loop == "native" and per_arc.loop == "per-arc"
    assert native.ok and per_arc.ok and exact.ok, (native.message, per_arc.message)
    assert native.events.equals(per_arc.events), "the native run must be the per-arc run"
    assert len(native.events) == len(exact.events)
    events = len(native.events)
    figures = {
        "native_over_exact": native.wall_time / exact.wall_time,
        "native_over_exact_cpu": _best_cpu(runs["native"]) / _best_cpu(runs["exact"]),
        "per_arc_over_native_cpu": _best_cpu(runs["per-arc"]) / _best_cpu(runs["native"]),
        "per_arc_over_exact": per_arc.wall_time / exact.wall_time,
        "per_arc_over_native": per_arc.wall_time / native.wall_time,
        "outside_us_per_event": 1e6 * (native.wall_time - native.integrator_time) / events,
        "native_ms": 1e3 * native.wall_time,
        "exact_ms": 1e3 * exact.wall_time,
        "per_arc_ms": 1e3 * per_arc.wall_time,
        "events": events,
        "nsteps": native.counters.nsteps,
    }
    benchmark.extra_info.update(integrator=name, problem="two-dof/1", t_end=SPAN, rounds=SUNDIALS_ROUNDS)
    nsbench_baseline.record(
        request,
        benchmark,
        figures,
        "native_over_exact",
        {"t_end": SPAN},
        label=(
            f"{name} native 2-DOF case 1 [0, {SPAN:g}]: {figures['native_over_exact']:.1f}x exact "
            f"(CPU {figures['native_over_exact_cpu']:.1f}x) "
            f"(per-arc {figures['per_arc_over_exact']:.0f}x), {figures['outside_us_per_event']:.2f} us/event outside"
        ),
    )


def _best_cpu(runs) -> float:
    return min(r.cpu_time for r in runs)
