"""``heyoka``, ``heyoka-ld``, ``heyoka-q``: event times against exact and quad, one compilation per structure."""

from __future__ import annotations

import numpy as np
import pytest

import nsbench
from nsbench.integrators import _heyoka_model
from nsbench.integrators.base import ArcRequest
from nsbench.sections import peaks, stroboscopic
from tests.conftest import conditioning_of, exact_events, max_time_error, precision_bound, same_sequence
from tests.integrators.runs import two_dof_run

EPS_DOUBLE = float(np.finfo(float).eps)
EPS_LONG_DOUBLE = float(np.finfo(np.longdouble).eps)


@pytest.mark.parametrize("case", [1, 2])
def test_heyoka_reproduces_exact_on_linear_cases(case):
    res = two_dof_run("heyoka", case)
    ref = exact_events("two-dof", case)
    assert res.ok, res.message
    assert same_sequence(res.events, ref)
    assert max_time_error(res.events, ref) <= 1e-12


@pytest.mark.parametrize("case", [3, 4])
def test_heyoka_matches_quad_precision_on_cubic_cases(case):
    # heyoka (double, tol = eps) against heyoka-q: kappa = 12 and 21 on cases 3 and 4 over tau 300, about
    # 900 Taylor steps: bounds 2.5e-12 and 4.1e-12. Seen: 5.7e-14 and 2.3e-13 (1 and 4 ulp of t ~ 300).
    res, quad = two_dof_run("heyoka", case), two_dof_run("heyoka-q", case)
    assert res.ok and quad.ok
    assert same_sequence(res.events, quad.events)
    bound = precision_bound(quad.events["t"], conditioning_of("two-dof", case), EPS_DOUBLE, res.counters.nsteps)
    assert max_time_error(res.events, quad.events) <= bound


def test_long_double_agrees_with_quad_on_a_cubic_case():
    # Event detection in extended precision: kappa * eps_ld * steps is about 2e-15 here, far below an
    # ulp of t, so both round to the same doubles or to neighbours (seen: the same doubles).
    ld, quad = two_dof_run("heyoka-ld", 4), two_dof_run("heyoka-q", 4)
    assert same_sequence(ld.events, quad.events)
    bound = precision_bound(quad.events["t"], conditioning_of("two-dof", 4), EPS_LONG_DOUBLE, ld.counters.nsteps)
    assert max_time_error(ld.events, quad.events) <= bound


@pytest.mark.parametrize("tol", [1e-3, 1e-8])
def test_force_driven_slip_while_both_blocks_stick(tol):
    # Case 2: block 2 slips at t ~ 33.46 while both blocks stick, pushed only by
    # the forcing; the mechanical states are linear in t there and say nothing
    # about it. The forcing lives in the cos/sin states, whose Taylor
    # coefficients bound the step, so even a loose tolerance finds the slip.
    res = two_dof_run("heyoka", 2, 60.0, (("tol", tol),))
    ref = exact_events("two-dof", 2, 60.0)
    assert same_sequence(res.events, ref)
    slip2 = res.events[(res.events["kind"] == "slip") & (res.events["block"] == 2)]
    assert np.any(np.abs(slip2["t"] - 33.4624) < 1e-3)


def test_one_compilation_per_problem_structure():
    first = nsbench.get_integrator("heyoka")
    first.setup(nsbench.get_problem("two-dof", case=2))
    entries = len(_heyoka_model._CACHE)
    other = nsbench.get_problem("two-dof", case=2, v0=0.1, F=0.3)  # same structure
    res = nsbench.simulate(other, "heyoka", 100.0)
    assert res.ok and len(res.events) > 10  # many mode switches, no recompilation
    assert len(_heyoka_model._CACHE) == entries
    assert res.setup_time < 0.05  # a copy of the compiled integrator


def test_inactive_guards_never_fire(case1):
    # A slip- arc that crosses v = v0, given no guards: the events of every phase
    # are compiled in, but only the request's guards may stop the arc.
    integ = nsbench.get_integrator("heyoka")
    integ.setup(case1)
    y0 = np.zeros(4)
    y0.flags.writeable = False
    arc = integ.advance(ArcRequest(problem=case1, mode=(-1, -1), t0=0.0, y0=y0, t_end=5.0, guards=()))
    assert arc.fired is None and arc.t == 5.0 and arc.status.ok
    guarded = integ.advance(
        ArcRequest(problem=case1, mode=(-1, -1), t0=0.0, y0=y0, t_end=5.0, guards=case1.guards((-1, -1)))
    )
    assert guarded.fired is not None and guarded.t < 1.0


