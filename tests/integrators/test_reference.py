"""``reference`` and its certification: exact vs heyoka-q, both against a 32-digit closed form."""

from __future__ import annotations

import mpmath as mp
import numpy as np
import pytest

import nsbench
from tests.conftest import conditioning_of, max_time_error, precision_bound, same_sequence
from tests.integrators.runs import two_dof_run
from tests.mp_reference import closed_form_events, max_error, stored_events


@pytest.mark.parametrize("case", [1, 2])
def test_exact_and_quad_taylor_agree_to_1e13_over_300(case):
    exact, quad = two_dof_run("exact", case), two_dof_run("heyoka-q", case)
    assert exact.ok and quad.ok
    assert same_sequence(exact.events, quad.events)
    assert max_time_error(exact.events, quad.events) <= 1e-13


@pytest.mark.parametrize("case", [1, 2])
def test_quad_taylor_matches_the_32_digit_closed_form(case):
    assert max_error(two_dof_run("heyoka-q", case).events, stored_events(case)) <= 1e-13


@pytest.mark.parametrize("case, delegate", [(1, "exact"), (2, "exact"), (3, "heyoka-q"), (4, "heyoka-q")])
def test_reference_is_exact_for_linear_and_quad_taylor_for_cubic_problems(case, delegate):
    ref = two_dof_run("reference", case)
    assert ref.ok
    own_counter = {"exact": "roots", "heyoka-q": "taylor_coefficients"}[delegate]  # whose counters it has
    assert own_counter in ref.counters.extra
    direct = two_dof_run(delegate, case)
    assert same_sequence(ref.events, direct.events)
    assert max_time_error(ref.events, direct.events) <= (0.0 if delegate == "exact" else 1e-13)


@pytest.mark.parametrize("case", [3, 4])
def test_extended_precision_agrees_with_the_cubic_reference(case):
    # No closed form for cubic springs: a second precision (80-bit) is the check. kappa * eps_ld * steps
    # is about 2e-15, far below an ulp of t: the same doubles or neighbours (seen: the same doubles).
    ld, ref = two_dof_run("heyoka-ld", case), two_dof_run("reference", case)
    assert same_sequence(ld.events, ref.events)
    bound = precision_bound(
        ref.events["t"], conditioning_of("two-dof", case), float(np.finfo(np.longdouble).eps), ld.counters.nsteps
    )
    assert max_time_error(ld.events, ref.events) <= bound


def test_reference_config_round_trip():
    integ = nsbench.get_integrator("reference")
    assert integ.config() == {"name": "reference", "options": {}}
    assert nsbench.integrator_from_config(integ.config()).config() == integ.config()


@pytest.mark.slow
def test_stored_closed_form_regenerates():
    fresh = closed_form_events(1, t_end=20.0)
    stored = stored_events(1).iloc[: len(fresh)]
    assert list(fresh["kind"]) == list(stored["kind"])
    assert max(abs(mp.mpf(a) - mp.mpf(b)) for a, b in zip(fresh["t"], stored["t"])) < 1e-25
