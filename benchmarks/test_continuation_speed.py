"""Continuation against brute force: one branch of case 1 along ``v0`` versus a sweep of the same range.

The continuation follows the orbit reached from rest at ``v0 = 0.16`` (block 2
sticks once per period) up to the end of its branch near 0.2744 with 200 steps,
locating that end (a grazing-sliding bifurcation) to about 1e-11. The brute-force
sweep computes 1000 values of the same range with ``exact`` on 2 worker processes
(transient 1500, 100 peaks), the way a diagram is drawn. Both are warm (numba
caches loaded, the flow set up) before timing. Speed is recorded, not asserted:
``continuation_s``, ``sweep_s`` and ``ratio_to_sweep`` (below 1: the continuation is
faster) go to ``extra_info`` and the baseline comparison.

Run: ``python -m pytest benchmarks/test_continuation_speed.py --benchmark-only``.
"""

from __future__ import annotations

import time

from nsbench import get_problem
from nsbench.bifurcation.parallel import run_sweep
from nsbench.bifurcation.sweep import SweepSpec
from nsbench.periodic import HybridFlow, continue_orbit, find_orbit

START, STOP, STEPS, VALUES = 0.16, 0.28, 200, 1000


def _case1(v0):
    return get_problem("two-dof", case=1, v0=v0)


def test_case1_v0_continuation_vs_sweep(benchmark, request, nsbench_baseline, tmp_path_factory):
    flow = HybridFlow(_case1(START))
    orbit = find_orbit(flow)
    continue_orbit(flow, _case1, "v0", orbit, START, START + 0.01, steps=5)  # warm

    def continuation():
        flow.rebind(_case1(START))
        return continue_orbit(flow, _case1, "v0", orbit, START, STOP, steps=STEPS)

    branch = benchmark.pedantic(continuation, rounds=3, iterations=1)
    cont_s = benchmark.stats.stats.median if benchmark.stats else float("nan")
    assert branch.bifurcations and branch.bifurcations[-1].kind == "grazing-sliding"

    spec = SweepSpec(
        problem="two-dof",
        case=1,
        name="v0",
        start=START,
        stop=STOP,
        count=VALUES,
        integrator="exact",
        transient=1500.0,
        record=100,
    )
    run_sweep(SweepSpec(**{**spec.to_dict(), "count": 2}), tmp_path_factory.mktemp("warm"), workers=2, progress=False)
    tic = time.perf_counter()
    run_sweep(spec, tmp_path_factory.mktemp("sweep"), workers=2, progress=False)
    sweep_s = time.perf_counter() - tic
    figures = {
        "continuation_s": cont_s,
        "sweep_s": sweep_s,
        "ratio_to_sweep": cont_s / sweep_s,
        "steps": len(branch.values),
        "located_end": branch.bifurcations[-1].value,
    }
    nsbench_baseline.record(
        request,
        benchmark,
        figures,
        "ratio_to_sweep",
        {"start": START, "stop": STOP, "steps": STEPS, "values": VALUES},
        label="continuation vs 1000-value sweep (case 1, v0)",
    )
