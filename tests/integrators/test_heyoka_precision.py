"""``heyoka-q`` keeps quad precision across events: against an independent real128 event-driven solver.

The independent solver below does not go through nsbench's hybrid core nor its
heyoka model: it writes the 2-DOF equations of MODEL.md out (cubes as
``x*x*x``, the forcing through cos/sin states), uses heyoka's real128
``taylor_adaptive`` with terminal events for the guards, and applies the
transition rules in real128. With ``round_events=True`` it rounds the
mechanical state to double after every event, which is what nsbench did before
its extended-precision integrators kept their own state across events.
"""

from __future__ import annotations


import numpy as np
import pytest

import nsbench

hy = pytest.importorskip("heyoka")
if getattr(hy, "real128", None) is None:  # pragma: no cover - depends on the heyoka build
    pytest.skip("this heyoka build has no real128", allow_module_level=True)

R128 = hy.real128

#: A forced cubic point (case 4, other parameters) whose event times amplify perturbations:
#: rounding the state to double at every event moves the event times by 1.2e-11 by tau = 300
#: (same event sequence), against about an ulp on case 4 itself.
SENSITIVE = {"case": 4, "v0": 0.323, "F": 0.755, "Omega": 0.897, "r_f": 0.553, "omega_r": 5.56}
SPAN = 300.0

_SOLVERS: dict = {}


def _solver(coeffs):
    """A real128 ``taylor_adaptive`` for the 2-DOF oscillator, mode and guard activations as parameters.

    Parameters: ``sig1, sig2`` (1 stuck), ``s1, s2`` (slip signs), ``av1, av2`` (velocity
    guards on), ``ar1, ar2`` (static-limit guards on). Terminal events, in order:
    ``v1 - v0, R1 - fr1, R1 + fr1, v2 - v0, R2 - fr2, R2 + fr2``.
    """
    key = coeffs
    if key in _SOLVERS:
        return _SOLVERS[key]
    (m1, m2), (c1, c2), (k1, k2), (h1, h2), (fs1, fs2), (fr1, fr2), F, w, v0 = (
        coeffs.m,
        coeffs.c,
        coeffs.k,
        coeffs.h,
        coeffs.fs,
        coeffs.fr,
        coeffs.F,
        coeffs.w,
        coeffs.v0,
    )
    x1, v1, x2, v2, cw, sw = hy.make_vars("x1", "v1", "x2", "v2", "cw", "sw")
    par = hy.par
    sig1, sig2, s1, s2, av1, av2, ar1, ar2 = (par[i] for i in range(8))

    def q(value):
        return hy.expression(R128(value))

    d = x1 - x2
    R1 = q(c1) * v1 + q(k1) * x1 + q(h1) * (x1 * x1 * x1) + q(k2) * d + q(h2) * (d * d * d)
    R2 = q(c2) * v2 - q(k2) * d - q(h2) * (d * d * d) - q(F) * cw
    one = q(1.0)
    sys = [
        (x1, sig1 * q(v0) + (one - sig1) * v1),
        (v1, (one - sig1) * (-R1 - q(fs1) * s1) / q(m1)),
        (x2, sig2 * q(v0) + (one - sig2) * v2),
        (v2, (one - sig2) * (-R2 - q(fs2) * s2) / q(m2)),
        (cw, -q(w) * sw),
        (sw, q(w) * cw),
    ]
    guards = [
        av1 * (v1 - q(v0)) + (one - av1),
        ar1 * (R1 - q(fr1)) + (one - ar1),
        ar1 * (R1 + q(fr1)) + (one - ar1),
        av2 * (v2 - q(v0)) + (one - av2),
        ar2 * (R2 - q(fr2)) + (one - ar2),
        ar2 * (R2 + q(fr2)) + (one - ar2),
    ]
    ta = hy.taylor_adaptive(
        sys,
        np.array([R128(0.0)] * 6),
        pars=np.array([R128(0.0)] * 8),
        fp_type=R128,
        t_events=[hy.t_event(g, fp_type=R128) for g in guards],
        tol=R128(1e-32),
        compact_mode=True,
    )

    def restoring(y, i):
        x1_, v1_, x2_, v2_, cw_ = y[0], y[1], y[2], y[3], y[4]
        d_ = x1_ - x2_
        if i == 0:
            return (
                R128(c1) * v1_ + R128(k1) * x1_ + R128(h1) * x1_ * x1_ * x1_ + R128(k2) * d_ + R128(h2) * d_ * d_ * d_
            )
        return R128(c2) * v2_ - R128(k2) * d_ - R128(h2) * d_ * d_ * d_ - R128(F) * cw_

    _SOLVERS[key] = (ta, restoring, (R128(fr1), R128(fr2)), R128(v0))
    return _SOLVERS[key]


