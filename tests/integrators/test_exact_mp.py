"""``exact-mp`` against independent solutions: a 32-digit closed form, heyoka-q, an mpmath 1-DOF closed form.

Event times are compared as ``t + t_lo`` (the compensated time every arc
returns; the event log keeps only ``t``), recorded by a thin subclass that
watches ``advance``. Never against ``exact-mp`` itself, except the digits test
(two precisions of the same method must agree to the coarser one).
"""

from __future__ import annotations

import mpmath
import numpy as np
import pandas as pd
import pytest

import nsbench
from nsbench.errors import ConfigError, UnsupportedProblemError
from nsbench.integrators.base import ArcRequest
from nsbench.integrators.exact_mp import ExactMP
from nsbench.sections import level_crossing, peaks, stroboscopic
from nsbench.testing import parametrize_with_checks
from tests.mp_reference import stored_events

#: The ill-conditioned forced 2-DOF point: double rounding moves its event times by ~3e-9 over tau 300.
ILL = {"case": 2, "F": 0.517, "Omega": 0.767, "omega_r": 7.2, "v0": 0.314, "r_f": 0.81}
SPAN = 300.0
CTX = mpmath.MPContext()  # the tests' own precision: the global mpmath context is left alone
CTX.dps = 50


def recording(cls):
    """A subclass of integrator ``cls`` that records ``(t, t_lo)`` of every arc that ends at an event."""

    class Recording(cls):
        def advance(self, request):
            arc = super().advance(request)
            if arc.fired is not None:
                self.stops[float(arc.t)] = float(arc.t_lo)
            return arc

    Recording.__name__ = f"Recording{cls.__name__}"
    return Recording


def run(cls, problem, t_end: float = SPAN, **options):
    """``(result, event times t + t_lo as mpf)`` of one simulation."""
    integ = recording(cls)(**options)
    integ.stops = {}
    res = nsbench.simulate(problem, integ, t_end)
    assert res.ok, res.message
    times = [CTX.fadd(t, integ.stops.get(t, 0.0), exact=True) for t in res.events["t"]]
    return res, times


def same_sequence(a: pd.DataFrame, b: pd.DataFrame) -> bool:
    return list(zip(a["kind"], a["block"])) == list(zip(b["kind"], b["block"]))


def max_abs(times_a, times_b) -> mpmath.mpf:
    return max(abs(x - y) for x, y in zip(times_a, times_b))


# ---------------------------------------------------------------------- 1. the 32-digit closed form
@pytest.mark.parametrize(
    "case, model", [(1, "coefficients"), (1, "linear-form"), (2, "coefficients"), (2, "linear-form")]
)
def test_matches_the_32_digit_closed_form_over_300(case, model):
    # tests/mp_reference.py: 32-digit arithmetic, times stored with 30 significant digits (rounding
    # <= 5e-30 relative), the modes from problem.linear_form, which is exactly model="linear-form"
    # (and the same problem as "coefficients" when the masses are 1, as here). Measured: 5e-28
    # absolute at t ~ 300, 1.7e-30 relative; 1e-27 relative leaves a factor 500, still 1e11 below
    # double resolution.
    res, times = run(ExactMP, nsbench.get_problem("two-dof", case=case), model=model)
    ref = stored_events(case)
    assert same_sequence(res.events, ref)
    rel = max(abs(t - CTX.mpf(r)) / max(1, abs(t)) for t, r in zip(times, ref["t"]))
    assert rel <= 1e-27, CTX.nstr(rel, 5)


