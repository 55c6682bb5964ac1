"""Speed of the N-block chain: ``exact`` on 64 blocks, checked against quad precision.

``exact`` on ``chain`` with ``n = 64``, case 1, ``tau`` in [0, 100] (scaled by
``NSBENCH_BENCH_T_END``) through ``nsbench.simulate``, one core, warm rounds (the
first run builds the tables of the modes it visits). The event log is checked
against ``heyoka-q`` (Taylor, quad precision at quad epsilon): the same event
sequence is asserted (tie groups of simultaneous stick events compared in the
reference's order, :func:`nsbench.bench.metrics.order_ties_as_reference`); the
largest event-time difference is recorded (``max_dt_vs_quad``), not asserted:
``exact``'s modal form loses accuracy as the chain grows (1.3e-9 at ``n = 64``
on the development machine, docs/core.md).

Figures in ``extra_info``: ``wall_s``, ``events``, ``events_per_s``,
``max_dt_vs_quad``; ``setup_s`` of the first run. Speed is recorded and compared
with ``benchmarks/baseline.json``, never asserted.
"""

from __future__ import annotations

import statistics

import numpy as np

import nsbench
from nsbench.bench.metrics import align, order_ties_as_reference
from nsbench.bench.pytest_bench import bench_span

SPAN = bench_span(100.0)
ROUNDS = 5
BLOCKS = 64


def test_exact_on_a_64_block_chain(benchmark, request, nsbench_baseline):
    problem = nsbench.get_problem("chain", n=BLOCKS, case=1)
    first = nsbench.simulate(problem, "exact", SPAN)  # builds the tables of the visited modes
    runs = []

    def run():
        res = nsbench.simulate(problem, "exact", SPAN)
        runs.append(res)
        return res

    benchmark.pedantic(run, rounds=ROUNDS, iterations=1)
    quad = nsbench.simulate(problem, "heyoka-q", SPAN)
    assert all(r.ok for r in runs) and quad.ok, runs[-1].message or quad.message
    events = runs[-1].events
    theirs = order_ties_as_reference(quad.events, events)
    al = align(quad.events, theirs)
    assert al.sequence_ok, f"exact and heyoka-q differ at event {al.first_divergence_index} of {al.n_ref}"
    max_dt = float(np.max(np.abs(theirs["t"].to_numpy() - quad.events["t"].to_numpy()))) if len(events) else 0.0
    wall = statistics.median(r.wall_time for r in runs)
    figures = {
        "wall_s": wall,
        "events": len(events),
        "events_per_s": len(events) / wall if wall > 0 else None,
        "max_dt_vs_quad": max_dt,
        "setup_s": first.setup_time,
        "call_s": benchmark.stats.stats.median if benchmark.stats else None,
    }
    benchmark.extra_info.update(problem=f"chain/1 n={BLOCKS}", t_end=SPAN, rounds=ROUNDS)
    nsbench_baseline.record(
        request,
        benchmark,
        figures,
        "wall_s",
        {"t_end": SPAN, "n": BLOCKS},
        label=f"exact chain n={BLOCKS} [0, {SPAN:g}]: {wall:.3g} s, {len(events)} events, "
        f"max |dt| against heyoka-q {max_dt:.2g}",
    )
