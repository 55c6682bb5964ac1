"""The whole-run protocol: heyoka running the event loop itself (``loop = 'native'``) against its per-arc path.

The native run calls the core's compiled steps (:mod:`nsbench.model.native`) from heyoka's event
callbacks, so it must give what the per-arc path gives: the same event sequences, the same
statuses and stops, and (the arithmetic being the same Taylor method) the same times to a few
ulp. The independent values are ``exact``'s (closed-form flow, event times polished in
double-double) on the piecewise-linear cases; on the cubic cases, heyoka-q's per-arc run.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import nsbench
from nsbench.errors import ConfigError
from nsbench.hybrid.run import run_hybrid
from nsbench.sections import peaks
from tests.conftest import conditioning_of, exact_events, max_time_error, precision_bound, same_sequence

EPS = {"heyoka": float(np.finfo(float).eps), "heyoka-ld": float(np.finfo(np.longdouble).eps), "heyoka-q": 1.93e-34}


def _run(name, problem, t_end=300.0, loop="auto", **kwargs):
    return nsbench.simulate(problem, nsbench.get_integrator(name, loop=loop), t_end, **kwargs)


def test_the_path_is_chosen_recorded_and_printed():
    p = nsbench.get_problem("two-dof", case=1)
    native = _run("heyoka", p, 30.0)
    assert native.loop == "native" and native.loop_note == ""
    assert "loop        native" in native.summary()
    forced = _run("heyoka", p, 30.0, loop="per-arc")
    assert forced.loop == "per-arc" and forced.loop_note == "loop = 'per-arc'"
    assert "loop        per-arc (loop = 'per-arc')" in forced.summary()
    assert forced.integrator["options"]["loop"] == "per-arc"  # in the config: bench rows and suites compare both
    assert nsbench.simulate(p, "exact", 30.0).loop == "kernel"
    assert nsbench.simulate(p, "scipy-dop853", 30.0).loop == "per-arc"
    assert nsbench.simulate(p, "moreau-jean", 30.0, options={"h": 1e-3}).loop == "whole-system"


@pytest.mark.parametrize("name", ["heyoka-ld", "heyoka-q"])
def test_the_extended_precisions_run_per_arc_unless_asked(name):
    # the core's step between native arcs takes times and states as doubles: by default heyoka-ld and
    # heyoka-q keep their precision on the per-arc path, and say why; loop = 'native' still runs natively
    p = nsbench.get_problem("two-dof", case=1)
    auto = _run(name, p, 30.0)
    assert auto.ok and auto.loop == "per-arc" and "works in doubles" in auto.loop_note, auto.loop_note
    assert _run(name, p, 30.0, loop="native").loop == "native"


def test_a_bad_or_impossible_loop_is_refused_in_one_line():
    with pytest.raises(ConfigError, match="option loop = 'compiled' is not allowed"):
        nsbench.get_integrator("heyoka", loop="compiled")
    relay = nsbench.get_problem("relay-feedback")
    auto = _run("heyoka", relay, 30.0)  # the per-arc path, which says why
    assert auto.ok and auto.loop == "per-arc" and "tangent to the switching surface" in auto.loop_note


@pytest.mark.parametrize("name", list(EPS))
def test_problems_written_symbolically_run_natively_with_a_selector_per_mode(name):
    """``henon-heiles`` and ``bouncing-ball``: one integrator whose runtime parameters select the mode. The ball's
    impacts are known in closed form; its flights are polynomials, so one Taylor step spans several of the late
    ones (a guard zero where a step starts would hide them from heyoka: the native events are nudged, see
    ``_heyoka_native.NUDGE``); the Zeno rule brings it to rest (a jump of the time inside the run)."""
    ball = nsbench.get_problem("bouncing-ball")
    res, arcs = _run(name, ball, 10.0, loop="native"), _run(name, ball, 10.0, loop="per-arc")
    assert res.ok and res.loop == "native" and same_sequence(res.events, arcs.events)
    impacts = res.events[res.events["kind"] == "impact"]["t"].to_numpy()
    exact = ball.impact_times(len(impacts))
    # t ~ 4: an ulp is 8.9e-16; each flight's root on an exact quadratic polynomial: 1e-14 covers 9 flights' rounding
    # the Zeno rule's estimate decides the depth (4 impacts before the rest at its default tolerance)
    assert len(impacts) >= 4 and np.max(np.abs(impacts - exact)) <= 1e-14
    assert res.events["kind"].iloc[-1] == "rest" and res.mode_final == arcs.mode_final
    # the rest at the closed form's accumulation time, within the rule's logged estimate of its error
    rest = res.events.iloc[-1]
    assert abs(rest["t"] - ball.accumulation_time()) <= rest["accumulation_error"] <= 1e-10
    hh = nsbench.get_problem("henon-heiles")
    res, arcs = _run(name, hh, 100.0, loop="native"), _run(name, hh, 100.0, loop="per-arc")
    assert res.ok and res.loop == "native" and len(res.events) > 10 and same_sequence(res.events, arcs.events)
    # a smooth field: both paths locate the crossings of x = 0 on the same Taylor polynomials; the chaotic
    # orbit's conditioning over t = 100 is well below 1e3, so 1e-10 is a loose bound for tol = eps
    assert max_time_error(res.events, arcs.events) <= 1e-10


@pytest.mark.parametrize("case", [1, 2])
@pytest.mark.parametrize("name", list(EPS))
def test_native_runs_give_exacts_events_on_the_linear_cases(name, case):
    # 1e-12: a few ulp of t ~ 300 (6e-14 each) for the event location, plus the Taylor method's error at
    # tol = eps over ~300 steps amplified by the case's conditioning (precision_bound: at most 4e-12 in
    # double; seen 5.7e-14). The extended precisions meet the same bound with room.
    p = nsbench.get_problem("two-dof", case=case)
    res, arcs = _run(name, p, loop="native"), _run(name, p, loop="per-arc")
    ref = exact_events("two-dof", case)
    assert res.ok and res.loop == "native", res.message
    assert same_sequence(res.events, ref) and same_sequence(res.events, arcs.events)
    assert max_time_error(res.events, ref) <= 1e-12


@pytest.mark.parametrize("case", [3, 4])
@pytest.mark.parametrize("name", ["heyoka", "heyoka-ld"])
def test_native_runs_give_the_per_arc_sequence_on_the_cubic_cases(name, case):
    p = nsbench.get_problem("two-dof", case=case)
    res, arcs, quad = _run(name, p, loop="native"), _run(name, p, loop="per-arc"), _run("heyoka-q", p, loop="per-arc")
    assert res.ok and res.loop == "native" and arcs.ok and quad.ok
    assert same_sequence(res.events, arcs.events) and same_sequence(res.events, quad.events)
    bound = precision_bound(quad.events["t"], conditioning_of("two-dof", case), EPS[name], res.counters.nsteps)
    assert max_time_error(res.events, quad.events) <= bound


@pytest.mark.parametrize(
    "name, params",
    [("one-dof", {"case": 2}), ("chain", {"case": 2, "n": 5}), ("block-on-ground", {"fs": 0.8, "c": 0.05})],
)
def test_native_runs_on_the_other_friction_problems(name, params):
    p = nsbench.get_problem(name, **params)
    res, arcs = _run("heyoka", p), _run("heyoka", p, loop="per-arc")
    assert res.ok and res.loop == "native" and len(res.events) > 5
    assert same_sequence(res.events, arcs.events)
    if p.is_linear:  # the bound of the linear cases above; the chain's conditioning is of the same order
        ref = nsbench.simulate(p, "exact", 300.0).events
        assert same_sequence(res.events, ref) and max_time_error(res.events, ref) <= 1e-12


def test_the_long_run_of_the_issue_names_the_native_path_and_gives_1094_events():
    """2-DOF case 1 over [0, 3000] with the default check points: 1094 events (exact's), more than the event
    buffer's first 1024 rows (it grows in the middle of heyoka's propagation) and 3001 checked states."""
    p = nsbench.get_problem("two-dof", case=1)
    ref = nsbench.simulate(p, "exact", 3000.0).events
    res, arcs = _run("heyoka", p, 3000.0), _run("heyoka", p, 3000.0, loop="per-arc")
    assert res.ok and res.loop == "native" and len(res.events) == 1094
    assert same_sequence(res.events, ref) and same_sequence(res.events, arcs.events)
    # chaining 1094 events over tau 3000: 2e-12 = 2 ulp of 3000 (4.5e-13 each) plus the Taylor error (seen 9.1e-13)
    assert max_time_error(res.events, ref) <= 2e-12


def test_more_arcs_than_the_log_holds_are_all_checked():
    """Over [0, 12000] with check points heyoka stops its propagation whenever 4096 arcs are logged for the
    missed-crossing check, checks them and goes on: the run is exact's all the same."""
    from nsbench.integrators._heyoka_native import LOG_CAPACITY

    p = nsbench.get_problem("two-dof", case=1)
    ref = nsbench.simulate(p, "exact", 12000.0, check_points=2001).events
    res = _run("heyoka", p, 12000.0, check_points=2001)
    assert len(ref) > LOG_CAPACITY
    assert res.ok and same_sequence(res.events, ref)


