"""``cvode-bdf``, ``cvode-adams``, ``ida``: event times against exact, the DAE's structure, the kernels."""

from __future__ import annotations

import numpy as np
import pytest

import nsbench
from nsbench.integrators import _sundials_kernels as sk
from nsbench.problems.friction_spec import LAYOUT
from tests.conftest import exact_events, max_time_error, same_sequence
from tests.integrators.runs import two_dof_run

SUNDIALS = ["cvode-bdf", "cvode-adams", "ida"]
TIGHT = (("atol", 1e-14), ("rtol", 1e-12))


def _check(name, case, options, bound):
    res = two_dof_run(name, case, 300.0, options)
    ref = exact_events("two-dof", case)
    assert res.ok, res.message
    assert same_sequence(res.events, ref)
    assert max_time_error(res.events, ref) <= bound


@pytest.mark.parametrize("name", SUNDIALS)
def test_case_2_at_rtol_1e12_within_1e8(name):
    _check(name, 2, TIGHT, 1e-8)


def test_adams_case_1_at_rtol_1e12_within_1e8():
    _check("cvode-adams", 1, TIGHT, 1e-8)


@pytest.mark.parametrize("name", ["cvode-bdf", "ida"])
@pytest.mark.xfail(
    reason="BDF's phase error drifts linearly on the unforced cycle: 2.3e-8 (cvode-bdf) and "
    "1.5e-8 (ida) by tau = 300 at rtol = 1e-12 (scipy-bdf: 1.8e-8); within 1e-8 from "
    "rtol = 1e-13 on",
    strict=False,
)
def test_bdf_case_1_at_rtol_1e12_within_1e8(name):
    _check(name, 1, TIGHT, 1e-8)


@pytest.mark.parametrize("name", ["cvode-bdf", "ida"])
def test_bdf_case_1_at_rtol_1e13_within_1e8(name):
    _check(name, 1, (("atol", 1e-15), ("rtol", 1e-13)), 1e-8)


@pytest.mark.parametrize("name", SUNDIALS)
def test_cubic_forced_case_against_quad(name):
    res = two_dof_run(name, 4, 300.0, (("atol", 1e-12), ("rtol", 1e-10)))
    quad = two_dof_run("heyoka-q", 4)
    assert same_sequence(res.events, quad.events)
    assert max_time_error(res.events, quad.events) <= 1e-6


def test_plain_cvode_misses_a_force_driven_slip():
    # The pitfall the cos/sin states cure: from t ~ 31.38 both blocks stick and the
    # mechanical states are linear in t, so CVODE's steps grow past the forcing
    # period; block 2's force-driven slip at t ~ 33.46 is stepped over.
    from sksundae.cvode import CVODE

    p = nsbench.get_problem("two-dof", case=2)
    ref = exact_events("two-dof", 2)
    start = ref.iloc[11]  # both blocks stuck from here
    assert (start["kind"], start["block"]) == ("stick", 1)
    guards = p.guards((0, 0))

    def rhs(t, y, yp):
        yp[:] = p.rhs((0, 0), t, y)

    def events(t, y, out):
        for q, g in enumerate(guards):
            out[q] = g.expected_sign * float(g.value(t, y))

    events.terminal, events.direction = [True] * 4, [-1] * 4
    y0 = start[["x1", "v1", "x2", "v2"]].to_numpy(dtype=float)
    plain = CVODE(rhs, rtol=1e-12, atol=1e-14, eventsfn=events, num_events=4).solve([start["t"], 60.0], y0)
    assert plain.t[-1] > 35.0  # stopped at a later event: the slip at 33.46 was missed
    res = two_dof_run("cvode-bdf", 2, 60.0, (("atol", 1e-8), ("rtol", 1e-6)))
    assert same_sequence(res.events, exact_events("two-dof", 2, 60.0))


def _codes(guards):
    """Kind codes, 0-based blocks and expected signs of guards, as the compiled callbacks take them."""
    return tuple(
        np.array(values, dtype=np.int64) for values in zip(*[(g.code, g.block - 1, g.expected_sign) for g in guards])
    )


