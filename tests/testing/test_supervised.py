"""The kit in supervised workers (:mod:`nsbench.testing._supervised`): each step announced under its limit."""

from __future__ import annotations

from nsbench.testing import CHECKS, first_call_cost
from nsbench.testing._supervised import is_plugin, supervised_checks
from tests.bench import _integrators as faulty


def test_the_first_call_announces_its_setup_and_its_calls():
    # a worker gives the set-up its own limit: first_call_cost says when each step starts
    seen: list[str] = []
    cost = first_call_cost("henon-rk4", stage=seen.append)
    assert seen == ["integrator set-up", "first call"]
    assert cost.call == "advance" and cost.first > 0 and cost.second > 0


def test_a_crash_costs_its_own_check_and_the_others_still_run():
    from nsbench import registry
    from nsbench.integrators import get_integrator

    registry.register("integrators", faulty.Crashing.name, faulty.Crashing)
    try:
        integ = get_integrator(faulty.Crashing.name)
        assert is_plugin(integ) and not is_plugin(get_integrator("henon-rk4"))
        checks = [c for c in CHECKS if c.name in ("protocol", "config-round-trip", "inputs-not-mutated")]
        first, results = supervised_checks(integ, {}, checks, {"name": "two-dof"}, 60.0, 120.0)
    finally:
        registry.unregister("integrators", faulty.Crashing.name)
    assert first == "crashed (exit code 3) in first call"
    assert [(r.check, r.status) for r in results] == [
        ("protocol", "failed"),
        ("inputs-not-mutated", "failed"),
        ("config-round-trip", "passed"),
    ]
    assert results[0].message == "crashed (exit code 3) in check protocol"
    assert results[1].message == "crashed (exit code 3) in check inputs-not-mutated"
