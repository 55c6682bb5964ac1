"""How a timed sample runs (nsbench.bench.execute._sample): its frames built once, a failing run kept."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from nsbench.bench.execute import _sample
from nsbench.integrators import get_integrator
from nsbench.integrators.scipy_ import ScipyRK45
from nsbench.problems import get_problem


class FailsPastArcs(ScipyRK45):
    """scipy RK45 whose ``advance`` raises once it has been called ``budget`` times (a bug that shows late)."""

    name = "fails-past-arcs-test"
    budget = 10**9

    def advance(self, request):
        self.calls = getattr(self, "calls", 0) + 1
        if self.calls > self.budget:
            raise RuntimeError(f"plug-in bug at call {self.calls}")
        return super().advance(request)


def _case(t_end: float) -> SimpleNamespace:
    # the fields _sample reads of a suite's Case
    return SimpleNamespace(t0=0.0, t_end=t_end, max_steps=2_000_000)


def test_a_looped_sample_builds_the_frames_of_one_run_and_times_every_run(monkeypatch):
    """Of ``loops`` runs only the first builds its event log and trajectory (the sample's result): the frames are
    nsbench's glue, outside the clocks; every run's clocks count. The result is simulate's own."""
    from nsbench import engine

    problem, integ = get_problem("one-dof"), get_integrator("exact")
    grid = np.linspace(0.0, 30.0, 31)
    alone = engine.simulate(problem, integ, 30.0, t_eval=grid)
    built = []
    frames = engine._frames
    monkeypatch.setattr(engine, "_frames", lambda *a, **k: built.append(1) or frames(*a, **k))
    sample = _sample(problem, integ, _case(30.0), grid, loops=5)
    assert len(built) == 1
    assert sample.run.ok and not sample.hit
    assert sample.run.events["t"].tolist() == alone.events["t"].tolist()  # runs are deterministic
    assert sample.wall > 0 and sample.cpu > 0 and np.isfinite(sample.inner)


def test_a_run_that_fails_inside_a_sample_ends_it_with_its_own_result():
    problem = get_problem("one-dof")
    integ = FailsPastArcs(rtol=1e-8, atol=1e-10)
    integ.setup(problem)
    grid = np.linspace(0.0, 10.0, 11)
    first = _sample(problem, integ, _case(10.0), grid, loops=1)
    per_run = integ.calls
    assert first.run.ok and per_run >= 2
    integ.budget = integ.calls + per_run + 1  # the next sample's first run passes, its second fails at its second arc
    sample = _sample(problem, integ, _case(10.0), grid, loops=3)
    assert not sample.run.ok and "plug-in bug" in sample.run.message
    assert sample.run.t_final < 10.0 and len(sample.run.trajectory) <= len(grid)
    assert sample.wall == pytest.approx(float(sample.run.wall_time))  # the failed run's clocks, not a mean


def test_a_probed_warm_up_times_a_warm_stretch_of_the_span_and_an_unprobed_one_none():
    from nsbench.bench import Suite
    from nsbench.bench.estimate import Probe
    from nsbench.bench.execute import warm_up

    case = Suite.from_dict(
        {
            "name": "p",
            "t_span": [0.0, 20.0],
            "problems": [{"name": "one-dof", "case": 1}],
            "integrators": {"only": ["exact"]},
        }
    ).cases()[0]
    plain = warm_up(case)
    assert plain.row is None and np.isnan(plain.probe_span) and Probe.of(plain) is None
    stages = []
    probed = warm_up(case, stage=lambda what, limit: stages.append(what), probe=True)
    assert probed.row is None and stages == ["setup", "warm-up run", "probe run"]
    assert 0 < probed.probe_span <= 1 and 0 < probed.probe_wall <= probed.probe_call
    probe = Probe.of(probed)
    assert probe.wall == probed.probe_wall / probed.probe_span and probe.call >= probe.wall
