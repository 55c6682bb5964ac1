"""nsbench's share of the integrators without a compiled arc kernel, and heyoka's sweep cost against exact's.

``test_python_arc_share``: ``nsbench.simulate`` on the 2-DOF case 1 over ``tau`` in
[0, 3000] (scaled by ``NSBENCH_BENCH_T_END``) with each integrator whose arcs run in
Python (``heyoka``, the SUNDIALS and the scipy methods): the compiled loop returns to
Python once per arc and ``_PythonArcs.arc`` runs the integrator's ``advance``. Figures
in ``extra_info``:

``outside_advance_us_per_event``
    ``(wall_time - integrator_time) / events``: nsbench's share (the arc's protocol, the
    loop's re-entry and its work per event); the goal (issue 29): at most 5 us;
``wall_us_per_event``
    the run's wall time per event;
``replayed_us_per_event``
    the same share with the integrator's own work taken out: its results of one run
    are recorded and handed back, arc by arc, to the same run made again (the events
    are checked to be the same). What is left is nsbench's own cost per event on warm
    caches; the difference to ``outside_advance_us_per_event`` is what the integrator's
    work between two arcs costs the glue in cache refills (docs/core.md).
``least_glue_us_per_event``
    the share in the run (the integrator really runs) with nsbench's per-arc glue replaced
    by the least any glue that calls Python once per arc must do (:func:`_least_glue`: the
    request, the timed ``advance``, the state, time, fired guard, steps and dense states
    stored; no protocol check, no section hits, no extra counters); the run is checked to
    give the same events. It bounds from below what any rework of the per-arc protocol in
    Python can reach on this machine (issue 29's goal: 5 us).

``test_heyoka_sweep_value_against_exact``: whole values of the sweep
``two-dof --case 1 --sweep v0=0.04:0.22:1000 --transient 1500 --record 100``
(``compute_point``, every 50th value), ``heyoka`` and ``exact`` interleaved in one
process; ``heyoka_over_exact`` is the median of the per-round ratios (the goal: the
sweep with ``heyoka`` within 4x of ``exact``'s).

Warm runs only (an untimed first run compiles and loads). Speed is recorded and
compared with ``benchmarks/baseline.json``, never asserted.
"""

from __future__ import annotations

import statistics
import time
from unittest import mock

import numpy as np
import pytest

import nsbench
from nsbench.bench.pytest_bench import bench_span
from nsbench.hybrid.run import _PythonArcs, low_part
from nsbench.integrators import get_integrator
from nsbench.model import abi
from nsbench.model.callback import ARC_STORED

SPAN = bench_span(3000.0)
ROUNDS = 5
PYTHON_ARCS = (
    "heyoka",
    "cvode-adams",
    "cvode-bdf",
    "ida",
    "scipy-dop853",
    "scipy-rk45",
    "scipy-radau",
    "scipy-bdf",
    "scipy-lsoda",
)


@pytest.mark.parametrize("name", PYTHON_ARCS)
def test_python_arc_share(benchmark, request, nsbench_baseline, name):
    problem = nsbench.get_problem("two-dof", case=1)
    integ = _per_arc(name)
    nsbench.simulate(problem, integ, min(SPAN, 50.0))  # set up, compile, load
    runs = []

    def run():
        res = nsbench.simulate(problem, integ, SPAN)
        runs.append(res)
        return res

    benchmark.pedantic(run, rounds=ROUNDS, iterations=1)
    assert all(r.ok for r in runs), runs[-1].message
    events = max(len(runs[-1].events), 1)
    outside = statistics.median((r.wall_time - r.integrator_time) / events for r in runs)
    wall = statistics.median(r.wall_time for r in runs)
    replayed = _replayed(problem, name, runs[-1])
    least = _least_glue_share(problem, integ, runs[-1])
    figures = {
        "wall_s": wall,
        "events": events,
        "outside_advance_us_per_event": 1e6 * outside,
        "wall_us_per_event": 1e6 * wall / events,
        "replayed_us_per_event": 1e6 * replayed / events,
        "least_glue_us_per_event": 1e6 * least / events,
    }
    benchmark.extra_info.update(integrator=name, problem="two-dof/1", t_end=SPAN, rounds=ROUNDS)
    nsbench_baseline.record(
        request,
        benchmark,
        figures,
        "outside_advance_us_per_event",
        {"t_end": SPAN},
        label=f"{name} 2-DOF case 1 [0, {SPAN:g}]: {1e6 * outside:.1f} us/event outside advance",
    )


def _per_arc(name: str):
    """The integrator on its per-arc path (this file measures that path's glue), also where it has a
    whole-run path of its own (``loop``: benchmarks/test_native_speed.py times that)."""
    integ = get_integrator(name)
    return get_integrator(name, loop="per-arc") if "loop" in integ.options else integ


