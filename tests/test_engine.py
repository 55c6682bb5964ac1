"""The hybrid engine: statuses, sections, trajectories, degenerate starts, integrator faults."""

from __future__ import annotations

import dataclasses
import re

import numpy as np
import pytest

import nsbench
from nsbench import registry
from nsbench.integrators import ArcResult, Capabilities, Integrator
from nsbench.integrators.scipy_ import ScipyDOP853
from nsbench.results import Status
from nsbench.sections import StateSection, TimeSection, peaks, stroboscopic


def test_event_log_columns(case1):
    res = nsbench.simulate(case1, "exact", 20.0)
    assert list(res.events.columns) == ["t", "kind", "block", "x1", "v1", "x2", "v2", "mode"]
    assert set(res.events["kind"]) <= {"stick", "slip", "reverse"}
    one = nsbench.simulate(nsbench.get_problem("one-dof"), "exact", 20.0)
    assert list(one.events.columns) == ["t", "kind", "block", "x1", "v1", "mode"]


def test_the_event_log_names_the_mode_after_each_event(case1):
    # replaying the transition rules on the log gives the same modes (no module needs to replay them)
    res = nsbench.simulate(case1, "exact", 60.0)
    mode = case1.initial_mode(0.0, case1.initial_state())
    for row in res.events.itertuples(index=False):
        y = np.array([getattr(row, name) for name in case1.state_names])
        guard = min((g for g in case1.guards(mode) if g.block == row.block), key=lambda g: abs(g.value(row.t, y)))
        mode = case1.transition(mode, guard, row.t, y).mode
        assert row.mode == "|".join({0: "stick", 1: "slip+", -1: "slip-"}[p] for p in mode)


def test_state_after_stick_has_belt_speed(case2):
    ev = nsbench.simulate(case2, "henon-rk4", 60.0, options={"h": 0.05}).events
    for row in ev.itertuples():
        assert getattr(row, f"v{row.block}") == case2.v0


def test_trajectory_on_requested_grid(case2):
    grid = np.linspace(0, 30, 301)
    for name in ("exact", "scipy-dop853", "henon-rk4"):
        res = nsbench.simulate(case2, name, 30.0, t_eval=grid)
        tr = res.trajectory
        np.testing.assert_array_equal(tr["t"].to_numpy(), grid)
        assert list(tr.columns) == ["t", "x1", "v1", "x2", "v2", "phase1", "phase2"]
        stuck = tr[tr["phase1"] == 0]
        assert (stuck["v1"] == case2.v0).all() or np.abs(stuck["v1"] - case2.v0).max() < 1e-12


def test_trajectories_agree_between_integrators(case2):
    grid = np.linspace(0, 30, 61)
    ref = nsbench.simulate(case2, "exact", 30.0, t_eval=grid).trajectory
    for name, tol in (("scipy-dop853", 1e-7), ("henon-rk4", 1e-6)):
        tr = nsbench.simulate(case2, name, 30.0, t_eval=grid).trajectory
        diff = np.abs(tr[["x1", "v1", "x2", "v2"]].to_numpy() - ref[["x1", "v1", "x2", "v2"]].to_numpy())
        assert diff.max() < tol, name


def test_peak_sections_agree_across_integrators(case2):
    sec = [peaks(case2, 1)]
    ref = nsbench.simulate(case2, "exact", 60.0, sections=sec).sections
    assert len(ref) > 5
    for name, opts in (("scipy-dop853", {"rtol": 1e-11, "atol": 1e-13}), ("henon-rk4", {"h": 0.01})):
        got = nsbench.simulate(case2, name, 60.0, options=opts, sections=sec).sections
        assert len(got) == len(ref), name
        np.testing.assert_allclose(got["t"], ref["t"], atol=1e-6)
        np.testing.assert_allclose(got["x1"], ref["x1"], atol=1e-8)