def test_double_zero_starts_fall_back_to_the_per_arc_path():
    """fs = fr: a slip starts on a double zero of its guard, where heyoka's own detection is not to be trusted
    (docs/core.md), so the automatic choice runs per arc, chosen from the parameters, and gives exact's
    sequence; the option still forces the native run, for comparison."""
    p = nsbench.get_problem("two-dof", case=2, r_f=1.0)
    ref = nsbench.simulate(p, "exact", 300.0).events
    auto = _run("heyoka", p)
    assert auto.ok and auto.loop == "per-arc" and "double zero" in auto.loop_note and "block 1, 2" in auto.loop_note
    assert same_sequence(auto.events, ref)
    assert _run("heyoka", p, 30.0, loop="native").loop == "native"


def test_leines_belt_gives_the_references_sequence_through_the_fallback():
    p = nsbench.get_problem("one-dof", case="leine")
    ref = nsbench.simulate(p, "reference", 300.0)
    for name in EPS:
        res = _run(name, p)
        # heyoka for the double zero; heyoka-ld and heyoka-q run per arc by default anyway (their precision)
        why = "double zero" if name == "heyoka" else "works in doubles"
        assert res.ok and res.loop == "per-arc" and why in res.loop_note, res.loop_note
        assert same_sequence(res.events, ref.events)