# ---------------------------------------------------------------------- 2. the ill-conditioned point
def test_ill_conditioned_point_against_quad_taylor_and_double_exact():
    hy = pytest.importorskip("heyoka")
    if getattr(hy, "real128", None) is None:  # pragma: no cover - depends on the heyoka build
        pytest.skip("this heyoka build has no real128")
    from nsbench.integrators.heyoka_ import HeyokaQuad

    problem = nsbench.get_problem("two-dof", **ILL)

    mp_res, mp_times = run(ExactMP, problem)
    q_res, q_times = run(HeyokaQuad, problem, tol=1e-30)
    assert len(mp_res.events) > 150
    assert same_sequence(mp_res.events, q_res.events)
    # heyoka-q solves the same problem (its coefficients) with quad rounding (1e-34) and tol 1e-30 per
    # step; the case amplifies an early change ~1e6-fold by the end: ~1e-24. Measured 1.7e-23.
    assert max_abs(mp_times, q_times) <= 1e-18
    # double exact solves linear_form's problem: compare with exact-mp on that same problem, so that
    # only exact's rounding shows. Measured 3.4e-9 (the largest event-time error over the run).
    lf_res, lf_times = run(ExactMP, problem, model="linear-form")
    exact = nsbench.simulate(problem, "exact", SPAN).events
    assert same_sequence(exact, lf_res.events)
    exact_err = max_abs([CTX.mpf(t) for t in exact["t"]], lf_times)
    assert exact_err > 1e-9  # 1e4 times the double resolution of t ~ 300: double cannot certify here
    assert max_abs(mp_times, q_times) < 1e-12 * exact_err


# ---------------------------------------------------------------------- 3. the 1-DOF closed form
def slip_phase(c, k, m, fs, s, x0, v0):
    """``m x'' + c x' + k x = -fs s`` from ``(x0, v0)`` (underdamped, mp): ``(x(u), v(u))``."""
    a = c / (2 * m)
    wd = CTX.sqrt(k / m - a * a)
    xe = -fs * s / k
    amp_c = x0 - xe
    amp_s = (v0 + a * amp_c) / wd

    def x(u):
        return xe + CTX.exp(-a * u) * (amp_c * CTX.cos(wd * u) + amp_s * CTX.sin(wd * u))

    def v(u):
        return CTX.exp(-a * u) * (
            (amp_s * wd - a * amp_c) * CTX.cos(wd * u) - (a * amp_s + amp_c * wd) * CTX.sin(wd * u)
        )

    return x, v


def first_rise_to(v, level, step=CTX.mpf("0.02")):
    """First ``u > 0`` where ``v`` rises through ``level`` (``v < level`` just after 0)."""
    lo = step / 1000
    while True:
        hi = lo + step
        if v(hi) >= level:
            return CTX.findroot(lambda u: v(u) - level, (lo, hi), solver="anderson")
        lo = hi


def one_dof_closed_form(problem, t_end: float):
    """Events ``[(kind, t)]`` of the standard 1-DOF stick-slip run, from MODEL.md with the problem's doubles."""
    co = problem.coefficients
    c, k, m, fs, fr, v0 = (CTX.mpf(float(x)) for x in (co.c[0], co.k[0], co.m[0], co.fs[0], co.fr[0], co.v0))
    t, x, v = CTX.zero, CTX.zero, CTX.zero
    events = []
    while True:
        # slip- until the velocity reaches the belt speed again
        xs, vs = slip_phase(c, k, m, fs, -1, x, v)
        u = first_rise_to(vs, v0)
        t, x = t + u, xs(u)
        if t > t_end:
            return events
        assert abs(c * v0 + k * x) <= fr, "the standard scenario never reverses"
        events.append(("stick", t))
        # stick: R = c v0 + k x grows with the belt until it reaches the static limit
        dt = (fr - c * v0 - k * x) / (k * v0)
        t, x, v = t + dt, x + v0 * dt, v0
        if t > t_end:
            return events
        events.append(("slip", t))


def test_one_dof_stick_slip_against_its_closed_form():
    problem = nsbench.get_problem("one-dof")
    ref = one_dof_closed_form(problem, 120.0)
    res, times = run(ExactMP, problem, 120.0)
    assert list(res.events["kind"]) == [kind for kind, _ in ref]
    assert len(ref) > 25
    # the closed form at 50 digits, exact-mp at 40, compared through t + t_lo (~32 digits)
    assert max(abs(a - b) / max(1, b) for a, (_, b) in zip(times, ref)) <= 1e-28


