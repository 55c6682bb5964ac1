"""moreau-jean's work counter: ``nfev`` counts the one-step problems it evaluates, never 0.

The expected counts follow from the algorithm, not from the counter: a step whose previous
stick/slip status is still consistent solves that one candidate; a step where it is not
(the status changes) re-tries the statuses of the enumeration, which for one block (stick,
slip+, slip-, pruned to the fewest changes) is two or three more candidates.
"""

from __future__ import annotations

import math

import numpy as np

from nsbench import simulate
from nsbench.integrators import get_integrator
from nsbench.integrators.whole import SystemRequest
from nsbench.problems import get_problem


def test_a_step_that_keeps_its_status_evaluates_one_one_step_problem():
    problem = get_problem("one-dof")
    # stuck on the belt all along (tests/integrators/test_moreau_jean.py): no status change, no enumeration
    run = simulate(problem, "moreau-jean", 8.0, y0=[0.3, problem.v0], options={"h": 1e-2})
    assert run.ok and len(run.events) == 0
    steps = math.ceil(8.0 / 1e-2 * (1 - 1e-12))
    assert run.counters.nsteps == steps
    assert run.counters.nfev == steps


def test_a_switching_step_evaluates_the_enumerations_candidates_too():
    problem = get_problem("one-dof")
    integ = get_integrator("moreau-jean", h=1e-2)
    integ.setup(problem)
    res = integ.integrate(SystemRequest(problem=problem, t0=0.0, y0=problem.initial_state(), t_end=20.0))
    steps = math.ceil(20.0 / 1e-2 * (1 - 1e-12))
    assert res.nsteps == steps
    # a step ending in another status is one whose previous status failed: the enumeration ran there
    switched = int(np.count_nonzero(np.any(res.modes[1:] != res.modes[:-1], axis=1)))
    assert switched > 0
    assert steps + 2 * switched <= res.nfev <= steps + 3 * switched
    # the engine passes the count on to the run's counters (the bench's nfev column)
    run = simulate(problem, "moreau-jean", 20.0, options={"h": 1e-2})
    assert run.counters.nfev == res.nfev > 0


def test_the_bouncing_ball_evaluates_its_contact_law_once_per_step():
    problem = get_problem("bouncing-ball")
    run = simulate(problem, "moreau-jean", 1.0, options={"h": 1e-3})
    assert run.counters.nsteps == 1000
    assert run.counters.nfev == 1000