@pytest.fixture(scope="module")
def case2():
    p = nsbench.get_problem("two-dof", case=2)
    integs = {loop: nsbench.get_integrator("heyoka", loop=loop) for loop in ("native", "per-arc")}
    for integ in integs.values():
        integ.setup(p)
    return p, integs


def test_budgets_end_the_native_run_as_they_end_the_per_arc_one(case2):
    p, integs = case2
    for kwargs, what in (({"max_events": 50}, "event budget of 50 events"), ({"max_steps": 100}, "")):
        native, arcs = (nsbench.simulate(p, integs[k], 300.0, **kwargs) for k in ("native", "per-arc"))
        assert native.status == arcs.status == nsbench.Status.BUDGET_EXHAUSTED
        assert what in native.message and len(native.events) == len(arcs.events)
        assert native.loop == "native" and same_sequence(native.events, arcs.events)
    storm = nsbench.simulate(p, nsbench.get_integrator("heyoka", loop="native"), 300.0, zeno_events=2, zeno_span=50.0)
    per_arc = nsbench.simulate(p, integs["per-arc"], 300.0, zeno_events=2, zeno_span=50.0)
    assert storm.status == per_arc.status == nsbench.Status.EVENT_STORM
    assert len(storm.events) == len(per_arc.events)


def test_the_stop_rules_of_sweeps_and_lyapunov_exponents_stop_where_the_per_arc_path_does(case2):
    """The core's stop rules (the ``stop_count``-th event of a kind, the ``hit_stop``-th section hit) and the
    transient (``record_from``, ``hit_from``) through ``run_hybrid``, which the sweeps, Lyapunov exponents and
    periodic orbits call: heyoka's native run stops at the same event or hit, in the same state."""
    p, integs = case2
    runs = {
        k: run_hybrid(p, integ, 400.0, record_from=300.0, stop_kind="slip", stop_count=1) for k, integ in integs.items()
    }
    a, b = runs["native"], runs["per-arc"]
    assert a.loop == "native" and a.stopped and b.stopped and a.mode == b.mode and a.n_events == b.n_events
    # the same Taylor method and event location: the stop time within a few ulp of t ~ 300
    assert abs(a.t - b.t) <= 1e-12 and np.allclose(a.y, b.y, rtol=0, atol=1e-12)
    kwargs = dict(record_from=300.0, sections=[peaks(p)], hit_from=300.0, hit_stop=20)
    runs = {k: run_hybrid(p, integ, 600.0, **kwargs) for k, integ in integs.items()}
    a, b = runs["native"], runs["per-arc"]
    assert a.stopped and b.stopped and a.n_hits == b.n_hits == 20 and a.n_events == b.n_events
    assert np.allclose(a.records.ht[:20], b.records.ht[:20], rtol=0, atol=1e-12)
    # a peak is where v2 = 0: heyoka's located state there, not the per-arc path's rounding, within 1e-12
    assert np.allclose(a.records.hy[:20], b.records.hy[:20], rtol=0, atol=1e-12) and a.t == a.records.ht[19]


