"""The conformance kit: what every nsbench integrator, built-in or plug-in, must satisfy.

>>> from nsbench.testing import check_integrator
>>> results = check_integrator("henon-rk4")              # doctest: +SKIP
>>> [(r.check, r.status) for r in results]                # doctest: +SKIP

In a plug-in's test suite, one pytest item per (integrator, check) pair::

    from nsbench.testing import parametrize_with_checks

    @parametrize_with_checks([MyIntegrator()])
    def test_conformance(integrator, check):
        check(integrator)

The checks run on the presets (cases 1-4) of a problem family, by default the
2-DOF oscillator; ``check_integrator(..., problem={"name": "chain", "n": 5})``,
``parametrize_with_checks([...], problem=...)`` or ``nsbench check INTEGRATOR
--problem chain --n 5`` run them on another registered problem.

Capability tags (:class:`~nsbench.integrators.Capabilities`) decide which
checks apply; an integrator declares the checks it knowingly fails in its
class attribute ``known_gaps = {"check-name": "reason"}``, and they are
reported as expected failures with that reason. The checks (:data:`CHECKS`):

- ``protocol``: names, capabilities, options, accuracy levels; one arc through
  ``advance``; honest counters (``njev > 0`` if it needs a Jacobian).
- ``determinism``: identical runs give identical events and counters.
- ``inputs-not-mutated``: ``advance`` leaves the request's arrays alone.
- ``declared-order``: step halving on a smooth arc shows the declared order
  (fixed-step methods with an order and a step option).
- ``convergence``: tightening the step or tolerance option never loses accuracy.
- ``event-times``: the event sequence and times of case 2 against ``exact``.
- ``cubic-event-times``: the same on case 4 (cubic) against ``reference``.
- ``refuses-unsupported``: linear-only integrators refuse cubic springs.
- ``stuck-stays-stuck``: stuck blocks stay at belt speed until the force
  reaches the static limit (no chattering, no drift).
- ``energy-balance``: energy change equals the work of friction, damping, force.
- ``failure-status``: an exhausted budget is a status, not an exception.
- ``config-round-trip``: every configured integrator is a small dict and back.
"""

from __future__ import annotations

from nsbench.testing._checks import CHECKS, Check, checking_on
from nsbench.testing._kit import (
    CheckResult,
    as_integrator,
    check_integrator,
    parametrize_with_checks,
    run_check,
)

__all__ = ["CHECKS", "Check", "CheckResult", "check_integrator", "parametrize_with_checks",
           "run_check", "as_integrator", "checking_on"]