def _event_index(outcome):
    """Index of the terminal event that stopped heyoka, or ``None`` (success, time limit, ...)."""
    v = int(outcome)
    if v >= 0:
        return v
    return -v - 1 if v > -(2**32) else None


def independent_events(problem, t_end: float, round_events: bool = False):
    """Event log ``[(t, kind, block)]`` of the standard run (rest at the origin), in real128."""
    ta, restoring, fr, v0 = _solver(problem.coefficients)
    zero, one = R128(0.0), R128(1.0)
    ta.dtime = (zero, zero)
    ta.state[:] = np.array([zero, zero, zero, zero, one, zero])
    ta.reset_cooldowns()
    sig, s = [0, 0], [-1, -1]  # both blocks slip- at rest (v = 0 < v0)
    events = []
    t_stop = R128(t_end)

    def set_pars(fresh=()):
        pars = [
            sig[0],
            sig[1],
            s[0],
            s[1],
            0 if (sig[0] or 0 in fresh) else 1,
            0 if (sig[1] or 1 in fresh) else 1,
            sig[0],
            sig[1],
        ]
        ta.pars[:] = np.array([R128(float(p)) for p in pars])

    def first_crossing(i, t_a, t_b):
        """First zero of ``s_i (v_i - v0)`` in ``(t_a, t_b]`` (it starts at 0 and turns positive)."""

        def g(t):
            return R128(s[i]) * (ta.update_d_output(t)[2 * i + 1] - v0)

        lo, positive = t_a, False
        for k in range(1, 65):
            t = t_a + (t_b - t_a) * R128(k) / R128(64)
            if g(t) > 0:
                lo, positive = t, True
            elif positive:
                hi = t
                for _ in range(200):  # bisection to the last bit of real128
                    mid = (lo + hi) / R128(2)
                    if not (lo < mid < hi):
                        break
                    if g(mid) > 0:
                        lo = mid
                    else:
                        hi = mid
                return hi
        return None

    while True:
        y = ta.state
        fresh = [i for i in (0, 1) if not sig[i] and y[2 * i + 1] == v0]
        fired = None
        if fresh:  # a slip that starts on its own surface: one step with that guard off, then look
            set_pars(fresh)
            t_a = ta.time
            outcome, _ = ta.step(t_stop - t_a)
            t_b = ta.time
            best = None
            for i in fresh:
                root = first_crossing(i, t_a, t_b)
                if root is not None and (best is None or root < best[0]):
                    best = (root, i)
            if best is not None:
                state = np.array(ta.update_d_output(best[0]), copy=True)
                ta.dtime = (best[0], zero)
                ta.state[:] = state
                fired = 3 * best[1]
            elif _event_index(outcome) is not None:
                fired = _event_index(outcome)
            elif t_b >= t_stop:
                return events
        if fired is None:
            set_pars()
            outcome = ta.propagate_until(t_stop)[0]
            fired = _event_index(outcome)
            if fired is None:
                assert outcome == hy.taylor_outcome.time_limit, outcome
                return events
        i, slot = divmod(fired, 3)
        y = np.array(ta.state, copy=True)
        y[2 * i + 1] = v0
        if slot == 0:
            r = restoring(y, i)
            if abs(r) <= fr[i]:
                sig[i], kind = 1, "stick"
            else:
                s[i], kind = (-1 if r > 0 else 1), "reverse"
        else:
            sig[i], s[i], kind = 0, (-1 if slot == 1 else 1), "slip"
        if round_events:
            for j in range(4):
                y[j] = R128(float(y[j]))
        hi, lo = ta.dtime
        ta.state[:] = y
        ta.reset_cooldowns()
        events.append((float(hi + lo), kind, i + 1))


def _compare(log, ref):
    """Same kinds and blocks, and the largest ``|dt| / max(1, t)``."""
    assert len(log) == len(ref)
    assert [(k, b) for _, k, b in log] == [(k, b) for _, k, b in ref]
    return max(abs(a[0] - b[0]) / max(1.0, abs(b[0])) for a, b in zip(log, ref))


def _nsbench_log(result):
    ev = result.events
    return list(zip(ev["t"].astype(float), ev["kind"].astype(str), ev["block"].astype(int)))


@pytest.fixture(scope="module")
def sensitive():
    problem = nsbench.get_problem("two-dof", **SENSITIVE)
    return problem, independent_events(problem, SPAN)