@pytest.mark.parametrize("law", [{}, {"law": "stribeck", "fk": 0.5, "vs": 0.2, "cv": 0.1}], ids=["coulomb", "stribeck"])
def test_cvode_kernels_match_the_problem(law):
    p = nsbench.get_problem("two-dof", case=4, **law)
    pk = p.packed.copy()
    pk[LAYOUT.offset("F", 2)] = 0.0  # CVODE's coefficients: the force enters through cos(w t)
    F, w = p.coefficients.F, p.coefficients.w
    rng = np.random.default_rng(3)
    for mode in p.modes:
        t = float(rng.uniform(0, 50))
        y = rng.uniform(-1, 1, 4)
        for i, ph in enumerate(mode):
            if ph == 0:
                y[2 * i + 1] = p.v0
        z = np.concatenate([y, [np.cos(w * t), np.sin(w * t)]])
        out = np.empty(6)
        sk.cvode_rhs(pk, np.array(mode, dtype=np.int64), F, w, z, out)
        np.testing.assert_allclose(out[:4], p.rhs(mode, t, y), atol=1e-14)
        jac = np.empty((6, 6))
        sk.cvode_jacobian(pk, np.array(mode, dtype=np.int64), F, w, z, jac)
        np.testing.assert_allclose(jac[:4, :4], p.jacobian(mode, t, y), atol=1e-14)
        guards = p.guards(mode)
        kinds, blocks, signs = _codes(guards)
        roots = np.empty(len(guards))
        sk.cvode_roots(
            pk, np.array(mode, dtype=np.int64), F, kinds, blocks, signs, np.zeros((0, 4)), np.zeros(0), z, roots
        )
        expected = [g.expected_sign * float(g.value(t, y)) for g in guards]
        np.testing.assert_allclose(roots, expected, atol=1e-14)


@pytest.mark.parametrize(
    "law",
    [{}, {"law": "weakening", "delta": 3.0}, {"law": "stribeck", "fk": 0.5, "vs": 0.2, "cv": 0.1}],
    ids=["coulomb", "weakening", "stribeck"],
)
@pytest.mark.parametrize("mode", [(-1, -1), (0, 1), (1, 0), (0, 0)])
def test_ida_dae_structure(mode, law):
    # Consistent values at a switch: zero residual; a stuck block's velocity is
    # pinned algebraically and its friction force equals R, whose bound is the
    # guard; the Jacobian is dF/dy + cj dF/dyp. A friction law other than Coulomb's
    # makes a slipping block's friction depend on its velocity (residual and Jacobian).
    p = nsbench.get_problem("two-dof", case=4, **law)
    pk, m = p.packed.copy(), np.array(mode, dtype=np.int64)
    rng = np.random.default_rng(7)
    t = 12.3
    y = rng.uniform(-1, 1, 4)
    for i, ph in enumerate(mode):
        if ph == 0:
            y[2 * i + 1] = p.v0
        elif law:  # a slip speed s (v - v0) >= 0, as while the phase holds
            y[2 * i + 1] = p.v0 + ph * abs(y[2 * i + 1])
    yy, yp = sk.consistent_start(pk, m, t, y)
    res = np.empty(6)
    sk.ida_residual(pk, m, t, yy, yp, res)
    np.testing.assert_allclose(res, 0.0, atol=1e-15)
    for i, ph in enumerate(mode):
        force = p.friction_forces(mode, t, y)[i]
        assert yy[4 + i] == pytest.approx(float(force), abs=1e-15)
    guards = p.guards(mode)
    kinds, blocks, signs = _codes(guards)
    roots = np.empty(len(guards))
    sk.ida_roots(pk, kinds, blocks, signs, np.zeros((0, 4)), np.zeros(0), yy, roots)
    np.testing.assert_allclose(roots, [g.expected_sign * float(g.value(t, y)) for g in guards], atol=1e-14)
    cj, jac, scratch = 3.7, np.empty((6, 6)), np.empty((4, 4))
    sk.ida_jacobian(pk, m, np.full(2, -1, dtype=np.int64), t, yy, cj, scratch, jac)
    numeric = np.empty((6, 6))
    for j in range(6):
        e = np.zeros(6)
        e[j] = 1e-6
        hi, lo = np.empty(6), np.empty(6)
        sk.ida_residual(pk, m, t, yy + e, yp + cj * e, hi)
        sk.ida_residual(pk, m, t, yy - e, yp - cj * e, lo)
        numeric[:, j] = (hi - lo) / 2e-6
    np.testing.assert_allclose(jac, numeric, atol=1e-7)


