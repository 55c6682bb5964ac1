"""Leine's belt oscillator (one-dof, case='leine': the weakening law): reference, four integrators, refusals.

Independent values: the slip arc of the limit cycle starts at ``x = fr / k = 1``,
``v = v0`` (the stick ends there) and was integrated with mpmath's Taylor-series
ODE solver at 30 digits (``mpmath.odefun``), its end ``v = v0`` found by
``mpmath.findroot``; the stick then lasts ``(1 - x_stick) / v0``.
:func:`test_the_cycle_constants_recomputed_in_mpmath` (slow) recomputes them.
"""

from __future__ import annotations

import numpy as np
import pytest

import nsbench
from nsbench.errors import UnsupportedProblemError
from tests.conftest import max_time_error, precision_bound, same_sequence

T_END = 300.0  # 51 events: the first stick, then 25 cycles of slip and stick
#: mpmath, 30 digits (see the module docstring)
SLIP_TIME = 4.29599952548015488335822954597
X_STICK = -0.541006353870084752709313998246
PERIOD = 12.0010312948305786469047995372
X_MAX, X_MIN = 1.13394467644165683997992964296, -0.555432690060231606322534964637


@pytest.fixture(scope="module")
def leine():
    return nsbench.get_problem("one-dof", case="leine")


@pytest.fixture(scope="module")
def reference(leine):
    return nsbench.simulate(leine, "reference", T_END)


@pytest.fixture(scope="module")
def kappa(leine, reference):
    from nsbench.bench.reference import conditioning

    value, note = conditioning(leine, nsbench.get_integrator("reference").config(), 0.0, T_END, reference.events)
    assert np.isfinite(value), note
    return value


def _cycle(events):
    kinds, t, x = events["kind"].to_numpy(), events["t"].to_numpy(), events["x1"].to_numpy()
    slips, sticks = t[kinds == "slip"], t[kinds == "stick"][1:]  # the first stick ends the transient
    return slips, sticks, x[kinds == "stick"][1:]


def test_reference_runs_quad_precision_and_gives_the_mpmath_cycle(leine, reference):
    integrator = nsbench.get_integrator("reference")
    integrator.setup(leine)
    assert integrator.delegate.name == "heyoka-q"  # a non-linear law: quad precision, not exact
    assert reference.ok and len(reference.events) == 51
    kinds = reference.events["kind"].tolist()
    assert kinds == ["stick"] + ["slip", "stick"] * 25
    slips, sticks, x_stick = _cycle(reference.events)
    # the cycle is reached at the first stick (the stick sets v = v0 exactly, the slip always starts at x = 1):
    # every cycle is the mpmath one, up to the rounding of the double event times (2 ulp of t ~ 300)
    ulp2 = 2 * np.spacing(T_END)
    np.testing.assert_allclose(sticks - slips, SLIP_TIME, rtol=0, atol=ulp2)
    np.testing.assert_allclose(np.diff(slips), PERIOD, rtol=0, atol=ulp2)
    np.testing.assert_allclose(x_stick, X_STICK, rtol=0, atol=4 * np.spacing(1.0))


def test_the_extremes_of_the_cycle(leine):
    from nsbench.sections import level_crossing

    res = nsbench.simulate(leine, "reference", 40.0, sections=[level_crossing(leine, "v1", 0.0, 0)])
    x = res.sections["x1"].to_numpy()
    np.testing.assert_allclose(x[0::2], X_MAX, rtol=0, atol=4 * np.spacing(1.0))
    np.testing.assert_allclose(x[1::2], X_MIN, rtol=0, atol=4 * np.spacing(1.0))


@pytest.mark.parametrize(
    "name, options",
    [
        ("heyoka", {"tol": 1e-14}),
        ("heyoka", {"tol": 1e-10}),
        ("scipy-dop853", {"rtol": 1e-12, "atol": 1e-14}),
        ("scipy-dop853", {"rtol": 1e-9, "atol": 1e-11}),
        ("cvode-bdf", {"rtol": 1e-9, "atol": 1e-11}),
    ],
)
def test_integrators_give_the_reference_sequence_within_their_tolerance(leine, reference, kappa, name, options):
    """Each step's relative error is at most the tolerance; amplified by the conditioning and summed over the
    steps (tests/conftest.precision_bound). Seen (kappa = 4.8): heyoka 5.7e-14 and 5.6e-11 against bounds
    3.5e-11 and 3.3e-7; dop853 2.5e-10 and 6.4e-7 (6.4e-9, 2.9e-6); CVODE-BDF 5.7e-6 (3.3e-5)."""
    res = nsbench.simulate(leine, name, T_END, options=options)
    assert res.ok, res.message
    assert same_sequence(res.events, reference.events)
    tol = options.get("tol", options.get("rtol"))
    bound = precision_bound(reference.events["t"], kappa, tol, res.counters.nsteps)
    assert max_time_error(res.events, reference.events) <= bound


