"""The compiled fast path against the Python engine: same event sequences, same times.

``exact-jit`` evaluates the same closed form as ``exact`` (summation order
differs, so rounding differs); both locate roots to a few ulps, and event
chaining over tau = 300 amplifies ulp-level differences to ~1e-12 at most
(measured 1.4e-13 for case 1 and 7e-13 for case 2): tolerance 1e-11.
``henon-rk4-jit`` runs the same steps as ``henon-rk4`` (same grid, same Henon
step), so on periodic scenarios their event times agree to rounding: 1e-12.
"""

from __future__ import annotations

import numpy as np
import pytest

import nsbench
from nsbench.integrators import get_integrator
from nsbench.sections import peaks, stroboscopic
from tests.conftest import exact_events, max_time_error, same_sequence


@pytest.mark.parametrize("problem, case", [("two-dof", 1), ("two-dof", 2), ("one-dof", 1)])
def test_exact_jit_matches_exact(problem, case):
    p = nsbench.get_problem(problem, case=case)
    ref = exact_events(problem, case)
    res = nsbench.simulate(p, "exact-jit", 300.0)
    assert res.ok
    assert same_sequence(res.events, ref)
    assert max_time_error(res.events, ref) < 1e-11
    states = ["x1", "v1"] + (["x2", "v2"] if problem == "two-dof" else [])
    assert np.abs(res.events[states].to_numpy() - ref[states].to_numpy()).max() < 1e-10


@pytest.mark.parametrize("case, t_end", [(2, 300.0), (4, 150.0)])
def test_henon_rk4_jit_matches_henon_rk4(case, t_end):
    p = nsbench.get_problem("two-dof", case=case)
    sec = [peaks(p)]
    a = nsbench.simulate(p, "henon-rk4", t_end, options={"h": 0.02}, sections=sec)
    b = nsbench.simulate(p, "henon-rk4-jit", t_end, options={"h": 0.02}, sections=sec)
    assert same_sequence(a.events, b.events)
    assert max_time_error(a.events, b.events) < 1e-12
    assert len(a.sections) == len(b.sections) > 10
    assert np.abs(a.sections["t"].to_numpy() - b.sections["t"].to_numpy()).max() < 1e-12
    assert b.counters.nfev == a.counters.nfev  # the same evaluations, counted the same way


def test_compiled_hybrid_loop_matches_the_engine():
    # peaks, mapping points and stroboscopic states of the compiled loop = the engine's
    p = nsbench.get_problem("two-dof", case=1, v0=0.1)
    ref = nsbench.simulate(p, "exact", 400.0, sections=[peaks(p)])
    jit = get_integrator("exact-jit")
    run = jit.run(p, t_end=400.0, section="peaks", t_rec=100.0, n_rec=30)
    want = ref.sections[ref.sections["t"] >= 100.0].iloc[:30]
    assert run.status == "success" and run.n == 30
    assert np.abs(want["t"].to_numpy() - run.rec_t).max() < 1e-11
    assert np.abs(want[["x1", "v1", "x2", "v2"]].to_numpy() - run.rec_y).max() < 1e-11
    run = jit.run(p, t_end=400.0, section="mapping", t_rec=100.0, n_rec=30)
    slips = ref.events[(ref.events["t"] >= 100.0) & (ref.events["kind"] == "slip")].iloc[:30]
    assert np.abs(slips["t"].to_numpy() - run.rec_t).max() < 1e-11
    assert (slips["block"].to_numpy() == run.rec_block).all()
    events_in_window = ref.events[(ref.events["t"] >= 100.0) & (ref.events["t"] <= run.rec_t[-1])]
    assert run.counters["slips1"] + run.counters["slips2"] == 30
    assert run.counters["sticks1"] == int(((events_in_window["kind"] == "stick")
                                           & (events_in_window["block"] == 1)).sum())
    p2 = nsbench.get_problem("two-dof", case=2)
    times = 2 * np.pi * np.arange(20, 40)
    run = jit.run(p2, t_end=float(times[-1]), section="strobe", times=times)
    ref2 = nsbench.simulate(p2, "exact", float(times[-1]) + 1.0, sections=[stroboscopic(p2)])
    want = ref2.sections[ref2.sections["t"] >= times[0] - 1e-9].iloc[:20]
    assert np.abs(want[["x1", "v1", "x2", "v2"]].to_numpy() - run.rec_y).max() < 1e-11


def test_rk4_jit_on_cubic_against_tight_reference():
    # independent accuracy check: h = 0.02 against h = 0.0025 (order 4: ~4000x smaller error)
    p = nsbench.get_problem("two-dof", case=3)
    coarse = nsbench.simulate(p, "henon-rk4-jit", 100.0, options={"h": 0.02})
    fine = nsbench.simulate(p, "henon-rk4-jit", 100.0, options={"h": 0.0025})
    assert same_sequence(coarse.events, fine.events)
    assert max_time_error(coarse.events, fine.events) < 1e-5


def test_exact_jit_refuses_cubic_problems():
    from nsbench.errors import UnsupportedProblemError

    with pytest.raises(UnsupportedProblemError):
        nsbench.simulate(nsbench.get_problem("two-dof", case=3), "exact-jit", 10.0)


def test_compiled_guards_and_transitions_follow_the_model():
    from nsbench.bifurcation import _jit_model as jm
    from nsbench.problems import kernels

    p = nsbench.get_problem("two-dof", case=2)
    packed = kernels.pack(p)
    gk, gb, gs = (np.empty(4, np.int64) for _ in range(3))
    rng = np.random.default_rng(3)
    for index, mode in enumerate(p.modes):
        m = np.array(mode, dtype=np.int64)
        assert jm.mode_index(m) == index
        ng = jm.guards_of(m, gk, gb, gs)
        kinds, blocks, signs = kernels.guard_codes(p.guards(mode))
        assert (gk[:ng] == kinds).all() and (gb[:ng] == blocks).all() and (gs[:ng] == signs).all()
        for q, guard in enumerate(p.guards(mode)):
            y, t = rng.normal(size=4), float(rng.uniform(0, 10))
            want = p.transition(mode, guard, t, y)
            m2, y2 = m.copy(), y.copy()
            kind = jm.transition(packed, m2, gk[q], gb[q], t, y2)
            assert ("stick", "slip", "reverse")[kind] == want.kind
            assert tuple(m2) == want.mode and np.array_equal(y2, want.y)