def test_ida_follows_the_forcing_through_the_stuck_force():
    # With both blocks stuck only the algebraic force f2 = R2 carries the forcing;
    # IDA's error test includes it, so a loose tolerance still finds the slip at 33.46.
    res = two_dof_run("ida", 2, 60.0, (("atol", 1e-8), ("rtol", 1e-6)))
    assert same_sequence(res.events, exact_events("two-dof", 2, 60.0))


@pytest.mark.parametrize("name", SUNDIALS)
def test_counters_budget_and_options(name, case1):
    res = two_dof_run(name, 2, 300.0, TIGHT)
    c = res.counters
    assert c.nfev > c.nsteps > 0 and c.njev > 0 and c.extra["root_returns"] >= len(res.events)
    # stepped from Python (states asked for) the budget is checked at every step; an arc in one call checks
    # it when the call returns (test_an_arc_in_one_call_keeps_to_the_step_budget)
    short = nsbench.simulate(case1, name, 300.0, max_steps=50, check_points=3001)
    assert short.status is nsbench.Status.BUDGET_EXHAUSTED and short.counters.nsteps <= 50
    with pytest.raises(nsbench.ConfigError, match="rtol"):
        nsbench.get_integrator(name, rtol=0.5)


def test_sections_and_trajectory_match_exact(case2):
    from nsbench.sections import peaks, stroboscopic

    grid = np.linspace(0, 50, 201)
    secs = [peaks(case2), stroboscopic(case2)]
    ref = nsbench.simulate(case2, "exact", 50.0, t_eval=grid, sections=secs)
    cols = ["t", "x1", "v1", "x2", "v2"]
    for name in SUNDIALS:
        res = nsbench.simulate(case2, name, 50.0, t_eval=grid, sections=secs, options={"rtol": 1e-11, "atol": 1e-13})
        assert len(res.sections) == len(ref.sections) > 5
        np.testing.assert_allclose(res.sections[cols].to_numpy(), ref.sections[cols].to_numpy(), atol=1e-8)
        np.testing.assert_allclose(res.trajectory[cols].to_numpy(), ref.trajectory[cols].to_numpy(), atol=1e-8)


@pytest.mark.parametrize("name", SUNDIALS)
def test_an_arc_without_states_in_one_call_is_the_stepped_arc(name, monkeypatch):
    # An arc that asks for no states runs as one call of scikit-sundae's solve; stepped from Python
    # instead, the same solver must give the same events, section crossings and counters, bit for
    # bit. Case 3 over [0, 400] ends in a step that reaches t_end as a plain step return followed by
    # a tstop return at the same time (cvode-bdf): one step, not two.
    from nsbench.integrators.sundials import SundialsIntegrator
    from nsbench.sections import peaks

    def run(case):
        problem = nsbench.get_problem("two-dof", case=case)
        return nsbench.simulate(
            problem, name, 400.0, check_points=0, sections=[peaks(problem)], options={"loop": "per-arc"}
        )

    whole = {case: run(case) for case in (2, 3)}
    monkeypatch.setattr(SundialsIntegrator, "_whole_arc", SundialsIntegrator._stepped_arc)
    for case, fast in whole.items():
        stepped = run(case)
        assert fast.ok and stepped.ok and len(fast.events) > 100
        assert fast.events.equals(stepped.events)  # exact equality of every value (NaN with NaN)
        assert len(fast.sections) > 20 and fast.sections.equals(stepped.sections)
        assert fast.counters == stepped.counters


@pytest.mark.parametrize("name", SUNDIALS)
def test_an_arc_in_one_call_keeps_to_the_step_budget(name, case1):
    # the budget is checked when the call returns: the run ends there, with its status and reason
    # (the per-arc path's one call; the native loop checks it before every step)
    res = nsbench.simulate(case1, name, 300.0, max_steps=50, check_points=0, options={"loop": "per-arc"})
    assert res.status is nsbench.Status.BUDGET_EXHAUSTED and "budget" in res.message
    assert res.counters.nsteps > 50