def test_henon_rk4_converges_at_fourth_order(leine, reference):
    """A fixed-step RK4 with Henon's event step is of order 4: a step 4x shorter divides the switching-time
    errors by 4^4 = 256 (seen: 2.47e-7 -> 9.66e-10, 256x); at least half of that is asked."""
    errors = []
    for h in (0.01, 0.0025):
        res = nsbench.simulate(leine, "henon-rk4", T_END, options={"h": h})
        assert res.ok and same_sequence(res.events, reference.events)
        errors.append(max_time_error(res.events, reference.events))
    assert errors[1] <= errors[0] / 128 and errors[0] < 1e-6


@pytest.mark.parametrize("name", ["exact", "exact-mp"])
def test_the_closed_forms_refuse_a_nonlinear_law_with_the_reason(leine, name):
    with pytest.raises(UnsupportedProblemError, match="piecewise-linear problems only .* weakening friction law"):
        nsbench.get_integrator(name).setup(leine)
    stribeck = nsbench.get_problem("two-dof", case=2, law="stribeck", fk=0.5, vs=0.2)
    with pytest.raises(UnsupportedProblemError, match="stribeck friction law"):
        nsbench.get_integrator(name).setup(stribeck)


@pytest.mark.slow
def test_the_cycle_constants_recomputed_in_mpmath():
    mpmath = pytest.importorskip("mpmath")
    mp = mpmath.MPContext()
    mp.dps = 30
    v0, delta = mp.mpf("0.2"), mp.mpf(3)
    sol = mp.odefun(lambda t, y: [y[1], -y[0] + 1 / (1 + delta * (v0 - y[1]))], 0, [mp.mpf(1), v0])
    slip = mp.findroot(lambda t: sol(t)[1] - v0, (mp.mpf("4.2"), mp.mpf("4.4")), solver="anderson")
    x_stick = sol(slip)[0]
    assert abs(slip - mp.mpf(SLIP_TIME)) < 1e-15 and abs(x_stick - mp.mpf(X_STICK)) < 1e-15
    assert abs(slip + (1 - x_stick) / v0 - mp.mpf(PERIOD)) < 1e-14
    t_max = mp.findroot(lambda t: sol(t)[1], (mp.mpf("0.3"), mp.mpf("1.5")), solver="anderson")
    t_min = mp.findroot(lambda t: sol(t)[1], (mp.mpf("2.5"), mp.mpf("4.2")), solver="anderson")
    assert abs(sol(t_max)[0] - mp.mpf(X_MAX)) < 1e-15 and abs(sol(t_min)[0] - mp.mpf(X_MIN)) < 1e-15


def test_the_bench_certifies_the_reference_per_event(leine, reference):
    """The bench's certificate of a non-linear reference: heyoka-q at tol 1e-30 (another step sequence)."""
    from nsbench.bench.reference import certified_errors

    errors, note = certified_errors(leine, reference.events, 0.0, T_END, reference="reference")
    assert "heyoka-q" in note and errors.shape == (51,) and np.isfinite(errors).all()
    assert errors.max() <= 2 * np.spacing(T_END)


@pytest.mark.parametrize("name", ["reference", "heyoka", "scipy-dop853", "henon-rk4"])
def test_a_stuck_block_stays_stuck_until_the_static_limit(name):
    """Stick keeps its static limit under the weakening law: from x = 0.5 at the belt speed the block moves
    with the belt (x = 0.5 + 0.2 t) until the spring force reaches fr = 1, at t = 2.5 exactly."""
    problem = nsbench.get_problem("one-dof", case="leine", x1_0=0.5, v1_0=0.2)
    res = nsbench.simulate(problem, name, 3.0)
    assert res.ok and res.events["kind"].tolist() == ["slip"]
    assert res.events["t"].iloc[0] == pytest.approx(2.5, abs=1e-12)