@pytest.mark.parametrize("overshoot", ["1e-9", "1e-13", "-1e-13"])
def test_grazing_crossing_is_found_or_correctly_absent(overshoot):
    # A slip- arc whose velocity maximum passes v0 by `overshoot` 3.3 time units after the start: the
    # guard v0 - v touches zero within ~1e-6 of the maximum (or misses it by 1e-13). Start from
    # doubles, the reference from those same doubles (mp closed form).
    problem = nsbench.get_problem("one-dof")
    co = problem.coefficients
    c, k, m, fs, v0 = (CTX.mpf(float(x)) for x in (co.c[0], co.k[0], co.m[0], co.fs[0], co.v0))
    v_max = v0 + CTX.mpf(overshoot)
    x_max = (fs - c * v_max) / k  # v' = 0 at the maximum
    xs, vs = slip_phase(c, k, m, fs, -1, x_max, v_max)
    y0 = np.array([float(xs(CTX.mpf("-3.3"))), float(vs(CTX.mpf("-3.3")))])
    xs, vs = slip_phase(c, k, m, fs, -1, CTX.mpf(y0[0]), CTX.mpf(y0[1]))
    integ = ExactMP()
    integ.setup(problem)
    mode = (-1,)
    arc = integ.advance(ArcRequest(problem=problem, mode=mode, t0=0.0, y0=y0, t_end=5.0, guards=problem.guards(mode)))
    assert arc.status.ok
    u_max = CTX.findroot(lambda u: CTX.diff(vs, u), CTX.mpf("3.3"))
    if CTX.mpf(overshoot) < 0:
        assert vs(u_max) < v0 and arc.fired is None and arc.t == 5.0
        return
    root = CTX.findroot(lambda u: vs(u) - v0, (u_max - CTX.mpf("0.01"), u_max), solver="anderson")
    assert arc.fired == 0
    assert abs(CTX.fadd(arc.t, arc.t_lo, exact=True) - root) <= 1e-28


# ---------------------------------------------------------------------- 4. the conformance kit
@parametrize_with_checks([ExactMP()])
def test_conformance(integrator, check):
    check(integrator)


# ---------------------------------------------------------------------- 5. digits
def test_thirty_and_sixty_digits_agree_on_case_1():
    problem = nsbench.get_problem("two-dof", case=1)
    res30, t30 = run(ExactMP, problem, digits=30)
    res60, t60 = run(ExactMP, problem, digits=60)
    assert same_sequence(res30.events, res60.events)
    assert max_abs(t30, t60) <= 1e-25  # 30 digits at t <= 300 resolve ~1e-28; measured below that


# ---------------------------------------------------------------------- 6. refusals
@pytest.mark.parametrize("value", [5, 19, 201, "x", 30.5, None])
def test_bad_digits_are_refused_naming_the_option(value):
    with pytest.raises(ConfigError, match="digits"):
        ExactMP(digits=value)


def test_unknown_model_is_refused():
    with pytest.raises(ConfigError, match="model"):
        ExactMP(model="closed-form")


def test_cubic_problems_are_refused_at_setup():
    with pytest.raises(UnsupportedProblemError, match="linear problems only"):
        ExactMP().setup(nsbench.get_problem("two-dof", case=3))


# ---------------------------------------------------------------------- the rest of the protocol
def test_sections_and_trajectory_match_exact():
    problem = nsbench.get_problem("two-dof", case=2)
    sections = [
        peaks(problem, 1),
        peaks(problem, 2),
        level_crossing(problem, "x2", 1.0),
        level_crossing(problem, "v1", 0.0, 1),
        stroboscopic(problem),
    ]
    grid = np.linspace(0.0, 60.0, 601)
    ref = nsbench.simulate(problem, "exact", 60.0, sections=sections, t_eval=grid)
    res = nsbench.simulate(problem, "exact-mp", 60.0, sections=sections, t_eval=grid)
    assert res.ok and len(res.sections) == len(ref.sections) > 20
    assert list(res.sections["section"]) == list(ref.sections["section"])
    names = list(problem.state_names)
    assert np.abs(res.sections[["t", *names]].to_numpy() - ref.sections[["t", *names]].to_numpy()).max() < 1e-12
    assert np.abs(res.trajectory[names].to_numpy() - ref.trajectory[names].to_numpy()).max() < 1e-12