def test_rounding_the_state_at_events_is_far_from_real128(sensitive):
    # (a) the old behaviour, emulated: the state passes through a double at every event.
    problem, ref = sensitive
    assert len(ref) > 50
    rounded = independent_events(problem, SPAN, round_events=True)
    assert _compare(rounded, ref) > 1e-12  # measured: 1.24e-11


def test_heyoka_q_matches_real128_across_events(sensitive, monkeypatch):
    # (b) heyoka-q now keeps its real128 state between arcs: every event time within an ulp or so
    # (measured: equal to the independent real128 times rounded to double), and every arc after
    # the first continues from the kept state.
    from nsbench.integrators import heyoka_

    problem, ref = sensitive
    kept = heyoka_.HeyokaIntegrator._continued
    arcs = []
    monkeypatch.setattr(
        heyoka_.HeyokaIntegrator, "_continued", lambda self, request: arcs.append(kept(self, request)) or arcs[-1]
    )
    res = nsbench.simulate(problem, "heyoka-q", SPAN, options={"tol": 1e-30, "loop": "per-arc"})
    assert res.ok, res.message
    assert _compare(_nsbench_log(res), ref) <= 4e-16
    assert len(arcs) == len(ref) + 1 and arcs[0] is None
    assert all(a is not None for a in arcs[1:])


def test_heyoka_q_running_the_loop_itself_matches_real128_across_events(sensitive):
    # the native run never leaves real128 between events: the transition's changes (velocities set to
    # the belt's speed, a double) are written into its state, every other entry keeps its digits
    problem, ref = sensitive
    res = nsbench.simulate(problem, "heyoka-q", SPAN, options={"tol": 1e-30, "loop": "native"})
    assert res.ok and res.loop == "native", res.message
    assert _compare(_nsbench_log(res), ref) <= 4e-16


def test_reference_matches_real128_across_events(sensitive):
    problem, ref = sensitive
    res = nsbench.simulate(problem, "reference", SPAN)
    assert res.ok, res.message
    assert _compare(_nsbench_log(res), ref) <= 4e-16


def test_heyoka_ld_keeps_long_double_across_events(sensitive, monkeypatch):
    # (c) heyoka-ld keeps its long double state between arcs: every arc after the first continues
    # from the kept state, and that state holds bits a double cannot (so it never passed through one).
    from nsbench.bench.reference import conditioning
    from nsbench.integrators import heyoka_

    problem, ref = sensitive
    kept, states = heyoka_.HeyokaIntegrator._continued, []
    monkeypatch.setattr(
        heyoka_.HeyokaIntegrator, "_continued", lambda self, request: states.append(kept(self, request)) or states[-1]
    )
    res = nsbench.simulate(problem, "heyoka-ld", SPAN, options={"loop": "per-arc"})
    assert res.ok, res.message
    assert len(states) == len(ref) + 1 and states[0] is None and all(c is not None for c in states[1:])
    carried = np.concatenate([np.asarray(c[1]) for c in states[1:]])
    assert carried.dtype == np.longdouble
    assert (carried != carried.astype(float).astype(np.longdouble)).mean() > 0.5
    # The bound on the event times, from the arithmetic: heyoka-ld integrates at tol = eps_ld
    # (2^-63, its default: the precision's epsilon), so with the state never rounded to double at
    # events, every perturbation it makes is of relative size eps_ld (a few per Taylor step). The
    # case carries a perturbation of its state into its switching times amplified by at most its
    # conditioning kappa: the largest switching-time change per unit change of the start positions,
    # measured on the quad reference flow as `nsbench bench` measures it (a perturbation at the
    # start has the whole span to grow; later ones have less). So |dt| <= kappa * eps_ld, the
    # "floor" the bench applies to a long double solution (kappa = 4.8e7 here: bound 5.2e-12).
    # Seen: 4.8e-15 on an Intel Xeon, 2.7e-13 on an AMD EPYC (heyoka 7.13.1 and 7.13.2 alike; its
    # JIT targets the host CPU). On AMD the error grows smoothly, e-fold every ~22 time units, from
    # the last bit of a double at tau ~ 127 (no jump at any event): ulps of long double amplified.
    # For scale: rounding the state to double at every event gives 7.7e-12 here, and a double
    # solution's floor is 2048 times this bound.
    kappa, note = conditioning(
        problem,
        nsbench.get_integrator("reference").config(),
        0.0,
        SPAN,
        nsbench.simulate(problem, "reference", SPAN).events,
    )
    assert np.isfinite(kappa), note
    eps_ld = float(np.finfo(np.longdouble).eps)
    assert _compare(_nsbench_log(res), ref) <= kappa * eps_ld


