"""The Jacobian of the hybrid flow (transition and saltation matrices) against finite differences."""

import numpy as np
import pytest

from nsbench import get_problem
from nsbench.periodic import HybridFlow
from nsbench.periodic.flow import free_components


def _fd(flow, t0, y0, mode, span, free, eps):
    cols = []
    for j in free:
        d = np.zeros_like(y0)
        d[j] = eps
        plus, minus = flow.run(t0, y0 + d, mode, span), flow.run(t0, y0 - d, mode, span)
        ref = flow.run(t0, y0, mode, span)
        # the perturbed runs must cross the same events, or the difference quotient is meaningless
        assert plus.pattern == ref.pattern == minus.pattern
        cols.append((plus.y - minus.y) / (2 * eps))
    return np.array(cols).T


@pytest.mark.parametrize(
    "case, params, tol",
    [
        (1, {}, 1e-6),  # both blocks stick at the start, then every event kind
        (1, {"v0": 0.17}, 1e-6),
        (2, {}, 1e-6),  # forced: time-dependent stick guards
        (3, {}, 1e-5),  # cubic springs: variational equations along each arc
    ],
)
def test_jacobian_matches_finite_differences(case, params, tol):
    problem = get_problem("two-dof", case=case, **params)
    flow = HybridFlow(problem)
    settled = flow.run(0.0, problem.initial_state(), problem.initial_mode(0.0, problem.initial_state()), 300.0)
    t0, y0, mode = 300.0, settled.y, settled.mode
    p = flow.run(t0, y0, mode, 20.0)
    assert len(p.events) >= 3
    free = free_components(problem, mode)
    jac = flow.jacobian(p)[:, free]
    # central differences: error ~ eps^2 * (third derivative) + rounding / eps, both far below tol
    fd = _fd(flow, t0, y0, mode, 20.0, free, 1e-6)
    assert np.max(np.abs(jac - fd)) <= tol * max(1.0, np.max(np.abs(fd)))


def test_stuck_start_has_no_velocity_unknown():
    problem = get_problem("two-dof", case=1)
    assert free_components(problem, (0, -1)).tolist() == [0, 2, 3]
    assert free_components(problem, (0, 0)).tolist() == [0, 2]


def test_a_flow_that_steps_over_a_crossing_fails_instead_of_giving_a_pass():
    """The flow runs through the engine with simulate's check: the loose dop853 run of 2-DOF case 3 that
    steps over block 1's stick near t = 25.68 (tests/test_engine.py) raises when the integrator does
    not check its own steps (simulate's check points catch it), and gives exact's events when it does.
    The wrong relay orbit of the docs came through this path with no check at all."""
    import dataclasses

    from nsbench import registry
    from nsbench.integrators.scipy_ import ScipyDOP853

    class Unchecked(ScipyDOP853):
        name = "test-flow-dop853-unchecked"
        check_steps = False
        capabilities = dataclasses.replace(ScipyDOP853.capabilities, checks_steps=False)

    p = get_problem("two-dof", case=3)
    y0 = p.initial_state()
    mode = p.initial_mode(0.0, y0)
    loose = {"rtol": 1e-6, "atol": 1e-8}
    registry.register("integrators", Unchecked.name, Unchecked)
    try:
        flow = HybridFlow(p, Unchecked.name, loose)
        with pytest.raises(ArithmeticError, match="event missed"):
            flow.run(0.0, y0, mode, 40.0)
        # a run that nothing checked (no check of the integrator's, no check points) is refused even where
        # it ends 'success' (the flow's runs never ask for that; a guard against a caller that would)
        from nsbench.engine import run
        from nsbench.periodic.flow import _require_ok

        bare = run(p, flow.integ, 40.0, check_points=0)
        assert bare.ok
        with pytest.raises(ArithmeticError, match="crossings unchecked"):
            _require_ok(bare)
    finally:
        registry.unregister("integrators", Unchecked.name)
    checked = HybridFlow(p, "scipy-dop853", loose).run(0.0, y0, mode, 40.0)
    ref = HybridFlow(p, "reference").run(0.0, y0, mode, 40.0)
    assert checked.pattern == ref.pattern
    # rtol 1e-6 over t <= 40 bounds the event times against the reference's
    assert max(abs(a.t - b.t) for a, b in zip(checked.events, ref.events)) < 1e-4