@pytest.mark.parametrize("name", SUNDIALS)
@pytest.mark.parametrize("check_points", [None, 0])
def test_the_root_lists_do_not_grow_over_a_run(name, check_points, case2):
    # scikit-sundae appends every root (index, time, state; IDA also the derivative) to lists on the
    # events function and turns them into arrays at every step: left to grow, each step of a run
    # costs more than the one before (IDA's derivatives were kept, and its steps slowed twofold).
    integ = nsbench.get_integrator(name, loop="per-arc")
    res = nsbench.simulate(case2, integ, 300.0, check_points=check_points)
    assert res.ok and res.counters.extra["root_returns"] > 100
    kept = [solver[1] for solver in integ._solvers.values()]
    assert kept
    for eventsfn in kept:
        lists = [getattr(eventsfn, name) for name in ("_i", "_t", "_y", "_yp") if hasattr(eventsfn, name)]
        assert len(lists) >= 3 and all(len(store) == 0 for store in lists)


def test_the_fallback_state_is_linear_between_the_last_step_end_and_the_known_point():
    # A requested time the solver's interpolant can no longer reach (a rare SUNDIALS refusal) is
    # interpolated linearly between the last step end and the point known after it, on the problem's
    # states only (a CVODE state may carry cos and sin of the forcing after them).
    from nsbench.integrators._sundials_loop import InterpolatedOutput

    out = InterpolatedOutput(None, np.array([1.5]), 2)
    np.testing.assert_array_equal(out._linear(1.5, 2.0, np.array([2.0, 4.0, 7.0])), [2.0, 4.0])  # no step end yet
    out.last = (1.0, np.array([0.0, 0.0, 9.0, 9.0]))
    np.testing.assert_array_equal(out._linear(1.5, 2.0, np.array([2.0, 4.0, 7.0, 7.0])), [1.0, 2.0])


def test_the_case_2_point_where_cvode_adams_stepped_over_a_stick_and_a_slip():
    """Issue 48, item 9: set 107 of the random study (2-DOF case 2, fs = fr on block 1), cvode-adams at its
    default tolerance over [0, 20]. Looked at only at its step ends and the study's 20 dense points (or
    none), it ended 'success' with 10 of the 12 events of exact (block 2's stick at 7.899 and its slip at
    9.094 stepped over); 3001 check points flag it. With its per-step check (the steps around 7.9
    integrated again) it gives exact's sequence. This is the per-arc path's check (forced here); the native
    loop's own check (the solver's interpolant at each step's middle) flags the point as 'event missed'."""
    import dataclasses

    from nsbench.integrators.sundials import CvodeAdams
    from tests.test_random_study import parameter_sets

    class Unchecked(CvodeAdams):
        name = "test-cvode-adams-unchecked"
        check_steps = False
        capabilities = dataclasses.replace(CvodeAdams.capabilities, checks_steps=False)

    case, params, t_end = parameter_sets()[107]
    p = nsbench.get_problem("two-dof", case=case, **params)
    grid = np.linspace(0.0, t_end, 20)
    ref = nsbench.simulate(p, "exact", t_end).events
    old = nsbench.simulate(p, Unchecked(loop="per-arc"), t_end, t_eval=grid, check_points=0)
    assert old.ok and len(old.events) == 10 and len(ref) == 12
    assert (
        nsbench.simulate(p, Unchecked(loop="per-arc"), t_end, check_points=3001).status is nsbench.Status.EVENT_MISSED
    )
    for kwargs in ({"t_eval": grid}, {}):
        new = nsbench.simulate(p, nsbench.get_integrator("cvode-adams", loop="per-arc"), t_end, **kwargs)
        assert new.ok and same_sequence(new.events, ref) and new.counters.extra["check_reruns"] > 0
        # rtol 1e-8 over t <= 20 through 12 events: within 1e-5 of exact (measured 2.0e-6)
        assert max_time_error(new.events, ref) <= 1e-5
    native = nsbench.simulate(p, "cvode-adams", t_end)  # never a success with a wrong sequence
    assert native.loop == "native" and (
        native.status is nsbench.Status.EVENT_MISSED or (native.ok and same_sequence(native.events, ref))
    ), native.message
