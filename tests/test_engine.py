"""The hybrid engine: statuses, sections, trajectories, degenerate starts, integrator faults."""

from __future__ import annotations

import re

import numpy as np
import pytest

import nsbench
from nsbench import registry
from nsbench.integrators import ArcResult, Capabilities, Integrator
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


def test_a_plain_call_is_checked_for_crossings_stepped_over_by_default():
    """``simulate`` without ``t_eval`` checks its guards at DEFAULT_CHECK_POINTS states: the loose dop853 run
    of 2-DOF case 3 that steps over a stick (tests/cli/test_cli.py) ends 'event missed', not 'success';
    ``check_points=0`` is the unchecked run, which reports success with events missing."""
    from nsbench.engine import DEFAULT_CHECK_POINTS

    problem = nsbench.get_problem("two-dof", case=3)
    loose = {"rtol": 1e-6, "atol": 1e-8}
    default = nsbench.simulate(problem, "scipy-dop853", 40.0, options=loose)
    explicit = nsbench.simulate(problem, "scipy-dop853", 40.0, options=loose, check_points=DEFAULT_CHECK_POINTS)
    unchecked = nsbench.simulate(problem, "scipy-dop853", 40.0, options=loose, check_points=0)
    assert default.status.value == "event missed" and default.t_final == explicit.t_final
    assert unchecked.ok
    # the unchecked success is false: a run six orders tighter has a stick of block 1 after the loose run's
    # last event and before the checked run's end
    tight = nsbench.simulate(problem, "scipy-dop853", 40.0, options={"rtol": 1e-12, "atol": 1e-14}).events
    between = tight[(tight["t"] > default.events["t"].iloc[-1]) & (tight["t"] <= default.t_final)]
    assert ("stick", 1) in list(zip(between["kind"], between["block"]))
