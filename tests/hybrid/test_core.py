"""The hybrid core: it reproduces the pre-core engine, runs any number of blocks, and times the integrator."""

from __future__ import annotations

import functools
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import nsbench
from nsbench.problems.oscillator import FrictionOscillator
from nsbench.problems.parameters import Coefficients, Scales
from tests.conftest import max_time_error, same_sequence

OLD = Path(__file__).parents[1] / "data" / "engine_v1_events.csv.gz"
SLOW = {"scipy-radau", "scipy-bdf", "ida"}  # seconds per run: kept for `-m slow`


@functools.lru_cache(maxsize=None)
def old_logs() -> pd.DataFrame:
    """Event logs of the engine before the core (nsbench 0.1, commit a8de1f4), every integrator at its
    defaults over tau in [0, 300]; times stored as repr of the doubles."""
    return pd.read_csv(OLD)


def _old(name: str, problem: str, case: int) -> pd.DataFrame:
    f = old_logs()
    return f[(f["integrator"] == name) & (f["problem"] == problem) & (f["case"] == case)].reset_index(drop=True)


def _params():
    keys = old_logs()[["integrator", "problem", "case"]].drop_duplicates().itertuples(index=False)
    return [
        pytest.param(
            k.integrator,
            k.problem,
            int(k.case),
            id=f"{k.integrator}-{k.problem}-{k.case}",
            marks=[pytest.mark.slow] if k.integrator in SLOW else [],
        )
        for k in keys
    ]


@pytest.mark.parametrize("name, problem, case", _params())
def test_the_core_reproduces_the_old_engine(name, problem, case):
    # Same event sequence; times within the integrator's own error. That error is measured on the
    # old log against the problem's reference (exact for linear problems, quad Taylor otherwise):
    # an adaptive step-size control may take other steps on another machine (other rounding), which
    # moves event times by about its own error, never more. Measured on the development machine:
    # every integrator bit-identical except exact/reference on two-dof case 2 (2.8e-14: the closed
    # form is a new implementation).
    old = _old(name, problem, case)
    ref_name = "exact" if problem == "one-dof" or case in (1, 2) else "reference"
    ref = _old(ref_name, problem, case)
    res = nsbench.simulate(nsbench.get_problem(problem, case=case), name, 300.0)
    assert res.ok and old["status"].iloc[0] == "success"
    assert same_sequence(res.events, old)
    own_error = max_time_error(old, ref) if same_sequence(old, ref) else 0.0
    assert max_time_error(res.events, old) <= max(1e-12, 2.0 * own_error), name


def three_blocks() -> FrictionOscillator:
    """A chain of three blocks (block 1 to the ground, each to the previous), forced on the last."""
    c = Coefficients(
        m=(1.0, 0.8, 1.2),
        c=(0.05, 0.04, 0.06),
        k=(1.0, 1.3, 0.7),
        h=(0.0, 0.0, 0.0),
        fs=(5 / 6, 0.7, 0.9),
        fr=(1.0, 0.9, 1.1),
        F=0.3,
        w=0.9,
        v0=1 / 12,
    )
    return FrictionOscillator(
        c, name="three-blocks", case=None, dimensional=False, params={}, parameters={}, scales=Scales()
    )


@pytest.mark.parametrize("name", ["exact", "henon-rk4", "ofapi"])
def test_three_blocks_through_the_compiled_core_and_the_python_engine(name):
    # The same integrator twice: its compiled kernel for the whole run, and (a subclass that overrides
    # advance) one arc at a time through Python. Same rules, same arcs: the same event log.
    from nsbench.integrators import integrator_class

    base = integrator_class(name)

    class OneArcAtATime(base):
        def advance(self, request):
            return super().advance(request)

    p = three_blocks()
    grid = np.linspace(0.0, 150.0, 301)
    compiled = nsbench.simulate(p, base(), 150.0, t_eval=grid)
    python = nsbench.simulate(p, OneArcAtATime(), 150.0, t_eval=grid)
    assert compiled.ok and python.ok
    assert len(compiled.events) > 50 and set(compiled.events["block"]) == {1, 2, 3}
    assert list(compiled.events.columns) == ["t", "kind", "block", "x1", "v1", "x2", "v2", "x3", "v3", "mode"]
    pd.testing.assert_frame_equal(compiled.events, python.events)
    pd.testing.assert_frame_equal(compiled.trajectory, python.trajectory)
    assert compiled.counters.as_dict() == python.counters.as_dict()


