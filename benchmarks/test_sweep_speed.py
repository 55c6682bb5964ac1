"""Speed of the case-1 ``v0`` sweep: [0.04, 0.22], 1000 values, transient 1500, 100 recorded peaks.

Run with ``python -m pytest benchmarks/test_sweep_speed.py --benchmark-only`` (not
part of the default test run). Every capable integrator is timed on 2 worker
processes: the ones with a compiled arc kernel (the whole hybrid loop runs in
compiled code, see :func:`compiled`) on every value; the ones whose arcs are Python calls
on ``NSBENCH_SWEEP_SUBSET`` (default 10) values of the same range, with the time
of every value extrapolated from that and labelled so in ``extra_info``.

Speed is recorded, not asserted. Figures in ``extra_info``: ``sweep_s`` (wall
seconds for all the values, measured or extrapolated), ``values_per_s``, ``cpu_s``
(CPU seconds of the sweep's processes for all the values) and, for every
integrator but :data:`REFERENCE`, ``ratio_to_reference`` and
``cpu_ratio_to_reference`` (its ``sweep_s``, ``cpu_s`` over :data:`REFERENCE`'s in
the same session) and the agreement of its section points with :data:`REFERENCE`'s
(median Hausdorff distance over the common values); ``values_s`` (the workers' seconds
computing values: the sum of each value's ``wall_time`` over the workers) and
``wall_over_values`` (``sweep_s`` over it). Compared with the baseline, always a ratio
measured in one run: ``ratio_to_reference``, and ``wall_over_values`` for
:data:`REFERENCE` itself. The CPU figures
are recorded for diagnosis only: on the shared development VM CPU time rose with the
load too (the old ``exact-jit``: 81 CPU-s under a load average of about 5, against at
most 2 x 14 s when quiet).

``NSBENCH_BENCH_T_END`` scales the sweep down (a smoke run): factor
``s = min(1, NSBENCH_BENCH_T_END / 1500)``, transient ``1500 s``, recorded peaks
``max(5, round(100 s))``, values ``max(10, round(1000 s))``, engine subset
``max(2, round(10 s))`` unless ``NSBENCH_SWEEP_SUBSET`` is set. Unset: full size.
"""

from __future__ import annotations

import os
import resource
import time

import numpy as np
import pytest

from nsbench.bench.pytest_bench import bench_span
from nsbench.bifurcation.compare import hausdorff
from nsbench.bifurcation.parallel import run_sweep
from nsbench.bifurcation.sweep import OK_STATUSES, SweepSpec
from nsbench.integrators import integrator_class, list_integrators
from nsbench.problems import get_problem

FULL_COUNT, FULL_TRANSIENT, FULL_RECORD, WORKERS = 1000, 1500.0, 100, 2
SCALE = bench_span(FULL_TRANSIENT) / FULL_TRANSIENT
TRANSIENT = FULL_TRANSIENT * SCALE
RECORD = FULL_RECORD if SCALE == 1 else max(5, round(FULL_RECORD * SCALE))
COUNT = FULL_COUNT if SCALE == 1 else max(10, round(FULL_COUNT * SCALE))
# the engine integrators dominate a scaled-down run (seconds per value even over a short
# transient), so their subset shrinks too unless NSBENCH_SWEEP_SUBSET says otherwise
SUBSET = min(int(os.environ.get("NSBENCH_SWEEP_SUBSET", 10 if SCALE == 1 else max(2, round(10 * SCALE)))), COUNT)
#: the integrator every other one is compared with (timed first)
REFERENCE = "exact"
_reference: dict[str, object] = {}


def compiled(name: str) -> bool:
    """Whether a sweep runs ``name`` entirely in compiled code (all values timed).

    The criterion of the hybrid core itself: the set-up integrator hands it a
    compiled arc kernel (:meth:`nsbench.integrators.base.Integrator.kernel`), so the
    list follows the registry rather than a list of names.
    """
    integ = integrator_class(name)()
    problem = get_problem("two-dof", case=1)
    integ.setup(problem)
    return integ.kernel(problem) is not None


def _capable() -> list[str]:
    """:data:`REFERENCE` first (the others need its time), then every other capable integrator: event-driven
    (a sweep refuses a whole-system method) and taking the problem."""
    problem = get_problem("two-dof", case=1)
    names, seen = [], set()
    for name in [REFERENCE, *sorted(set(list_integrators()) - {REFERENCE})]:
        try:
            cls = integrator_class(name)
            if cls.capabilities.family != "event-driven":
                continue
            cls().setup(problem)
        except Exception:  # refuses the problem or fails to load: not capable
            continue
        if cls in seen:  # an alias of an integrator already listed would time the same run twice
            continue
        seen.add(cls)
        names.append(name)
    return names


def _spec(name: str, count: int) -> SweepSpec:
    return SweepSpec(
        problem="two-dof",
        case=1,
        name="v0",
        start=0.04,
        stop=0.22,
        count=count,
        integrator=name,
        transient=TRANSIENT,
        record=RECORD,
    )


def _cpu() -> float:
    """CPU seconds of this process, its reaped children and the live workers of the kept sweep pool."""
    from nsbench.workers.jobs import worker_cpu_seconds

    own, kids = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + kids.ru_utime + kids.ru_stime + worker_cpu_seconds()


