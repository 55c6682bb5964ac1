"""CVODE and IDA running the whole run natively (issue 47), against ``exact`` and their per-arc path, in one process.

``nsbench.simulate`` on the 2-DOF case 1 over ``tau`` in [0, 3000] (scaled by
``NSBENCH_BENCH_T_END``), ``check_points=0``, for ``cvode-adams``, ``cvode-bdf`` and
``ida`` on their native path (SUNDIALS' C API from a compiled loop), with ``exact``
and the same integrator on its per-arc path (``loop = 'per-arc'``: one ``advance`` per
arc through scikit-sundae) timed in the same rounds, interleaved. Figures in
``extra_info`` (best of the rounds for each run; the ratios of the bests):

``native_over_exact``
    wall time of the native run over ``exact``'s: the goal (issue 47) at most 10 for
    ``cvode-adams`` and ``cvode-bdf``, 20 for ``ida`` (174, 248 and 588 on the per-arc path
    when the issue was filed);
``native_over_exact_cpu``, ``per_arc_over_native_cpu``
    the same with the CPU time of the process (``cpu_time``, best of the rounds): on a machine
    shared with other work a long run is preempted more often than a short one, so the wall
    ratio grows with the load and the CPU ratio much less;
``per_arc_over_exact``, ``per_arc_over_native``
    the per-arc path's wall time over ``exact``'s, and over the native run's;
``outside_us_per_event``
    ``(wall_time - integrator_time) / events`` of the native run: what the run costs outside
    SUNDIALS' steps and nsbench's checks on them (the core's steps at each event, the records,
    the run's set-up in Python); the goal: at most 1 us;
``native_ms``, ``exact_ms``, ``per_arc_ms``, ``events``, ``nsteps``.

Warm runs only (an untimed first run compiles and loads). Speed is recorded and compared with
``benchmarks/baseline.json``, never asserted; the runs are checked to give the same events.
"""

from __future__ import annotations

import pytest

import nsbench
from nsbench.bench.pytest_bench import bench_span
from nsbench.integrators import get_integrator

SPAN = bench_span(3000.0)
ROUNDS = 5


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

    benchmark.pedantic(one_round, rounds=ROUNDS, iterations=1)
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
    benchmark.extra_info.update(integrator=name, problem="two-dof/1", t_end=SPAN, rounds=ROUNDS)
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