def _replayed(problem, name: str, run) -> float:
    """nsbench's share of ``run`` per run with the integrator's results replayed (median of ROUNDS runs)."""
    integ = _per_arc(name)
    advance, results = integ.advance, []

    def record(arc_request):
        results.append(advance(arc_request))
        return results[-1]

    integ.advance = record
    nsbench.simulate(problem, integ, SPAN)
    position = iter(())

    def replay(arc_request):
        return next(position)

    integ.advance = replay
    shares = []
    for _ in range(ROUNDS):
        position = iter(results)
        res = nsbench.simulate(problem, integ, SPAN)
        assert res.events.t.equals(run.events.t), "the replayed run must be the run"
        shares.append(res.wall_time - res.integrator_time)
    return statistics.median(shares)


def _least_glue(self: _PythonArcs) -> int:
    """A stand-in for ``_PythonArcs.__call__`` that does only what any glue running ``advance`` once per
    arc must: the mode's tuple and guards, the request, ``advance`` timed, and its outcome stored where
    the compiled loop reads it (time, low part, state, fired guard, steps, dense states). It trusts the
    result: no protocol check, no counters but the steps, no section hits (the runs timed here have
    no sections). Its first lines are those of ``_PythonArcs.__call__`` on purpose: the same request,
    built the same way, so that the two figures differ only by what the real glue checks."""
    st = self.st
    key = st.mode.tobytes()
    entry = self._by_mode.get(key)
    mode, guards = self._mode(key) if entry is None else entry
    sf, si = st.sf, st.si
    times = sf.tolist()
    t, t_lo = times[abi.SF_T], times[abi.SF_TLO]
    i_eval = int(si[abi.SI_IEVAL])
    t_eval = self.t_eval[i_eval:] if i_eval else self.t_eval
    y_in = np.frombuffer(st.y.tobytes())  # a read-only copy
    request = self._build(mode, t, y_in, guards, t_eval, self.max_steps - self.nsteps, t_lo)
    tic = time.perf_counter()
    res = self._advance(request)
    self.seconds += time.perf_counter() - tic
    self.nsteps += res.nsteps
    st.cnt[abi.NSTEPS] = self.nsteps
    k = res.y_eval.shape[1]
    if k:
        self.rec.dense.y[i_eval : i_eval + k] = res.y_eval.T
        si[abi.SI_IEVAL] = i_eval + k
    sf[abi.SF_ARC_T] = res.t
    sf[abi.SF_ARC_TLO] = low_part(res.t, res.t_lo) if res.t_lo else 0.0
    st.y_arc[:] = res.y
    si[abi.SI_ARC_STATUS] = abi.K_OK
    si[abi.SI_DETAIL] = -1 if res.fired is None else res.fired
    return ARC_STORED


def _least_glue_share(problem, integ, run) -> float:
    """nsbench's share of ``run`` per run with the glue replaced by :func:`_least_glue` (median of ROUNDS)."""
    shares = []
    with mock.patch.object(_PythonArcs, "__call__", _least_glue):
        for _ in range(ROUNDS):
            res = nsbench.simulate(problem, integ, SPAN)
            assert res.events.t.equals(run.events.t), "the least glue must make the same run"
            shares.append(res.wall_time - res.integrator_time)
    return statistics.median(shares)


def test_heyoka_sweep_value_against_exact(benchmark, request, nsbench_baseline):
    from nsbench.bifurcation.sweep import SweepSpec, compute_point

    names = ("exact", "heyoka")
    integs = {n: get_integrator(n) for n in names}
    specs = {
        n: SweepSpec(problem="two-dof", case=1, name="v0", start=0.04, stop=0.22, count=1000, integrator=n)
        for n in names
    }
    for n in names:
        compute_point(specs[n], 0, integs[n])  # set up, compile, load
    per_value: dict[str, list[float]] = {n: [] for n in names}

    def one_round():
        for n in names if len(per_value["exact"]) % 2 == 0 else names[::-1]:
            tic = time.perf_counter()
            for i in range(0, 1000, 50):
                compute_point(specs[n], i, integs[n])
            per_value[n].append((time.perf_counter() - tic) / 20)

    benchmark.pedantic(one_round, rounds=4, iterations=1)
    ratios = [h / e for h, e in zip(per_value["heyoka"], per_value["exact"])]
    figures = {
        "exact_ms_per_value": 1e3 * statistics.median(per_value["exact"]),
        "heyoka_ms_per_value": 1e3 * statistics.median(per_value["heyoka"]),
        "heyoka_over_exact": statistics.median(ratios),
    }
    benchmark.extra_info.update(problem="two-dof/1", values="0:1000:50", rounds=4)
    nsbench_baseline.record(
        request,
        benchmark,
        figures,
        "heyoka_over_exact",
        {},
        label=f"sweep value, heyoka over exact: {statistics.median(ratios):.2f}",
    )
