"""Speed of the hybrid core itself: events per second and the core's own cost per event.

``nsbench.simulate`` on the 2-DOF case 1 over ``tau`` in [0, 3000] (scaled by
``NSBENCH_BENCH_T_END``), one core, for every integrator with a compiled arc
kernel. Each round is a warm run (compilation and the mode tables are built by
an untimed first run). Figures in ``extra_info``:

``events_per_s``
    events over the run's wall time (the paper-scale goal for ``exact``: at least
    200,000 per second on one core);
``overhead_us_per_event``
    ``(wall_time - integrator_time) / events`` in microseconds: the core's own
    work (settle step, guards, records, the clock) per event, where
    ``integrator_time`` is the time the same loop spends inside the arc kernel
    (the goal: at most 2 us);
``engine_share``
    ``1 - integrator_time / wall_time``;
``call_s``, ``events_per_s_call``
    the whole ``simulate`` call, which adds a fixed cost (pandas frames of the
    events and the provenance) to the run's ``wall_time``.

Speed is recorded and compared with ``benchmarks/baseline.json``, never asserted.
"""

from __future__ import annotations

import statistics

import pytest

import nsbench
from nsbench.bench.pytest_bench import bench_span
from nsbench.integrators import get_integrator, list_integrators

SPAN = bench_span(3000.0)
ROUNDS = 5


def _compiled() -> list[str]:
    problem = nsbench.get_problem("two-dof", case=1)
    names = []
    for name in sorted(list_integrators()):
        integ = get_integrator(name)
        try:
            integ.setup(problem)
        except Exception:  # refuses the problem: not timed here
            continue
        if integ.kernel(problem) is not None:
            names.append(name)
    return names


@pytest.mark.parametrize("name", _compiled())
def test_core_events_per_second(benchmark, request, nsbench_baseline, name):
    problem = nsbench.get_problem("two-dof", case=1)
    nsbench.simulate(problem, name, min(SPAN, 50.0))  # compile, load, build the mode tables
    runs = []

    def run():
        res = nsbench.simulate(problem, name, SPAN)
        runs.append(res)
        return res

    benchmark.pedantic(run, rounds=ROUNDS, iterations=1)
    call = benchmark.stats.stats.median if benchmark.stats else float("nan")
    assert all(r.ok for r in runs), runs[-1].message
    events = len(runs[-1].events)
    wall = statistics.median(r.wall_time for r in runs)
    inner = statistics.median(r.integrator_time for r in runs)
    overhead = statistics.median((r.wall_time - r.integrator_time) / max(len(r.events), 1) for r in runs)
    figures = {"wall_s": wall, "integrator_s": inner, "events": events,
               "events_per_s": events / wall if wall > 0 else None,
               "overhead_us_per_event": 1e6 * overhead,
               "engine_share": 1.0 - inner / wall if wall > 0 else None,
               "call_s": call, "events_per_s_call": events / call if call > 0 else None}
    benchmark.extra_info.update(integrator=name, problem="two-dof/1", t_end=SPAN, rounds=ROUNDS)
    nsbench_baseline.record(request, benchmark, figures, "wall_s", {"t_end": SPAN},
                            label=f"core {name} 2-DOF case 1 [0, {SPAN:g}]: {events / wall:,.0f} events/s, "
                                  f"{1e6 * overhead:.2f} us/event in the core")