def test_sections_do_not_change_events(case2):
    plain = nsbench.simulate(case2, "scipy-dop853", 60.0).events
    observed = nsbench.simulate(case2, "scipy-dop853", 60.0, sections=[peaks(case2), stroboscopic(case2)]).events
    np.testing.assert_array_equal(plain["t"].to_numpy(), observed["t"].to_numpy())


def test_section_validation(case1):
    with pytest.raises(nsbench.ConfigError, match="direction"):
        StateSection("bad", (0, 1, 0, 0), 0.0, 2)
    with pytest.raises(nsbench.ConfigError, match="period"):
        TimeSection("bad", 0.0)
    with pytest.raises(nsbench.ConfigError, match="forcing frequency"):
        stroboscopic(nsbench.get_problem("two-dof", case=1, Omega=0.0))
    with pytest.raises(nsbench.ConfigError, match="3 coefficients"):
        nsbench.simulate(case1, "exact", 1.0, sections=[StateSection("s", (1.0, 0.0, 0.0))])


@pytest.mark.parametrize(
    "kwargs, fragment",
    [
        (dict(t_end=-1.0), "must be greater than t0"),
        (dict(t_end=float("nan")), "must be finite"),
        (dict(t_end=1.0, y0=[0.0, 0.0]), "needs 4 states"),
        (dict(t_end=1.0, t_eval=[0.5, 0.2]), "sorted"),
        (dict(t_end=1.0, t_eval=[0.5, 2.0]), "must lie in"),
    ],
)
def test_bad_engine_input(case1, kwargs, fragment):
    with pytest.raises(nsbench.ConfigError, match=fragment):
        nsbench.simulate(case1, "exact", **kwargs)


def test_unknown_integrator_and_option(case1):
    with pytest.raises(nsbench.ConfigError, match="unknown integrator 'rk5'"):
        nsbench.simulate(case1, "rk5", 1.0)
    with pytest.raises(nsbench.ConfigError, match="h = -0.1 must be > 0"):
        nsbench.simulate(case1, "henon-rk4", 1.0, options={"h": -0.1})


def test_budget_exhaustion_keeps_events(case1):
    res = nsbench.simulate(case1, "henon-rk4", 300.0, options={"h": 0.01}, max_steps=3000)
    assert res.status is Status.BUDGET_EXHAUSTED
    assert res.counters.nsteps <= 3000
    assert len(res.events) >= 2  # the ones found before the budget ran out are kept
    assert 20.0 < res.t_final < 40.0


class _AlwaysFires(Integrator):
    """A broken integrator: reports the first guard at the arc start, forever."""

    name = "test-always-fires"
    capabilities = Capabilities(event_location="none", order=None, adaptive=False)

    def advance(self, request):
        return ArcResult(t=request.t0, y=np.array(request.y0), fired=0, y_eval=np.empty((request.problem.n_states, 0)))


class _Diverges(Integrator):
    name = "test-diverges"
    capabilities = Capabilities(event_location="none", order=None, adaptive=False)

    def advance(self, request):
        return ArcResult(
            t=request.t0 + 1.0,
            y=np.full(request.problem.n_states, np.nan),
            fired=None,
            y_eval=np.empty((request.problem.n_states, 0)),
        )


class _Raises(Integrator):
    name = "test-raises"
    capabilities = Capabilities(event_location="none", order=None, adaptive=False)

    def advance(self, request):
        raise RuntimeError("boom")


def test_event_storm_is_detected(case1):
    res = nsbench.simulate(case1, _AlwaysFires(), 10.0)
    assert res.status is Status.EVENT_STORM
    assert "events within" in res.message
    assert len(res.events) == 65
    # told apart from a genuine accumulation, and the chattering guard named
    assert "all at one instant: a numerical storm" in res.message
    assert "chattering: " in res.message and "of block " in res.message


def test_an_accumulation_over_time_is_named_as_such():
    # exact on a real case with a tiny storm budget: events spread over time
    p = nsbench.get_problem("two-dof", case=2)
    res = nsbench.simulate(p, "exact", 300.0, zeno_events=3, zeno_span=5.0)
    assert res.status is Status.EVENT_STORM
    assert "spread over time" in res.message and "numerical storm" not in res.message