def _timed_sweep(benchmark, tmp_path_factory, name: str, rounds: int):
    """Warm up (compile or load numba's cache, untimed), then time the sweep.

    Returns
    -------
    frame, wall, cpu
        The rows of the last round, its wall seconds (median of the rounds) and the
        CPU seconds per round of the sweep's processes (this one and its workers,
        which stay alive between sweeps: :func:`nsbench.workers.jobs.worker_cpu_seconds`).
    """
    count = COUNT if compiled(name) else SUBSET
    run_sweep(_spec(name, 1), tmp_path_factory.mktemp("warm"), workers=1, progress=False)
    dirs = iter(tmp_path_factory.mktemp(f"{name}-{i}") for i in range(rounds + 1))

    def sweep():
        return run_sweep(_spec(name, count), next(dirs), workers=WORKERS, progress=False)

    tic, cpu = time.perf_counter(), _cpu()
    if benchmark is None:  # the reference for a run that deselected its benchmark
        frame = sweep()
        return frame, time.perf_counter() - tic, _cpu() - cpu
    frame = benchmark.pedantic(sweep, rounds=rounds, iterations=1)
    cpu = (_cpu() - cpu) / rounds
    # no stats with --benchmark-disable (one untimed call): the wall clock of that call
    return frame, benchmark.stats.stats.median if benchmark.stats else time.perf_counter() - tic, cpu


def _reference_run(tmp_path_factory):
    """:data:`REFERENCE`'s frame and seconds in this session (timed here if its test did not run)."""
    if "frame" not in _reference:
        frame, wall, cpu = _timed_sweep(None, tmp_path_factory, REFERENCE, 1)
        scale = COUNT / (COUNT if compiled(REFERENCE) else SUBSET)
        _reference.update(frame=frame, sweep_s=wall * scale, cpu_s=cpu * scale)
    return _reference


def _agreement(ref, frame) -> float:
    """Median Hausdorff distance between the peak sets of the values both sweeps ran."""
    ref_values = ref.groupby("index")["value"].first()
    d = []
    for _, rows in frame.groupby("index"):
        v = rows["value"].iloc[0]
        j = int(np.argmin(np.abs(ref_values.to_numpy() - v)))
        if abs(ref_values.iloc[j] - v) < 1e-12:
            mine = ref[ref["index"] == ref_values.index[j]]
            d.append(hausdorff(mine[["x1", "x2"]].to_numpy(float), rows[["x1", "x2"]].to_numpy(float)))
    finite = [x for x in d if not np.isnan(x)]  # values without a distance (NaN) are left out
    return float(np.median(finite)) if finite else float("nan")


@pytest.mark.parametrize("name", _capable())
def test_case1_v0_sweep(benchmark, request, nsbench_baseline, tmp_path_factory, name):
    full = compiled(name)
    count = COUNT if full else SUBSET
    # the reference twice: its figure is the absolute one, so the median of 2 rounds
    frame, wall, cpu = _timed_sweep(benchmark, tmp_path_factory, name, 2 if name == REFERENCE else 1)
    estimate, cpu_s = wall * COUNT / count, cpu * COUNT / count
    pts = frame.groupby("index").first()
    info = dict(
        values=COUNT,
        values_timed=count,
        transient=TRANSIENT,
        record=RECORD,
        workers=WORKERS,
        measured=full,
        failed=int((~pts["status"].isin(OK_STATUSES)).sum()),
        at_rest=int((pts["status"] == "rest").sum()),
        nfev=int(pts["nfev"].sum()),
        reference_integrator=REFERENCE,
    )
    benchmark.extra_info.update(info)
    figures = {"sweep_s": estimate, "values_per_s": COUNT / estimate if estimate > 0 else None, "cpu_s": cpu_s}
    # the seconds the workers spent computing values (each value's own wall_time), per worker
    values_s = float(pts["wall_time"].sum()) / WORKERS * COUNT / count
    figures["values_s"] = values_s
    figures["wall_over_values"] = estimate / values_s if values_s > 0 else None
    # compared with the baseline: ratios measured in this run, which hold on a machine of another
    # speed: the wall ratio to the reference timed in the same session (both see about the same
    # load), and for the reference itself its wall time over its workers' computing time
    primary = "wall_over_values"
    if name == REFERENCE:
        _reference.update(frame=frame, sweep_s=estimate, cpu_s=cpu_s)
    else:
        ref = _reference_run(tmp_path_factory)
        figures["ratio_to_reference"] = estimate / ref["sweep_s"]
        figures["cpu_ratio_to_reference"] = cpu_s / ref["cpu_s"] if ref["cpu_s"] > 0 else None
        figures[f"median_hausdorff_vs_{REFERENCE.replace('-', '_')}"] = _agreement(ref["frame"], frame)
        primary = "ratio_to_reference"
    how = "measured" if full else f"extrapolated from {count}"
    nsbench_baseline.record(
        request,
        benchmark,
        figures,
        primary,
        {"values": COUNT, "timed": count, "transient": TRANSIENT, "record": RECORD, "workers": WORKERS},
        label=f"sweep {name} ({COUNT} values, {how})",
    )