def test_double_heyoka_never_carries_state(sensitive, monkeypatch):
    # The double path is unchanged: it never consults or keeps a carried state.
    from nsbench.integrators import heyoka_

    problem, _ = sensitive
    before = nsbench.simulate(problem, "heyoka", 60.0)

    def forbidden(*args, **kwargs):  # pragma: no cover - fails the test if reached
        raise AssertionError("the double heyoka took the extended-precision path")

    monkeypatch.setattr(heyoka_.HeyokaIntegrator, "_continued", forbidden)
    after = nsbench.simulate(problem, "heyoka", 60.0)
    assert after.ok and len(after.events) > 10
    assert before.events.equals(after.events)


def test_a_request_that_does_not_continue_starts_from_its_doubles(sensitive):
    # A new start (here: the first event's state perturbed) is not mistaken for a continuation.
    problem, _ = sensitive
    integ = nsbench.get_integrator("heyoka-q", tol=1e-30)
    integ.setup(problem)
    from nsbench.integrators.base import ArcRequest

    y0 = problem.initial_state()
    mode = problem.initial_mode(0.0, y0)
    first = integ.advance(ArcRequest(problem, mode, 0.0, y0, SPAN, problem.guards(mode)))
    assert first.fired is not None and integ._carry is not None
    y1 = first.y.copy()
    y1[0] += 1e-3
    assert (
        integ._continued(ArcRequest(problem, mode, first.t, y1, SPAN, problem.guards(mode), t0_lo=first.t_lo)) is None
    )
    y2 = first.y.copy()
    y2[1] = problem.coefficients.v0  # a velocity reset by a transition: continues, in real128
    carried = integ._continued(ArcRequest(problem, mode, first.t, y2, SPAN, problem.guards(mode), t0_lo=first.t_lo))
    assert carried is not None and carried[1][1] == R128(problem.coefficients.v0)


#: More forced cubic points (case 4, random within the sweep ranges, tau in [0, 300]) where the state
#: passing through a double at every event moved the event times by (relative to max(1, t)) 1.4e-4,
#: 2.2e-9 and 9.4e-11 (measured with the independent solver's round_events=True).
AMPLIFYING = [
    ({"v0": 0.39, "F": 0.679, "Omega": 0.777, "r_f": 0.488, "omega_r": 7.88}, 1e-5),
    ({"v0": 0.304, "F": 0.658, "Omega": 1.253, "r_f": 0.481, "omega_r": 7.28}, 1e-10),
    ({"v0": 0.281, "F": 0.394, "Omega": 0.903, "r_f": 0.512, "omega_r": 5.05}, 1e-11),
]


@pytest.mark.parametrize("params, rounded_off", AMPLIFYING)
def test_reference_gives_the_real128_event_times_where_rounding_at_events_is_far_off(params, rounded_off):
    # measured: bit-identical to the independent real128 times rounded to double at every event
    problem = nsbench.get_problem("two-dof", case=4, **params)
    ref = independent_events(problem, SPAN)
    assert _compare(independent_events(problem, SPAN, round_events=True), ref) > rounded_off
    res = nsbench.simulate(problem, "reference", SPAN)
    assert res.ok, res.message
    assert _compare(_nsbench_log(res), ref) <= 4e-16


def test_the_certified_error_bounds_the_reference_on_a_chaotic_point():
    # A point where a 1e-9 change of the start changes the event sequence (tau ~ 138): two quad solvers
    # (the independent one here, and heyoka-q at its epsilon) part by 2e-10 by tau = 300. The bench's
    # certified error (a third quad run, heyoka-q at tol 1e-30) must cover that at every event, and
    # the conditioning must say the case is beyond grading in double.
    from nsbench.bench.reference import candidates, compute_reference

    problem = nsbench.get_problem("two-dof", case=4, v0=0.357, F=0.897, Omega=1.093, r_f=0.543, omega_r=7.36)
    truth = independent_events(problem, SPAN)
    ref = compute_reference(problem.config(), candidates(["exact", "reference"]), 0.0, SPAN, 20)
    assert ref.ok and ref.name == "reference"
    log = _nsbench_log(type("R", (), {"events": ref.events})())
    assert [(k, b) for _, k, b in log] == [(k, b) for _, k, b in truth]
    dt = np.abs(np.array([a[0] for a in log]) - np.array([b[0] for b in truth]))
    cert = ref.events["certified_error"].to_numpy()
    assert dt.max() > 1e-12 and (dt <= cert).all()
    assert np.isinf(ref.conditioning) and "changes the event sequence" in ref.conditioning_note