@pytest.mark.parametrize("bad, fragment", [(_Diverges, "non-finite"), (_Raises, "RuntimeError: boom")])
def test_integrator_failures_become_statuses(case1, bad, fragment):
    # no check points: these fakes return no dense states, which the protocol check would name first
    res = nsbench.simulate(case1, bad(), 10.0, check_points=0)
    assert res.status is Status.INTEGRATOR_FAILURE
    assert fragment in res.message


def test_runtime_registration(case1):
    registry.register("integrators", "test-always-fires", _AlwaysFires)
    try:
        assert "test-always-fires" in nsbench.list_integrators()
        res = nsbench.simulate(case1, "test-always-fires", 1.0)
        assert res.status is Status.EVENT_STORM
    finally:
        registry.unregister("integrators", "test-always-fires")
    assert "test-always-fires" not in nsbench.list_integrators()


def test_start_on_a_stick_boundary_fires_at_once():
    # Block 1 stuck exactly at its upper static limit with R1 increasing: the
    # stick guard is on its surface heading out, so it slips at t0.
    p = nsbench.get_problem("one-dof")
    c, v0 = p.parameters["c"], p.v0
    y0 = [1.0 - c * v0, v0]  # R = c v0 + x = 1 exactly
    res = nsbench.simulate(p, "exact", 5.0, y0=y0)
    assert res.events.iloc[0]["kind"] == "slip"
    assert res.events.iloc[0]["t"] == 0.0


def test_inputs_are_not_mutated(case2):
    y0 = np.array([0.1, 0.0, -0.1, 0.0])
    grid = np.linspace(0, 5, 11)
    keep_y, keep_g = y0.copy(), grid.copy()
    nsbench.simulate(case2, "henon-rk4", 5.0, y0=y0, t_eval=grid)
    np.testing.assert_array_equal(y0, keep_y)
    np.testing.assert_array_equal(grid, keep_g)


def test_summary_mentions_events_and_counters(case1):
    text = nsbench.simulate(case1, "exact", 30.0).summary()
    assert "stick@1" in text and "nfev=" in text and "wall time" in text


def test_compensated_time_is_carried_between_arcs(case1):
    # The engine keeps each event time as t + t_lo and hands t_lo back as the
    # next arc's t0_lo, so rounding t to a double does not accumulate.
    from nsbench.integrators.exact import ExactIntegrator

    class Recording(ExactIntegrator):
        def advance(self, request):
            arc = super().advance(request)
            self.seen.append((request.t0_lo, arc.t_lo))
            return arc

    integ = Recording()
    integ.seen = []
    nsbench.simulate(case1, integ, 100.0)
    handed = [lo for lo, _ in integ.seen[1:]]
    returned = [lo for _, lo in integ.seen[:-1]]
    assert handed == returned
    assert any(lo != 0.0 for lo in handed)


def test_invalid_low_time_parts_are_dropped():
    from nsbench.hybrid.run import low_part as _low_part

    assert _low_part(100.0, 1e-15) == 1e-15
    assert _low_part(100.0, 1e-3) == 0.0  # not a correction below one ulp
    assert _low_part(100.0, float("nan")) == 0.0