def test_three_blocks_exact_against_a_tight_runge_kutta():
    # an independent integrator on the three-block chain: same sequence, times within its tolerance
    p = three_blocks()
    ex = nsbench.simulate(p, "exact", 150.0)
    dop = nsbench.simulate(p, "scipy-dop853", 150.0, options={"rtol": 1e-12, "atol": 1e-14})
    assert same_sequence(ex.events, dop.events)
    assert max_time_error(ex.events, dop.events) < 1e-8


@pytest.mark.parametrize("name", ["exact", "scipy-dop853"])
def test_integrator_time_is_part_of_wall_time(name):
    res = nsbench.simulate(nsbench.get_problem("two-dof", case=2), name, 100.0)
    assert 0.0 < res.integrator_time <= res.wall_time


def test_many_section_hits_and_events_grow_their_buffers():
    from nsbench.hybrid.records import Records
    from nsbench.sections import level_crossing

    first = Records(4, 2, np.empty(0))
    p = nsbench.get_problem("two-dof", case=1)
    res = nsbench.simulate(p, "exact", 3000.0, sections=[level_crossing(p, "v1", 0.0)])
    assert len(res.events) > first.ev_t.shape[0] and len(res.sections) > first.ht.shape[0]
    short = nsbench.simulate(p, "exact", 1500.0, sections=[level_crossing(p, "v1", 0.0)])
    n = len(short.events)
    pd.testing.assert_frame_equal(res.events.iloc[:n], short.events)


def test_a_run_that_stops_at_its_hth_hit_holds_them_without_leaving_the_loop(monkeypatch):
    # A sweep value stops at its 100th peak: the hits buffer is sized for them, so the compiled loop
    # is entered once (each return to grow a buffer is a Python round trip and numba's dispatch),
    # and the hits are those of a run whose buffer grew as it went.
    from nsbench.hybrid import run as hybrid_run
    from nsbench.model import loop
    from nsbench.sections import peaks

    p = nsbench.get_problem("two-dof", case=1)
    integ = nsbench.get_integrator("exact")
    integ.setup(p)
    codes: list[int] = []
    original = loop.hybrid_loop

    def counted(*args):
        codes.append(original(*args))
        return codes[-1]

    monkeypatch.setattr(loop, "hybrid_loop", counted)
    kw = dict(sections=[peaks(p)], hit_from=500.0, hit_stop=100)
    sized = hybrid_run.run_hybrid(p, integ, 5000.0, **kw)
    assert sized.n_hits == 100 and codes.count(loop.R_GROW_HITS) == 0
    monkeypatch.setattr(hybrid_run, "MAX_HITS_AHEAD", 8)  # the buffer starts smaller than the hits
    codes.clear()
    grown = hybrid_run.run_hybrid(p, integ, 5000.0, **kw)
    assert codes.count(loop.R_GROW_HITS) >= 1
    np.testing.assert_array_equal(sized.records.ht[:100], grown.records.ht[:100])
    np.testing.assert_array_equal(sized.records.hy[:100], grown.records.hy[:100])


def test_a_stop_at_events_the_problem_does_not_have_is_refused():
    from nsbench.hybrid.run import run_hybrid

    problem = nsbench.get_problem("henon-heiles")
    integ = nsbench.get_integrator("henon-rk4")
    integ.setup(problem)
    with pytest.raises(nsbench.ConfigError, match="stop_kind 'slip': henon-heiles has no such events; its event kinds"):
        run_hybrid(problem, integ, 10.0, stop_kind="slip", stop_count=1)
