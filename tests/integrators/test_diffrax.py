"""``diffrax-*`` (JAX) against ``exact`` and the closed forms; its compilation is done in ``setup``.

Skipped with the reason where the extra ``[jax]`` is not installed. The first compilation of a shape
takes 20-50 s on the 2-core machine (JAX's disk cache shortens it in later processes), so these tests
share one integrator per method and problem shape. Bounds as in ``test_cyrk.py``: 100 ``rtol`` for a
run of a few hundred events, rounding plus the root finder's 1e-14 for the ball's quadratic flights.
"""

from __future__ import annotations

import time

import numpy as np
import pytest

import nsbench
from nsbench.errors import UnsupportedProblemError
from nsbench.integrators.diffrax_ import DiffraxTsit5
from tests.conftest import exact_events, max_time_error, same_sequence

REASON = DiffraxTsit5.unavailable()
needs_jax = pytest.mark.skipif(REASON is not None, reason=f"diffrax unavailable: {REASON}")
pytestmark = needs_jax


@pytest.mark.parametrize(
    "name, bound",
    [
        ("diffrax-tsit5", 1e-7),  # measured 4.1e-9
        # measured 2.6e-7 (at a stick, event 8; 1.2e-9 at rtol 1e-12): diffrax's Dopri8 locates events on its
        # interpolant, less accurate than its steps; cyrk-dop853 at the same rtol is within 6.1e-9
        ("diffrax-dopri8", 1e-6),
    ],
)
def test_exacts_sequence_on_the_forced_two_dof(name, bound):
    p = nsbench.get_problem("two-dof", case=2)
    integ = nsbench.get_integrator(name, rtol=1e-9, atol=1e-11)
    integ.setup(p)
    res = nsbench.simulate(p, integ, 300.0)
    ref = exact_events("two-dof", 2)
    assert res.ok, res.message
    assert same_sequence(res.events, ref)
    assert max_time_error(res.events, ref) <= bound
    assert res.counters.nfev > 0 and res.counters.nsteps > 0


def test_the_balls_impacts_match_the_closed_form():
    # a flight is a quadratic in time, which Tsit5 follows to rounding: measured 2.8e-14; bound 1e-11. How
    # many impacts precede the rest is the core's Zeno rule's (by the tail's accuracy): at least four
    p = nsbench.get_problem("bouncing-ball")
    res = nsbench.simulate(p, "diffrax-tsit5", 6.0, options={"rtol": 1e-12, "atol": 1e-14})
    assert res.ok, res.message
    impacts = res.events[res.events["kind"] == "impact"]["t"].to_numpy()
    assert list(res.events["kind"]) == ["impact"] * len(impacts) + ["rest"] and len(impacts) >= 4
    assert np.max(np.abs(impacts - p.impact_times(len(impacts)))) <= 1e-11
    assert abs(res.events["t"].iloc[-1] - p.accumulation_time()) <= 1e-9


def test_relay_sliding_events_against_exact():
    p = nsbench.get_problem("relay-feedback")
    ref = nsbench.simulate(p, "exact", 60.0)
    res = nsbench.simulate(p, "diffrax-dopri8", 60.0, options={"rtol": 1e-12, "atol": 1e-14})
    assert res.ok, res.message
    assert same_sequence(res.events, ref.events)
    # measured 5.6e-10 at rtol 1e-12 (Dopri8's interpolant, as on the two-dof: cyrk-vern7 has 1.7e-12)
    assert max_time_error(res.events, ref.events) <= 1e-8


def test_compilation_is_in_setup_and_reused_for_every_level():
    # the solve is compiled once per shape: after setup at one level, a run at another level (other
    # tolerances, the same shape) compiles nothing, so it takes a small part of the setup's time
    p = nsbench.get_problem("two-dof", case=1)
    first = nsbench.get_integrator("diffrax-tsit5", rtol=1e-6, atol=1e-8)
    first.setup(p)
    other = nsbench.get_integrator("diffrax-tsit5", rtol=1e-12, atol=1e-14)
    tic = time.perf_counter()
    other.setup(p)  # one short arc: nothing to compile
    again = time.perf_counter() - tic
    res = nsbench.simulate(p, other, 20.0)
    assert res.ok
    from nsbench.integrators import diffrax_

    shape = ("tsit5", p.n_states, p.max_guards, diffrax_.CHUNK)
    assert sum(1 for key in diffrax_._COMPILED if key == shape) == 1
    assert again < 5.0  # a warm arc: milliseconds; a compilation: 20-50 s


@pytest.mark.parametrize(
    "make, why",
    [
        (lambda: nsbench.get_problem("two-dof", case=4), "piecewise-linear"),
        (lambda: nsbench.get_problem("one-dof", case="leine"), "piecewise-linear"),
        (lambda: nsbench.get_problem("henon-heiles"), "piecewise-linear"),
    ],
)
def test_refuses_what_is_not_piecewise_linear_at_setup(make, why):
    with pytest.raises(UnsupportedProblemError, match=why):
        nsbench.get_integrator("diffrax-tsit5").setup(make())


def test_records_no_sections_and_says_so():
    p = nsbench.get_problem("two-dof", case=2)
    assert "no state sections" in nsbench.get_integrator("diffrax-tsit5").sections_refusal(p)