def test_sections_and_trajectory_match_exact(case2):
    # Three state sections: one more than the slots compiled in setup(), so a
    # wider model is compiled on demand.
    from nsbench.sections import level_crossing

    grid = np.linspace(0, 50, 201)
    secs = [peaks(case2), peaks(case2, block=2), level_crossing(case2, "v2", 0.05, +1), stroboscopic(case2)]
    ref = nsbench.simulate(case2, "exact", 50.0, t_eval=grid, sections=secs)
    res = nsbench.simulate(case2, "heyoka", 50.0, t_eval=grid, sections=secs)
    assert len(res.sections) == len(ref.sections) > 20
    assert set(res.sections["section"]) == {"peaks_x1", "peaks_x2", "v2=0.05", "strobe"}
    cols = ["t", "x1", "v1", "x2", "v2"]
    np.testing.assert_allclose(res.sections[cols].to_numpy(), ref.sections[cols].to_numpy(), atol=1e-12)
    np.testing.assert_allclose(res.trajectory[cols].to_numpy(), ref.trajectory[cols].to_numpy(), atol=1e-12)


@pytest.mark.parametrize("name", ["heyoka", "heyoka-q"])
def test_states_at_many_times_in_every_step_come_from_their_own_step(case2, name):
    # A grid ten times as dense as the steps: each arc spans several Taylor steps, each step holds
    # several requested times, and each is evaluated on the polynomial of the step that holds it
    # (a step callback, not heyoka's continuous output). Against exact's closed form to 1e-12, as
    # the coarse grid above: heyoka's error on this case is rounding (tolerance at eps).
    grid = np.linspace(0.0, 50.0, 20_001)
    ref = nsbench.simulate(case2, "exact", 50.0, t_eval=grid)
    res = nsbench.simulate(case2, name, 50.0, t_eval=grid)
    assert res.ok, res.message
    assert res.counters.nsteps > len(res.events) and len(grid) > 10 * res.counters.nsteps  # arcs of several steps
    cols = ["t", "x1", "v1", "x2", "v2"]
    assert list(res.events["kind"]) == list(ref.events["kind"])
    np.testing.assert_allclose(res.trajectory[cols].to_numpy(), ref.trajectory[cols].to_numpy(), atol=1e-12)


def _hits_and_callbacks(problem, name: str, hit_from: float, monkeypatch, **kwargs):
    """The section hits of a run through the core at ``t >= hit_from``, and the number of section
    callbacks heyoka made (counted on the callback class)."""
    from nsbench.hybrid.run import run_hybrid

    calls = [0]
    record = _heyoka_model.SectionLog.__call__

    def counted(self, ta, t, d_sgn):
        calls[0] += 1
        return record(self, ta, t, d_sgn)

    monkeypatch.setattr(_heyoka_model.SectionLog, "__call__", counted)
    # the per-arc adapter's sections (the native run's are terminal events: tests/integrators/test_native_runs.py)
    integ = nsbench.get_integrator(name, **({"loop": "per-arc"} if name.startswith("heyoka") else {}))
    integ.setup(problem)
    raw = run_hybrid(problem, integ, 80.0, sections=[peaks(problem)], hit_from=hit_from, **kwargs)
    rec = raw.records
    return raw, np.column_stack([rec.ht[: raw.n_hits], rec.hy[: raw.n_hits]]), calls[0]


def test_sections_off_before_sections_from_keep_every_hit_after_it(case2, monkeypatch):
    # A sweep's transient: the core drops hits before hit_from, and heyoka runs those arcs with its
    # sections off (ArcRequest.sections_from), stopping its propagation at hit_from. The hits after it
    # are exact's to heyoka's accuracy on this case (test_sections_and_trajectory_match_exact), and
    # heyoka calls back for none of the crossings before it but those of an arc's first steps.
    ref, ref_hits, _ = _hits_and_callbacks(case2, "exact", 40.0, monkeypatch)
    raw, hits, calls = _hits_and_callbacks(case2, "heyoka", 40.0, monkeypatch)
    _, all_hits, all_calls = _hits_and_callbacks(case2, "heyoka", -np.inf, monkeypatch)
    assert raw.status is nsbench.Status.SUCCESS and len(hits) == len(ref_hits) >= 5
    assert (hits[:, 0] >= 40.0).all()
    np.testing.assert_allclose(hits, ref_hits, rtol=0, atol=1e-12)
    before = int(np.count_nonzero(all_hits[:, 0] < 40.0))
    assert before >= 5 and calls <= all_calls - before


def test_an_arc_whose_first_steps_pass_sections_from_is_run_again_with_its_sections(case2, monkeypatch):
    # An arc that starts on a guard's surface takes its first steps apart (HeyokaIntegrator._first_step);
    # with the sections off, steps that go past sections_from would miss the crossings just after it. Such
    # an arc is run again with its sections on: no crossing after sections_from is missed, and the hits are
    # the run's with sections throughout to heyoka's accuracy (not bit for bit: the arc before ended at
    # an event inside a step cut at sections_from, whose root is found on a shorter interval).
    from nsbench.integrators.heyoka_ import HeyokaIntegrator

    full, full_hits, _ = _hits_and_callbacks(case2, "heyoka", -np.inf, monkeypatch)
    propagate, again = HeyokaIntegrator._propagate, []

    def watched(self, compiled, request, quiet, spent=0):
        out = propagate(self, compiled, request, quiet, spent)
        again.append(out[0] is None)
        return out

    monkeypatch.setattr(HeyokaIntegrator, "_propagate", watched)
    checked = 0
    for t_event in full.records.ev_t[: full.n_events][5:25]:
        hit_from = float(t_event) + 1e-9  # inside the first step of the arc after the event
        again.clear()
        raw, hits, _ = _hits_and_callbacks(case2, "heyoka", hit_from, monkeypatch)
        wanted = full_hits[full_hits[:, 0] >= hit_from]
        assert raw.status is nsbench.Status.SUCCESS and len(hits) == len(wanted)
        np.testing.assert_allclose(hits, wanted, rtol=0, atol=1e-12)
        checked += any(again)
    assert checked >= 3  # the arcs run again