@pytest.mark.parametrize(
    "kw, fragment",
    [
        ({"max_steps": 0}, "max_steps = 0 must be a whole number from 1"),
        ({"max_steps": -5}, "max_steps = -5"),
        ({"max_steps": 2.5}, "max_steps = 2.5"),
        ({"max_steps": True}, "max_steps = True"),
        ({"max_steps": 10**30}, "max_steps = 10000"),
        ({"max_events": 0}, "max_events = 0"),
        ({"zeno_events": -1}, "zeno_events = -1"),
        ({"zeno_span": -1.0}, "zeno_span = -1.0 must be a finite time > 0"),
        ({"zeno_span": float("nan")}, "zeno_span = nan"),
        ({"zeno_span": float("inf")}, "zeno_span = inf"),
        ({"zeno_span": "1e-9"}, "zeno_span = '1e-9'"),
        # the accumulation rule's tolerance: a count of intervals (its meaning before issue 48) is refused
        # by name, as are a negative, nan or infinite tolerance
        ({"accumulation": -1}, "accumulation = -1 must be 0 (no accumulation rule) or the tolerance"),
        ({"accumulation": 8}, "accumulation = 8 must be 0"),
        # looser than 1e-4 the tail estimate no longer covers its error (docs/core.md)
        ({"accumulation": 1e-3}, "accumulation = 0.001 must be 0"),
        ({"accumulation": 1.5}, "no longer a count of intervals"),
        ({"accumulation": float("nan")}, "accumulation = nan"),
        ({"accumulation": float("inf")}, "accumulation = inf"),
        ({"accumulation": True}, "accumulation = True"),
        ({"accumulation": "1e-12"}, "accumulation = '1e-12'"),
    ],
)
def test_budgets_and_the_storm_span_are_checked(case1, kw, fragment):
    # each of these used to run: a budget of 0 or -5 steps ended at once with a message about
    # "-5 steps used", and a storm span of -1 or nan silently switched the storm check off
    with pytest.raises(nsbench.ConfigError, match=re.escape(fragment)):
        nsbench.simulate(case1, "exact", 10.0, **kw)


@pytest.mark.parametrize("value", [1, -1, 2.0, True, "100", 10**8])
def test_check_points_are_checked(case1, value):
    with pytest.raises(nsbench.ConfigError, match=re.escape(f"check_points = {value!r} must be 0")):
        nsbench.simulate(case1, "exact", 10.0, check_points=value)


def test_check_points_leave_a_clean_run_as_it_is(case2):
    """Check points are states the core looks at, not output: the log and the trajectory are unchanged."""
    grid = np.linspace(0.0, 40.0, 41)
    plain = nsbench.simulate(case2, "scipy-dop853", 40.0, t_eval=grid)
    checked = nsbench.simulate(case2, "scipy-dop853", 40.0, t_eval=grid, check_points=4001)
    assert plain.ok and checked.ok
    assert checked.events[["kind", "block"]].equals(plain.events[["kind", "block"]])
    assert np.allclose(checked.events["t"], plain.events["t"], rtol=0, atol=1e-6)  # same tolerance, same events
    assert checked.trajectory["t"].tolist() == grid.tolist() and len(checked.sections) == 0


def test_budgets_of_numpy_integers_are_accepted(case1):
    assert nsbench.simulate(
        case1, "exact", 10.0, max_steps=np.int64(1000), zeno_events=np.int32(8), accumulation=np.float32(1e-12)
    ).ok


class _UncheckedDop853(ScipyDOP853):
    """``scipy-dop853`` as ``solve_ivp`` runs it: only the signs at its step ends are looked at."""

    name = "test-dop853-unchecked"
    check_steps = False
    capabilities = dataclasses.replace(ScipyDOP853.capabilities, checks_steps=False)


def test_every_built_in_event_driven_integrator_checks_its_own_steps():
    """What check_points_for reads. henon-rk4 tests each step too (the cubic Hermite of each guard), but its
    fixed step is not sized to the guards: at h = 1.7 on case 1 the test sees 1 of exact's 8 events
    (tests/integrators/test_henon_rk4.py), so it keeps the check points. An integrator added without the
    declaration is checked at DEFAULT_CHECK_POINTS states."""
    from nsbench.engine import DEFAULT_CHECK_POINTS, check_points_for
    from nsbench.integrators import integrator_class, list_integrators
    from nsbench.integrators.whole import is_whole_system

    points = {}
    for name in list_integrators():
        if not is_whole_system(integrator_class(name)()):
            points[name] = check_points_for(integrator_class(name)())
    # the engines behind a pip extra (CyRK, diffrax) locate events on their own dense output without
    # nsbench's per-step test: the engine checks them at its evenly spaced points
    extras = {"cyrk-rk45", "cyrk-dop853", "cyrk-tsit5", "cyrk-vern7", "diffrax-tsit5", "diffrax-dopri8"}
    assert {name for name, k in points.items() if k} == {"henon-rk4"} | (extras & set(points))
    assert points["henon-rk4"] == DEFAULT_CHECK_POINTS
    assert check_points_for(_UncheckedDop853()) == DEFAULT_CHECK_POINTS
    assert check_points_for(nsbench.get_integrator("moreau-jean")) == 0  # events inferred: no state checked