def test_global_mpmath_precision_is_untouched():
    before = mpmath.mp.prec
    nsbench.simulate(nsbench.get_problem("two-dof", case=2), ExactMP(digits=80), 5.0)
    assert mpmath.mp.prec == before


def test_a_set_up_instance_pickles_as_its_configuration():
    # bench workers receive integrators by pickle; mp numbers of the private context do not pickle
    import pickle

    problem = nsbench.get_problem("two-dof", case=2)
    integ = ExactMP(digits=30)
    first = nsbench.simulate(problem, integ, 20.0)
    again = pickle.loads(pickle.dumps(integ))
    assert again.config() == integ.config()
    assert nsbench.simulate(problem, again, 20.0).events.equals(first.events)


# ---------------------------------------------------------------------- 7. the whole hybrid run in mp
#: The complete chattering set of issue 48 (every period ends stuck on the stop after a chattering sequence).
CHATTER = {"zeta": 0.0, "w": 4.2, "sigma": -0.25, "r": 0.5, "F": 1.0}


def test_the_whole_hybrid_run_in_mp_matches_an_independent_solution():
    # tests/impact_reference.py (60 digits, closed-form flights, its own root finder and Zeno tail,
    # written without this code) against mp_hybrid.hybrid_run at 40 digits, resets and accumulations
    # in mp. The run's accumulations are accepted at a tail estimate of 1e-24 t; measured 1.1e-24 at
    # the sticks, 1e-30 elsewhere: 1e-22 leaves a factor 100 and is 1e6 below a double's resolution.
    from nsbench.integrators.mp_hybrid import hybrid_run
    from nsbench.model.streaks import pair_events
    from tests.impact_reference import impact_oscillator_events

    p = nsbench.get_problem("impact-oscillator", **CHATTER)
    mine = hybrid_run(p, 10.0)
    truth = impact_oscillator_events(p, 10.0)
    pairs, stop = pair_events(
        [(p.event_kinds[e.code], 1) for e in mine],
        [e.accumulation_error is not None for e in mine],
        [(e.kind, 1) for e in truth],
        [e.err is not None for e in truth],
    )
    assert stop is None and sum(e.kind == "stick" for e in truth) == 2
    assert max(abs(mine[i].t - truth[j].t) for i, j in pairs) <= 1e-22
    for i, j in pairs:  # the accumulations' own estimates cover their error
        if mine[i].accumulation_error is not None:
            assert abs(mine[i].t - truth[j].t) <= mine[i].accumulation_error


def test_the_law_runs_as_plain_python_on_mp_numbers():
    # the resets of the mp run are the law's own transition, run on mpmath numbers: on doubles it must
    # give what the compiled law gives, and on mp numbers keep their precision
    from nsbench.integrators.mp_hybrid import python_law

    p = nsbench.get_problem("impact-oscillator", **CHATTER)
    law = python_law(p)
    compiled = p.transition((0,), p.guards((0,))[0], 1.3, np.array([-0.25, 0.7]))
    mode, y, fresh = [0], [-0.25, 0.7], [False]
    code = law["transition"](list(p.data.p), mode, 0, 0, 1.3, y, fresh)
    assert (p.event_kinds[code], tuple(mode), y) == (compiled.kind, compiled.mode, compiled.y.tolist())
    y_mp = [CTX.mpf(-0.25), CTX.mpf(1) / 3]
    law["transition"]([CTX.mpf(float(v)) for v in p.data.p], [0], 0, 0, CTX.mpf("1.3"), y_mp, [False])
    assert y_mp[1] == -CTX.mpf("0.5") / 3  # -r v in 50 digits, not a double