def test_a_step_budget_spent_before_sections_from_is_a_status(case2, monkeypatch):
    raw, hits, _ = _hits_and_callbacks(case2, "heyoka", 70.0, monkeypatch, max_steps=30)
    assert raw.status is nsbench.Status.BUDGET_EXHAUSTED and raw.counters.nsteps <= 30
    assert raw.t < 70.0 and len(hits) == 0


def test_step_budget_is_a_status(case1):
    res = nsbench.simulate(case1, "heyoka", 300.0, max_steps=20)
    assert res.status is nsbench.Status.BUDGET_EXHAUSTED
    assert res.counters.nsteps <= 20


def test_counters_and_options(case1):
    res = two_dof_run("heyoka", 1)
    c = res.counters
    assert c.nsteps > 0 and c.nfev == c.nsteps and c.njev == 0
    assert c.extra["taylor_coefficients"] >= 10 * c.nsteps  # order ~20 in double
    with pytest.raises(nsbench.ConfigError, match="tol"):
        nsbench.get_integrator("heyoka", tol=-1.0)
    with pytest.raises(nsbench.ConfigError, match="compact_mode"):
        nsbench.get_integrator("heyoka", compact_mode="yes")


@pytest.mark.parametrize("name", ["heyoka", "heyoka-q"])
def test_grazing_start_is_not_an_event(name):
    # rf2 = rho2: a fresh slip of block 2 starts with zero acceleration, so its
    # velocity guard dips by rounding right at t0; the arc must end at t > t0 only.
    params = dict(
        c1=0.375,
        c2=0.375,
        kappa=1.75,
        mu=0.7106924674664972,
        rho2=1.75,
        rf1=0.875,
        rf2=1.75,
        F=0.375,
        Omega=2.5,
        v0=0.5,
    )
    p = nsbench.get_problem("two-dof", case=2, **params)
    res = nsbench.simulate(p, name, 60.0)
    ref = nsbench.simulate(p, "exact", 60.0)
    assert res.ok, res.message
    assert same_sequence(res.events, ref.events)
    assert max_time_error(res.events, ref.events) < 1e-12


@pytest.mark.parametrize("name", ["heyoka", "heyoka-q"])
def test_crossing_inside_the_first_step_of_a_phase(name):
    # heyoka does not look for roots of an event that is zero where a step starts,
    # and a fresh phase's guard is exactly zero at its start: with quad precision's
    # long steps, block 2's return to the belt speed at t ~ 10.2986 fell inside the
    # first step of its slip and was missed. Random parameters from a stress run
    # against exact (which agrees with scipy-dop853, cvode-adams and henon-rk4).
    params = dict(
        c1=0.3661233074461234,
        c2=0.2681226586953908,
        kappa=3.5257387152090716,
        mu=0.985959941375206,
        rho2=1.6801921414092478,
        rf1=0.3167221697851682,
        rf2=1.638393897524099,
        F=0.5165770924477069,
        Omega=2.8566479995322,
        v0=0.1877044922586059,
    )
    p = nsbench.get_problem("two-dof", case=2, **params)
    res, ref = nsbench.simulate(p, name, 60.0), nsbench.simulate(p, "exact", 60.0)
    assert same_sequence(res.events, ref.events)
    assert max_time_error(res.events, ref.events) < 1e-12


def test_a_pickled_integrator_writes_into_its_own_compiled_integrator():
    # The kept compiled integrator holds numpy views of heyoka's storage (state, parameters, Taylor
    # coefficients), read once. A pickled view would be an array of its own: writing the next arc's
    # state into it would leave heyoka's untouched. After unpickling, the views are the unpickled
    # integrator's own, and the integrator runs as before.
    import pickle

    problem = nsbench.get_problem("two-dof", case=1)
    integ = nsbench.get_integrator("heyoka")
    first = nsbench.simulate(problem, integ, 60.0)
    copied, copied_problem = pickle.loads(pickle.dumps((integ, problem)))
    assert copied._models
    for compiled in copied._models.values():
        for name in ("state", "pars", "tc"):
            assert np.shares_memory(getattr(compiled, name), getattr(compiled.ta, name))
    again = nsbench.simulate(copied_problem, copied, 60.0)
    assert first.ok and again.ok
    np.testing.assert_array_equal(again.events["t"], first.events["t"])