def test_dense_states_come_from_heyokas_own_steps(case2):
    p, integs = case2
    grid = np.linspace(0.0, 300.0, 1001)
    native = nsbench.simulate(p, integs["native"], 300.0, t_eval=grid)
    exact = nsbench.simulate(p, "exact", 300.0, t_eval=grid)
    assert native.loop == "native" and len(native.trajectory) == len(grid)
    cols = list(p.state_names)
    # the states on the Taylor polynomials of heyoka's steps: errors of order tol = eps times the conditioning
    # of the state (events 1e-13 apart move a velocity by at most 1e-13 * |a| ~ 1e-13); 1e-11 is far above
    diff = np.abs(native.trajectory[cols].to_numpy() - exact.trajectory[cols].to_numpy())
    assert diff.max() <= 1e-11
    assert (
        native.trajectory[list(p.mode_columns)].to_numpy() == exact.trajectory[list(p.mode_columns)].to_numpy()
    ).all()


def test_the_missed_crossing_check_reads_a_stretch_arc_by_arc(case1):
    """:func:`nsbench.model.native.missed_over`, the core's check on states an integrator stores a stretch at a
    time: a velocity guard ``-(v1 - v0)`` of slip- turning wrong at ``t = 2`` and back at ``t = 3`` is a
    crossing stepped over, reported at the first wrong state; a stick mode has no such guard."""
    from nsbench.integrators._heyoka_native import _scratch
    from nsbench.model import abi, native

    v0 = float(case1.coefficients.v0)
    times = np.arange(5.0)
    states = np.zeros((5, 4))
    states[:, 1] = [0.0, v0 - 0.01, v0 + 0.01, v0 - 0.01, 0.0]
    dense = abi.Dense(times, states)
    scratch = _scratch(np.zeros(4), np.zeros(2, np.int64), case1.max_guards)
    slip = np.array([-1, -1], np.int64)
    assert native.missed_over(case1.data, scratch, dense, slip, 0, 5) == 2.0
    assert math.isnan(native.missed_over(case1.data, scratch, dense, slip, 0, 3))  # never back on its side
    stuck = np.array([0, -1], np.int64)  # block 1 stuck: its guards are the static limits, never wrong here
    assert math.isnan(native.missed_over(case1.data, scratch, dense, stuck, 0, 5))


