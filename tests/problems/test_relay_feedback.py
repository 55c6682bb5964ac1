"""``relay-feedback``: crossing, Filippov sliding and exits, against an independent piecewise-linear solution."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.linalg import expm
from scipy.optimize import brentq

import nsbench
from nsbench.errors import ConfigError, UnsupportedProblemError


def _by_hand(p, count, span=20.0, h=1e-3):
    """The first ``count`` events, mode by mode, written out from the equations independently of the law:
    each mode's flow is ``expm`` of its augmented matrix; a guard's first zero is bracketed on a grid of
    step ``h`` and refined by Brent's method from the mode's start (the flow is never chained across it)."""
    a, b, c = p.A, p.B, p.C
    cb = float(c @ b)
    ca = c @ a
    a_slide = a - np.outer(b, ca) / cb
    x, t = p.initial_state().astype(float), 0.0
    y = float(c @ x)
    mode = "u+" if y < 0 else "u-" if y > 0 else "slide"
    events = []
    while len(events) < count:
        if mode == "slide":
            m, f = a_slide, np.zeros(3)
            guards = [lambda z: 1.0 + (ca @ z) / cb, lambda z: 1.0 - (ca @ z) / cb]  # 1 - u_eq, 1 + u_eq
        else:
            m, f = a, (b if mode == "u+" else -b)
            sign = -1.0 if mode == "u+" else 1.0
            guards = [lambda z, s=sign: s * float(c @ z)]
        aug = np.zeros((4, 4))
        aug[:3, :3], aug[:3, 3] = m, f
        z0 = np.append(x, 1.0)
        step = expm(aug * h)
        z, s_prev, found = z0.copy(), 0.0, None
        for k in range(1, int(span / h) + 1):
            z = step @ z
            for q, g in enumerate(guards):
                if g(z[:3]) < 0.0:
                    found = (q, brentq(lambda s: g((expm(aug * s) @ z0)[:3]), s_prev, k * h, xtol=1e-15))
                    break
            if found:
                break
            s_prev = k * h
        q, s = found
        x, t = (expm(aug * s) @ z0)[:3], t + s
        if mode == "slide":
            kind, mode = "exit", ("u+" if q == 0 else "u-")
        else:
            cax = float(ca @ x)
            if cax - cb > 0.0:
                new = "u-"
            elif cax + cb < 0.0:
                new = "u+"
            else:
                new = "slide"
            kind = "slide" if new == "slide" else "cross"
            mode = new
        events.append((t, kind))
    return events


@pytest.mark.parametrize("lam", [0.02, 0.06])
def test_exact_meets_the_events_of_an_independent_piecewise_linear_solution(lam):
    # lam = 0.02: the default, a symmetric orbit that slides; lam = 0.06: one that crosses without sliding
    p = nsbench.get_problem("relay-feedback", lam=lam)
    res = nsbench.simulate(p, "exact", 40.0)
    assert res.ok, res.message
    hand = _by_hand(p, 10)
    assert list(res.events["kind"].iloc[:10]) == [k for _, k in hand]
    # both are double-precision closed forms; the hand one restarts from each event's rounded state
    np.testing.assert_allclose(res.events["t"].to_numpy()[:10], [t for t, _ in hand], rtol=0, atol=1e-11)


def test_the_default_orbit_is_symmetric_and_slides():
    p = nsbench.get_problem("relay-feedback")
    ev = nsbench.simulate(p, "exact", 700.0).events
    late = ev[ev["t"] > 600.0]  # the transient has died out to rounding by then (1.5e-7 left at t = 300)
    assert set(late["kind"]) == {"slide", "exit"}
    slides = late[late["kind"] == "slide"][["x1", "x2", "x3"]].to_numpy()
    # consecutive slides are mirror images (x -> -x), the symmetry of the relay system
    np.testing.assert_allclose(slides[1:], -slides[:-1], atol=1e-9)
    # while sliding, |u_eq| = |C A x| < 1 (C B = 1): the entry point is inside the sliding region
    assert np.all(np.abs(slides @ (p.C @ p.A)) < 1.0)


@pytest.mark.parametrize(
    "name, bound", [("ofapi", 1e-11), ("scipy-radau", 1e-6), ("scipy-dop853", 1e-6), ("henon-rk4", 1e-6)]
)
def test_other_integrators_find_the_same_dozens_of_events(name, bound):
    p = nsbench.get_problem("relay-feedback")
    ref = nsbench.simulate(p, "reference", 60.0).events
    assert len(ref) >= 40
    res = nsbench.simulate(p, name, 60.0)
    assert res.ok, res.message
    assert list(res.events["kind"]) == list(ref["kind"])
    assert np.abs(res.events["t"].to_numpy() - ref["t"].to_numpy()).max() <= bound


@pytest.mark.parametrize(
    "params, message",
    [
        ({"lam": 0}, "real pole lam must be > 0"),
        ({"omega": -1}, "natural frequency omega must be > 0"),
        ({"rho": 0}, "zero frequency rho must be > 0"),
        ({"gain": 1}, "unknown parameter 'gain'"),
        ({"sigma": float("inf")}, "finite"),
    ],
)
def test_bad_parameters_are_refused(params, message):
    with pytest.raises(ConfigError, match=message):
        nsbench.get_problem("relay-feedback", **params)


def test_integrators_without_a_form_for_it_refuse_at_setup():
    p = nsbench.get_problem("relay-feedback")
    for name in ("cvode-bdf", "ida"):
        with pytest.raises(
            UnsupportedProblemError, match=r"blocks on a belt \(the friction oscillators' formulation\) only"
        ):
            nsbench.get_integrator(name).setup(p)


@pytest.mark.parametrize("lam", [0.02, 0.06])
@pytest.mark.parametrize("name", ["heyoka", "heyoka-q"])
def test_heyoka_through_the_symbolic_form_gives_exacts_events(name, lam):
    # crossings, slides and exits of the sliding (0.02) and the crossing (0.06) orbit; both integrators
    # locate each root in their own precision: measured 7.1e-15 and 0 against exact
    p = nsbench.get_problem("relay-feedback", lam=lam)
    want = nsbench.simulate(p, "exact", 60.0).events
    got = nsbench.simulate(p, name, 60.0).events
    assert len(got) >= 20 and list(got["kind"]) == list(want["kind"])
    assert np.abs(got["t"].to_numpy() - want["t"].to_numpy()).max() <= 1e-12


def test_the_crossing_orbit_solved_in_closed_form_is_the_one_the_simulation_settles_on():
    from nsbench.problems.relay_feedback import symmetric_orbit

    p = nsbench.get_problem("relay-feedback", lam=0.06)
    ev = nsbench.simulate(p, "exact", 800.0).events
    up = ev[(ev["t"] > 700.0) & (ev["x2"] > 0.0)].iloc[-1]
    x2, x3, period = symmetric_orbit(p, (1.0, 1.5, 5.0))
    # the half-period equations' solution and the settled simulation agree to the rounding of both
    assert abs(up["x2"] - x2) <= 1e-12 and abs(up["x3"] - x3) <= 1e-12
    crossings = ev[ev["t"] > 700.0]["t"].to_numpy()
    assert np.abs(np.diff(crossings) - period / 2).max() <= 1e-11


def test_sliding_appears_where_the_crossing_orbit_reaches_the_sliding_region():
    from nsbench.problems.relay_feedback import sliding_bifurcation

    lam, x3, period = sliding_bifurcation((0.05, 1.6, 5.3))
    assert lam == pytest.approx(0.0486891614, abs=1e-9)  # the value the docs state (computed, not published)
    # 0.1 % either side, the orbit the simulation settles on slides (below) or only crosses (above)
    below = nsbench.simulate(nsbench.get_problem("relay-feedback", lam=lam * (1 - 1e-3)), "exact", 3000.0).events
    above = nsbench.simulate(nsbench.get_problem("relay-feedback", lam=lam * (1 + 1e-3)), "exact", 3000.0).events
    assert set(below[below["t"] > 2900.0]["kind"]) == {"slide", "exit"}
    assert set(above[above["t"] > 2900.0]["kind"]) == {"cross"}


def test_the_bench_certifies_the_closed_form_reference_per_event():
    from nsbench.bench.reference import candidates, compute_reference

    p = nsbench.get_problem("relay-feedback", lam=0.06)
    ref = compute_reference(p.config(), candidates(["exact", "reference"]), 0.0, 60.0, 10)
    assert ref.ok and ref.name == "exact" and "exact-mp" in ref.certify_note
    assert set(ref.events["kind"]) == {"cross", "slide", "exit"} and ref.certainty <= 1e-13


@pytest.mark.parametrize(
    ("case", "several"),
    [("siconos-sliding", False), ("siconos-multisliding", True), ("piiroinen-kuznetsov", None)],
)
def test_published_cases_settle_on_the_orbits_their_sources_describe(case, several):
    """Siconos labels its sets 'limit cycles with sliding' and 'multi-sliding periods'; Piiroinen and
    Kuznetsov's set carries no label here. Each settles on a symmetric periodic orbit that slides."""
    from nsbench.periodic import HybridFlow, find_orbit
    from nsbench.problems.relay_feedback import CASE_SOURCES, CASES

    p = nsbench.get_problem("relay-feedback", case=case)
    assert {k: p.parameters[k] for k in CASES[case]} == CASES[case] and case in CASE_SOURCES
    orbit = find_orbit(HybridFlow(p), transient=200.0, window=100.0)
    kinds = [e.kind for e in orbit.events]
    half = len(kinds) // 2
    assert set(kinds) == {"slide", "exit"} and len(kinds) == 2 * half
    # x -> -x maps each half of the orbit onto the other (the relay system's symmetry)
    first = np.array([e.y for e in orbit.events[:half]])
    second = np.array([e.y for e in orbit.events[half:]])
    assert np.max(np.abs(first + second)) <= 1e-9
    if several is not None:
        assert (kinds.count("slide") > 2) == several  # more than one sliding segment per half period


def test_an_unknown_case_names_the_allowed_ones():
    with pytest.raises(ConfigError, match="siconos-sliding"):
        nsbench.get_problem("relay-feedback", case="dibernardo")