def test_a_crossing_pair_inside_one_step_is_located_by_the_integrators_own_check():
    """The loose dop853 run of 2-DOF case 3 steps over block 1's stick near t = 25.68 when only its step ends
    are looked at (tests/cli/test_cli.py): checked at DEFAULT_CHECK_POINTS states it ends 'event missed',
    unchecked it ends 'success' with events missing. With its per-step check it finds the stick: the
    sequence of the reference (heyoka's Taylor method in extended precision on this cubic problem, an
    independent method whose event detection isolates every root of a guard on each step), with no
    check point."""
    from nsbench.engine import DEFAULT_CHECK_POINTS

    problem = nsbench.get_problem("two-dof", case=3)
    loose = {"rtol": 1e-6, "atol": 1e-8}
    tight = nsbench.simulate(problem, "reference", 40.0).events
    default = nsbench.simulate(problem, _UncheckedDop853(**loose), 40.0)
    explicit = nsbench.simulate(problem, _UncheckedDop853(**loose), 40.0, check_points=DEFAULT_CHECK_POINTS)
    unchecked = nsbench.simulate(problem, _UncheckedDop853(**loose), 40.0, check_points=0)
    assert default.status is Status.EVENT_MISSED and default.t_final == explicit.t_final
    assert unchecked.ok and len(unchecked.events) < len(tight)
    between = tight[(tight["t"] > default.events["t"].iloc[-1]) & (tight["t"] <= default.t_final)]
    assert ("stick", 1) in list(zip(between["kind"], between["block"]))
    checked = nsbench.simulate(problem, "scipy-dop853", 40.0, options=loose)
    assert checked.ok and checked.counters.extra["check_reruns"] >= 1
    assert list(zip(checked.events["kind"], checked.events["block"])) == list(zip(tight["kind"], tight["block"]))
    # the tolerance of the loose run (1e-6) over t <= 40 bounds its event times against the reference's
    assert np.abs(checked.events["t"].to_numpy() - tight["t"].to_numpy()).max() < 1e-4


def test_run_gives_the_buffers_simulate_makes_its_frames_of(case2):
    from nsbench.engine import prepare, run

    grid = np.linspace(0.0, 40.0, 81)
    sec = [peaks(case2)]
    res = nsbench.simulate(case2, "exact", 40.0, t_eval=grid, sections=sec)
    integ = nsbench.get_integrator("exact")
    prepare(case2, integ)
    rec = run(case2, integ, 40.0, t_eval=grid, sections=sec)
    assert rec.ok and rec.checked_steps and rec.check_points == 0 and rec.crossings_checked
    ev = res.events
    np.testing.assert_array_equal(rec.events.t, ev["t"].to_numpy())
    np.testing.assert_array_equal(rec.events.block, ev["block"].to_numpy())
    assert [case2.event_kinds[k] for k in rec.events.kind] == list(ev["kind"])
    np.testing.assert_array_equal(rec.events.y, ev[list(case2.state_names)].to_numpy())
    assert [case2.mode_name(tuple(m)) for m in rec.events.mode] == list(ev["mode"])
    np.testing.assert_array_equal(rec.hits.t, res.sections["t"].to_numpy())
    np.testing.assert_array_equal(rec.dense.t, grid)
    np.testing.assert_array_equal(rec.dense.y, res.trajectory[list(case2.state_names)].to_numpy())
    assert rec.n_events_total == len(ev) and rec.counters.n_events == len(ev) and not rec.stopped