def test_the_time_inside_heyoka_is_measured_apart_from_the_callbacks(case2):
    p, integs = case2
    res = nsbench.simulate(p, integs["native"], 300.0, check_points=0)
    assert 0.0 < res.integrator_time < res.wall_time
    assert res.counters.nsteps > 0 and res.counters.extra["taylor_coefficients"] % res.counters.nsteps == 0


def test_a_native_binding_that_does_not_load_gives_one_line_and_the_per_arc_path():
    """An integrator whose own loop needs a library that fails to load (SUNDIALS' shared libraries) says so
    in ``native_refusal`` by raising: the core runs it per arc and the note names the failure in one line."""
    from nsbench.integrators.heyoka_ import Heyoka

    class Unloadable(Heyoka):
        def native_refusal(self, problem, forced=False):
            raise OSError("libsundials_cvode.so.7: cannot open shared object file\nsecond line")

    p = nsbench.get_problem("two-dof", case=1)
    res = nsbench.simulate(p, Unloadable(), 30.0)
    assert res.ok and res.loop == "per-arc"
    assert (
        res.loop_note
        == "its own event loop is unavailable (OSError: libsundials_cvode.so.7: cannot open shared object file)"
    )
    with pytest.raises(ConfigError, match="loop = 'native' cannot run two-dof: its own event loop is unavailable"):
        nsbench.simulate(p, Unloadable(loop="native"), 30.0)


GOLDEN = Path(__file__).parents[1] / "data" / "event_logs_before_the_hybrid_model.csv.gz"


def _golden_keys():
    logs = pd.read_csv(GOLDEN, dtype={"state": str})
    keys = logs[["problem", "case", "n"]].drop_duplicates().itertuples(index=False)
    return [pytest.param(k.problem, int(k.case), int(k.n), id=f"{k.problem}-{k.n}-{k.case}") for k in keys]


@pytest.mark.parametrize("problem, case, n", _golden_keys())
def test_heyokas_sequences_on_the_golden_logs_are_the_per_arc_paths(problem, case, n):
    """The stored golden event logs (``tests/hybrid/test_event_logs.py``) over [0, 300]: heyoka on the automatic
    path (native unless refused) gives their sequence of kinds, blocks and modes, the per-arc path's, and where
    the log holds ``exact`` (the piecewise-linear cases) its times within 1e-12 (the bound of the linear cases
    above: a few ulp of t ~ 300 for the location plus the Taylor error at tol = eps times the conditioning)."""
    logs = pd.read_csv(GOLDEN, dtype={"state": str})
    logs = logs[(logs["problem"] == problem) & (logs["case"] == case) & (logs["n"] == n)]
    golden = logs[logs["integrator"] == ("exact" if (logs["integrator"] == "exact").any() else "reference")]
    p = nsbench.get_problem(problem, case=case, **({"n": n} if problem == "chain" else {}))
    res, arcs = _run("heyoka", p), _run("heyoka", p, loop="per-arc")
    assert res.ok and arcs.ok, (res.message, arcs.message)
    assert res.loop == "native" or (res.loop == "per-arc" and res.loop_note), res.loop_note
    assert same_sequence(res.events, golden) and list(res.events["mode"]) == list(golden["mode"])
    assert same_sequence(res.events, arcs.events) and list(res.events["mode"]) == list(arcs.events["mode"])
    if golden["integrator"].iloc[0] == "exact":
        assert max_time_error(res.events, golden) <= 1e-12
