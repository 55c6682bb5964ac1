"""heyoka's batch mode (:mod:`nsbench.integrators._heyoka_batch`) through :func:`nsbench.engine.run_batch`.

A batch runs several problems at once, one per SIMD lane, each with its own records and checks, and
must give per problem what :func:`nsbench.engine.run` of that problem gives on heyoka's scalar
native path: lanes integrate with the same Taylor arithmetic as the scalar integrator (per-lane
step sizes from the lane's own coefficients), so the event sequences, statuses, step counts and
recorded values are the scalar run's to rounding (1e-12 here; they came out equal bit for bit).
Independently, event times are within 1e-12 of ``exact`` (closed-form flow) on the linear cases, the
bound the scalar native runs are held to (tests/integrators/test_native_runs.py).
"""

from __future__ import annotations

import numpy as np
import pytest

import nsbench
from nsbench import engine
from nsbench.bifurcation.sweep import SweepSpec, point_columns, points_columns
from nsbench.integrators import _heyoka_batch
from nsbench.sections import peaks
from nsbench.status import Status

#: 20 values of v0 over case 1's sweep range: stick-slip with one and two sticking blocks, and pure slip
V0 = np.linspace(0.04, 0.22, 20)
SCALAR = 1e-12  # batch against the scalar native run: the same arithmetic
EXACT = 1e-12  # event times against exact on the linear cases (the native runs' bound)


def _problems(case=1, values=V0):
    return [nsbench.get_problem("two-dof", case=case, v0=float(v)) for v in values]


def _scalar(problem, integ, t_end, **kwargs):
    integ.setup(problem)
    return engine.run(problem, integ, t_end, **kwargs)


def _close(a, b, tol):
    assert a.shape == b.shape
    assert np.max(np.abs(a - b), initial=0.0) <= tol


def _same_run(batch, one, tol=SCALAR, samples=0):
    """``samples``: requested times, each of which ends a step of the batch run (a terminal event; the
    scalar run evaluates them on its steps' polynomials), so that run takes up to as many more steps."""
    assert batch.status == one.status, (batch.status, one.status, batch.message, one.message)
    assert len(batch.events) == len(one.events) and batch.n_events_total == one.n_events_total
    assert (batch.events.kind == one.events.kind).all() and (batch.events.block == one.events.block).all()
    _close(batch.events.t, one.events.t, tol)
    _close(batch.events.y, one.events.y, tol)
    _close(batch.hits.t, one.hits.t, tol)
    _close(batch.hits.y, one.hits.y, tol)
    _close(batch.dense.y, one.dense.y, tol)
    assert 0 <= batch.counters.nsteps - one.counters.nsteps <= samples
    assert abs(batch.t - one.t) <= tol and batch.mode == one.mode


def test_the_batch_size_is_heyokas_simd_width():
    assert engine.batch_size(nsbench.get_integrator("heyoka")) == _heyoka_batch.lanes() >= 2
    assert engine.batch_size(nsbench.get_integrator("exact")) == 1


def test_a_peaks_sweep_in_batches_is_the_scalar_native_run_and_exact_per_value():
    problems = _problems()
    integ = nsbench.get_integrator("heyoka")
    kwargs = dict(hit_from=200.0, hit_stop=20, record_from=200.0, max_steps=50_000_000, max_events=5_000_000)
    t_end = 200.0 + 40 * 20 + 400.0
    recs = engine.run_batch(problems, integ, t_end, sections=engine.Each([[peaks(p)] for p in problems]), **kwargs)
    assert [r.batch for r in recs] == [_heyoka_batch.lanes()] * len(problems)
    assert {r.loop for r in recs} == {"native"}
    exact = nsbench.get_integrator("exact")
    for p, rec in zip(problems, recs):
        assert rec.ok and rec.stopped and len(rec.hits) == 20  # every lane stopped at its own 20th peak
        _same_run(rec, _scalar(p, integ, t_end, sections=[peaks(p)], **kwargs))
        ref = _scalar(p, exact, t_end, sections=[peaks(p)], **kwargs)
        assert (rec.events.kind == ref.events.kind).all() and (rec.events.block == ref.events.block).all()
        _close(rec.events.t, ref.events.t, EXACT)


