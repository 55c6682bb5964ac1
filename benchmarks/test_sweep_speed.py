"""Speed of the case-1 ``v0`` sweep: [0.04, 0.22], 1000 values, transient 1500, 100 recorded peaks.

Run with ``python -m pytest benchmarks/test_sweep_speed.py`` (not part of the
default test run). Every capable integrator is timed on 2 worker processes:
the compiled ones (``exact-jit``, ``henon-rk4-jit``) on all 1000 values; the
ones that run through the Python engine on ``NSBENCH_SWEEP_SUBSET`` (default
10) values of the same range, with the 1000-value time extrapolated from that
and labelled so in ``extra_info``. The goal: the fastest finishes in 60 s.
Each result also records its agreement with ``exact-jit`` (median Hausdorff
distance between the peak sets over the common values).
"""

from __future__ import annotations

import os
import time

import numpy as np
import pytest

from nsbench.bifurcation.compare import hausdorff
from nsbench.bifurcation.parallel import run_sweep
from nsbench.bifurcation.sweep import OK_STATUSES, SweepSpec
from nsbench.integrators import integrator_class, list_integrators
from nsbench.problems import get_problem

COUNT, TRANSIENT, RECORD, WORKERS, GOAL_S = 1000, 1500.0, 100, 2, 60.0
SUBSET = int(os.environ.get("NSBENCH_SWEEP_SUBSET", "10"))
COMPILED = ("exact-jit", "henon-rk4-jit")
_reference: dict[str, object] = {}


def _capable() -> list[str]:
    problem = get_problem("two-dof", case=1)
    names = []
    for name in list_integrators():
        try:
            integrator_class(name)().setup(problem)
        except Exception:  # refuses the problem or fails to load: not capable
            continue
        names.append(name)
    return names


def _spec(name: str, count: int) -> SweepSpec:
    return SweepSpec(problem="two-dof", case=1, name="v0", start=0.04, stop=0.22, count=count,
                     integrator=name, transient=TRANSIENT, record=RECORD)


@pytest.mark.parametrize("name", _capable())
def test_case1_v0_sweep(benchmark, tmp_path_factory, name):
    full = name in COMPILED
    count = COUNT if full else SUBSET
    # compile (or load from numba's cache) outside the timing
    run_sweep(_spec(name, 1), tmp_path_factory.mktemp("warm"), workers=1, progress=False)
    dirs = iter(tmp_path_factory.mktemp(f"{name}-{i}") for i in range(1000))

    def sweep():
        return run_sweep(_spec(name, count), next(dirs), workers=WORKERS, progress=False)

    tic = time.perf_counter()
    frame = benchmark.pedantic(sweep, rounds=2 if name == "exact-jit" else 1, iterations=1)
    wall = benchmark.stats.stats.median if benchmark.stats else time.perf_counter() - tic
    estimate = wall * COUNT / count
    pts = frame.groupby("index").first()
    info = dict(values_timed=count, sweep_1000_s=estimate, measured=full,
                failed=int((~pts["status"].isin(OK_STATUSES)).sum()),
                at_rest=int((pts["status"] == "rest").sum()), nfev=int(pts["nfev"].sum()))
    if name == "exact-jit":
        _reference["frame"] = frame
    ref = _reference.get("frame")
    if ref is not None and name != "exact-jit":
        ref_values = ref.groupby("index")["value"].first().to_numpy()
        d = []
        for index, rows in frame.groupby("index"):
            v = rows["value"].iloc[0]
            j = int(np.argmin(np.abs(ref_values - v)))
            if abs(ref_values[j] - v) < 1e-12:
                d.append(hausdorff(ref[ref["index"] == j][["x1", "x2"]].to_numpy(float),
                                   rows[["x1", "x2"]].to_numpy(float)))
        info["median_hausdorff_vs_exact_jit"] = float(np.nanmedian(d)) if d else float("nan")
    benchmark.extra_info.update(info)
    print(f"\n{name}: {estimate:.1f} s for {COUNT} values ({'measured' if full else f'extrapolated from {count}'})")
    if name == "exact-jit":
        assert estimate <= GOAL_S, f"{name} took {estimate:.1f} s > {GOAL_S} s"