def test_check_points_stay_out_of_the_dense_record_and_a_repeated_time_keeps_its_rows(case2):
    from nsbench.engine import prepare, run

    integ = _UncheckedDop853()
    prepare(case2, integ)
    times = np.array([1.0, 2.5, 2.5, 7.0])
    rec = run(case2, integ, 8.0, t_eval=times)
    assert rec.check_points == 3001 and not rec.checked_steps and rec.crossings_checked
    np.testing.assert_array_equal(rec.dense.t, times)
    np.testing.assert_array_equal(rec.dense.y[1], rec.dense.y[2])
    bare = run(case2, integ, 8.0, t_eval=times, check_points=0)
    # the same steps with or without the check points' dense states: the same states at the requested times
    np.testing.assert_array_equal(bare.dense.y, rec.dense.y)
    # four requested times are no check: only the integrator's own or the engine's check points count
    assert not bare.crossings_checked and not run(case2, integ, 8.0, check_points=0).crossings_checked


def test_run_hands_the_core_what_simulate_hands_it(monkeypatch):
    """Every command runs a problem under simulate's defaults: the same budgets, the storm span scaled by
    the problem's time scale (a sweep point once got 1e-9 absolute), the same check points."""
    import nsbench.engine as engine

    p = nsbench.get_problem("two-dof", case=1, dimensional=True, k1=0.01)
    assert p.time_scale == 10.0
    seen = []

    def spy(*args, **kwargs):
        seen.append(kwargs)
        return run_hybrid(*args, **kwargs)

    run_hybrid = engine.run_hybrid
    monkeypatch.setattr(engine, "run_hybrid", spy)
    for integ in (nsbench.get_integrator("exact"), _UncheckedDop853()):
        seen.clear()
        nsbench.simulate(p, integ, 30.0)
        engine.prepare(p, integ)
        engine.run(p, integ, 30.0)
        a, b = seen[-2], seen[-1]
        assert a["zeno_span"] == b["zeno_span"] == 1e-8
        for key in ("max_steps", "max_events", "zeno_events", "accumulation", "t0", "mode"):
            assert a[key] == b[key], key
        np.testing.assert_array_equal(a["t_eval"], b["t_eval"])  # the check points of each integrator
        assert a["t_eval"].size == (0 if integ.capabilities.checks_steps else 3001)


@pytest.mark.parametrize(
    "kwargs, fragment",
    [
        (dict(t_end=-1.0), "must be greater than t0"),
        (dict(t_end=1.0, y0=[0.0]), "needs 4 states"),
        (dict(t_end=1.0, mode=(0,)), "has 1 entries"),
        (dict(t_end=1.0, max_steps=0), "max_steps = 0"),
        (dict(t_end=1.0, check_points=1), "check_points = 1"),
        (dict(t_end=1.0, sections=[StateSection("s", (1.0, 0.0, 0.0))]), "3 coefficients"),
        (dict(t_end=1.0, stop_kind="bounce"), "stop_kind 'bounce'"),
    ],
)
def test_run_checks_its_input_as_simulate_does(case1, kwargs, fragment):
    from nsbench.engine import prepare, run

    integ = nsbench.get_integrator("exact")
    prepare(case1, integ)
    with pytest.raises(nsbench.ConfigError, match=re.escape(fragment)):
        run(case1, integ, **kwargs)


def test_run_refuses_the_core_only_controls_to_a_whole_system_method(case1):
    from nsbench.engine import prepare, run

    integ = nsbench.get_integrator("moreau-jean")
    prepare(case1, integ)
    assert run(case1, integ, 5.0).ok
    with pytest.raises(nsbench.ConfigError, match="a run with stop_kind, stop_count needs an event-driven"):
        run(case1, integ, 5.0, stop_kind="slip", stop_count=1)