def test_requested_states_and_a_forced_case_in_batches_are_the_scalar_runs():
    # case 2 is forced (two more integrated states, cos and sin of the phase); the requested times (a
    # strobe's) are sampled by a terminal event of their own in each lane, one grid per problem
    problems = _problems(case=2, values=V0[::3])
    grids = [np.linspace(50.0, 149.0, 37) + 0.01 * k for k in range(len(problems))]
    integ = nsbench.get_integrator("heyoka")
    recs = engine.run_batch(problems, integ, 150.0, t_eval=engine.Each(grids))
    exact = nsbench.get_integrator("exact")
    for p, grid, rec in zip(problems, grids, recs):
        assert rec.batch and rec.ok and len(rec.dense) == grid.size
        _same_run(rec, _scalar(p, integ, 150.0, t_eval=grid), tol=1e-11, samples=grid.size)
        ref = _scalar(p, exact, 150.0, t_eval=grid)
        assert (rec.events.kind == ref.events.kind).all()
        _close(rec.events.t, ref.events.t, EXACT)
        _close(rec.dense.y, ref.dense.y, 1e-11)


def test_a_lane_that_runs_out_of_events_fails_alone_as_its_scalar_run():
    problems = _problems()
    integ = nsbench.get_integrator("heyoka")
    recs = engine.run_batch(problems, integ, 300.0, max_events=45)
    statuses = [r.status for r in recs]
    assert Status.BUDGET_EXHAUSTED in statuses and Status.SUCCESS in statuses  # some lanes fail, others do not
    for p, rec in zip(problems, recs):
        _same_run(rec, _scalar(p, integ, 300.0, max_events=45))


def test_a_batch_that_cannot_run_together_falls_back_to_one_run_each():
    integ = nsbench.get_integrator("heyoka")
    mixed = [nsbench.get_problem("two-dof", case=1), nsbench.get_problem("two-dof", case=3)]  # case 3: cubic
    double_zero = [nsbench.get_problem("two-dof", case=1, v0=0.1), nsbench.get_problem("two-dof", case=1, r_f=1.0)]
    for problems in (mixed, double_zero):
        recs = engine.run_batch(problems, integ, 100.0)
        assert [r.batch for r in recs] == [0, 0]
        for p, rec in zip(problems, recs):
            one = _scalar(p, integ, 100.0)
            assert rec.loop == one.loop
            _same_run(rec, one)
    assert engine.run_batch(double_zero, integ, 100.0)[1].loop == "per-arc"  # fs = fr: heyoka's per-arc path
    for name in ("heyoka-ld", "exact"):  # no batch mode in long double; none in exact
        recs = engine.run_batch(_problems(values=V0[:3]), nsbench.get_integrator(name), 50.0)
        assert [r.batch for r in recs] == [0, 0, 0] and all(r.ok for r in recs)


def test_run_batch_checks_each_runs_arguments_as_run_does():
    problems = _problems(values=V0[:2])
    integ = nsbench.get_integrator("heyoka")
    with pytest.raises(nsbench.ConfigError, match="max_events"):
        engine.run_batch(problems, integ, 50.0, max_events=0)
    with pytest.raises(nsbench.ConfigError, match="t_end = 50 must be greater than t0 = 60"):
        engine.run_batch(problems, integ, 50.0, t0=engine.Each([0.0, 60.0]))
    with pytest.raises(nsbench.ConfigError, match="Each"):
        engine.run_batch(problems, integ, engine.Each([50.0]))
    with pytest.raises(nsbench.ConfigError, match="unknown argument 'sectoins'"):
        engine.run_batch(problems, integ, 50.0, sectoins=())


def test_a_sweeps_values_in_a_batch_are_its_values_run_one_by_one():
    spec = SweepSpec("two-dof", 1, "v0", 0.04, 0.22, 10, integrator="heyoka", transient=100.0, record=10)
    integ = nsbench.get_integrator("heyoka")
    together = points_columns(spec, list(range(10)), integ)
    for i, got in enumerate(together):
        alone = point_columns(spec, i, integ)
        assert got.keys() == alone.keys()
        for column in got:
            if column == "wall_time":
                continue
            a, b = got[column], alone[column]
            if isinstance(a, list):
                assert a == b, column
            else:
                np.testing.assert_allclose(a, b, rtol=0, atol=SCALAR, err_msg=column)
