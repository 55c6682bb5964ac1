"""``woodpecker``: Glocker's woodpecker toy against an independent 40-digit event-driven solution."""

from __future__ import annotations

import numpy as np
import pytest

import nsbench
from nsbench.errors import ConfigError
from nsbench.problems.woodpecker import DEFAULTS
from nsbench.testing import parametrize_with_checks
from tests.testing.test_conformance import BUILTINS
from tests.problems import woodpecker_mp

#: The span of the comparison (problem units: 30 bird swing times, 0.52 s, three cycles and 32 events).
SPAN = 30.0
#: The 40-digit reference is exact to far below double rounding; exact rounds its state to double at each
#: event and its defective modes use the matrix exponential (measured 3.4e-12 over 60 units); 1e-10 is the
#: issue's bound.
BOUND = 1e-10


@pytest.fixture(scope="module")
def mp_events():
    p = nsbench.get_problem("woodpecker")
    z0 = list(p.to_si(0.0, p.initial_state())[1])
    return woodpecker_mp.solve(DEFAULTS, z0, SPAN * p.units.time, step=p.units.time / 100)


@pytest.mark.parametrize("integrator", ["exact", "reference", "exact-mp", "ofapi"])
def test_the_run_meets_the_independent_40_digit_solution(integrator, mp_events):
    p = nsbench.get_problem("woodpecker")
    ev = nsbench.simulate(p, integrator, SPAN).events
    ref = [(e.kind, e.contact + 1, e.mode) for e in mp_events]
    assert list(zip(ev["kind"], ev["block"], ev["mode"])) == ref
    t_ref = np.array([float(e.t) for e in mp_events]) / p.units.time
    assert np.abs(ev["t"].to_numpy() - t_ref).max() <= BOUND
    # the states after each event (SI in the reference), in the problem's units
    y_ref = np.array([[float(x) for x in e.z[:6]] for e in mp_events]).T
    y_si = p.to_si(ev["t"].to_numpy(), ev[list(p.state_names)].to_numpy().T)[1]
    scale = np.abs(y_ref).max(axis=1, keepdims=True)
    assert (np.abs(y_si - y_ref) / scale).max() <= BOUND


def test_the_cycle_is_glockers_mechanism():
    """Per cycle: the sleeve jams, breaks away, leaves the pole, hits it tilted the other way, the beak pecks,
    the sleeve slides up and leaves, hits the first tilt and slides down until it jams again."""
    run = nsbench.simulate(nsbench.get_problem("woodpecker"), "exact", 60.0)
    kinds = list(run.events["kind"])
    cycle = ["stick", "slip", "release", "impact", "peck", "impact", "release", "impact", "impact"]
    assert kinds[: 2 * len(cycle)] == cycle * 2
    sticks = run.events["t"][run.events["kind"] == "stick"].to_numpy()
    periods = np.diff(sticks)
    assert np.all(periods > 8.0) and np.all(periods < 8.6)  # about 0.146 s: 8.3 swing times
    assert run.events["y"].iloc[-1] < run.events["y"].iloc[0]  # it climbs down the pole


def test_free_flight_conserves_energy():
    """Between events in the free mode only the spring and gravity act: the energy after an event equals the
    energy at the next, the state there taken by the matrix exponential of the free mode (``scipy``: about
    1e-13 relative over an arc of a few swing times, hence the bound)."""
    from scipy.linalg import expm

    p = nsbench.get_problem("woodpecker")
    ev = nsbench.simulate(p, "exact", 30.0).events
    a, b0, _, _ = p.linear_form((0,))
    aug = np.zeros((7, 7))
    aug[:6, :6], aug[:6, 6] = a, b0
    checked = 0
    for k in range(len(ev) - 1):
        if ev["mode"].iloc[k] != "free":
            continue
        after = ev[list(p.state_names)].iloc[k].to_numpy()
        before = (expm(aug * (ev["t"].iloc[k + 1] - ev["t"].iloc[k])) @ np.append(after, 1.0))[:6]
        e0, e1 = p.energy(after), p.energy(before)
        assert abs(e1 - e0) <= 1e-11 * max(1.0, abs(e0))
        checked += 1
    assert checked >= 10


def test_dimensional_runs_the_same_motion_in_si():
    scaled = nsbench.get_problem("woodpecker")
    si = nsbench.get_problem("woodpecker", dimensional=True)
    a = nsbench.simulate(scaled, "exact", 20.0).events
    b = nsbench.simulate(si, "exact", 20.0 * scaled.units.time).events
    assert list(a["kind"]) == list(b["kind"])
    # two roundings of the coefficients (the unit conversion): event times agree to a few ulps times the
    # sensitivity of the cycle (measured 2e-13)
    assert np.abs(a["t"].to_numpy() * scaled.units.time - b["t"].to_numpy()).max() <= 1e-10 * scaled.units.time


def test_bad_parameters_and_starts_are_refused():
    with pytest.raises(ConfigError, match="Painleve"):
        nsbench.get_problem("woodpecker", mu=40.0)
    with pytest.raises(ConfigError, match="beyond the sleeve's clearance"):
        nsbench.get_problem("woodpecker", phiM_0=-0.2)
    with pytest.raises(ConfigError, match="beak into the pole"):
        nsbench.get_problem("woodpecker", phiS_0=0.2)
    with pytest.raises(ConfigError, match="r0"):
        nsbench.get_problem("woodpecker", r0=0.004)
    with pytest.raises(ConfigError, match="e_beak"):
        nsbench.get_problem("woodpecker", e_beak=0.0)
    p = nsbench.get_problem("woodpecker", phiM_0=-(0.0031 - 0.0025) / 0.0058 * (1 + 1e-12))
    assert p.initial_state()[1] == -p.theta  # within 1e-9 of the limit: put on it


@parametrize_with_checks(["exact", "reference", "ofapi", "scipy-radau", "heyoka"], problem="woodpecker")
def test_conformance_on_the_woodpecker(integrator, check):
    check(integrator)


@pytest.mark.slow
@parametrize_with_checks(BUILTINS, problem="woodpecker")
def test_builtin_conformance_on_the_woodpecker(integrator, check):
    """Every built-in integrator: runs the checks, or is refused at setup with its reason."""
    check(integrator)
