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

**Which configuration each check runs.** Options the user gives
(``check_integrator(..., options={"h": 0.5})``, ``nsbench check INTEGRATOR --option
h=0.5``, or a configured instance's settings that differ from the defaults) are
used by every check. The single-configuration checks (``event-times``,
``cubic-event-times``, ``stuck-stays-stuck``, ``energy-balance``) run exactly that
configuration; without options they run the *middle accuracy level*,
``accuracy_levels[len(accuracy_levels) // 2]`` (the second of three levels, the
third of four: ``h = 0.0025`` for ``henon-rk4``), or the defaults if the integrator
declares no levels. The stepped checks (``declared-order``, ``convergence``) run
the declared accuracy levels (with the options given on top), or three values of
the step option around the given one (a factor 4 apart for a fixed step, 1000 for
a tolerance). :func:`plan` says what will run; a failure note starts with the
options its run used (``at h=0.5 (the options given): ...``).

Capability tags (:class:`~nsbench.integrators.Capabilities`) decide which
checks apply; an integrator declares the checks it knowingly fails in its
class attribute ``known_gaps = {"check-name": "reason"}``, and they are
reported as expected failures with that reason. The checks (:data:`CHECKS`):

- ``protocol``: names, capabilities, options, accuracy levels; one arc through
  ``advance`` (a whole-system method: one call of ``integrate`` whose result
  keeps :class:`~nsbench.integrators.whole.SystemResult`'s shapes); honest
  counters (``njev > 0`` if it needs a Jacobian).
- ``determinism``: identical runs give identical events and counters.
- ``inputs-not-mutated``: ``advance`` (``integrate``) leaves the request's arrays alone.
- ``switch-convergence`` (whole-system methods): from the loosest declared
  accuracy level to the tightest, the switching-time error of case 1 over
  [0, 20] against ``exact`` falls, and the tightest level has ``exact``'s
  event sequence (convergence with ``h``, ``eta`` or ``eps``).
- ``declared-order``: the end-state error of a smooth arc over the stepped levels
  shows the declared order within 0.6 (fixed-step methods with an order and a
  step option; a whole-system method runs the whole system over the arc, where
  no switch may be inferred, and declares its order there with ``smooth_order()``).
- ``convergence``: tightening the step or tolerance option never loses accuracy
  (an error may grow by at most half, above 1e-12), and the tightest level's error
  is below ``CONVERGED_BOUND`` (1e-5).
- ``event-times``: the event sequence of case 2 over ``tau`` in [0, 60] equals
  ``exact``'s and every event time is within ``EVENT_BOUND`` (1e-5) of it.
- ``cubic-event-times``: the same on case 4 (cubic) over [0, 30] against ``reference``.
- ``refuses-unsupported``: linear-only integrators refuse cubic springs.
- ``stuck-stays-stuck``: stuck blocks stay at belt speed until the force
  reaches the static limit: block 1 slips first, within 1e-6 of the closed-form
  time, and no stuck block drifts from the belt by more than 1e-9.
- ``energy-balance``: energy change equals the work of friction, damping and force
  along case 2 over [0, 40], to ``ENERGY_BOUND`` (1e-6).
- ``failure-status``: an exhausted budget is a status, not an exception.
- ``config-round-trip``: every configured integrator is a small dict and back.
- ``problem-config``: the problem the checks run on is rebuilt whole from its config
  (:func:`check_problem`, which a problem plug-in's own tests can call).

**The first call's cost.** :func:`first_call_cost` times ``setup`` and then the
same first ``advance`` (``integrate``) twice; a first call that costs more than
``FIRST_CALL_RATIO`` (10) times the second, by more than ``FIRST_CALL_FLOOR``
(0.25 s), is flagged: the integrator compiles or loads something there that
``setup`` should. ``nsbench check`` runs it before the checks and prints it on a
line of its own (``FLAG first call: ...``); it is a flag, never a failure, since a
ratio of wall times is no property of the results.

**Checking a problem.** :func:`check_problem` (``check_problem("thermostat")``)
checks a registered problem, built-in or plug-in, without an integrator: at its
default, at every case it names (``HybridProblem.cases``), in each unit system
its factory accepts and with a few parameters overridden,
``problem_from_config(p.config())`` (through JSON text) has the same parameter
vector, start state and start mode as ``p``, and the same config. Every path
that moves a problem between processes or files rebuilds it that way.
"""

from __future__ import annotations

from nsbench.testing._checks import (
    CHECKS,
    ENERGY_BOUND,
    EVENT_BOUND,
    Check,
    checking_on,
    checking_with,
    configured,
    step_levels,
)
from nsbench.testing._first_call import FIRST_CALL_FLOOR, FIRST_CALL_RATIO, FirstCall, first_call_cost
from nsbench.testing._kit import (
    CheckResult,
    as_integrator,
    check_integrator,
    checks_for,
    configure,
    parametrize_with_checks,
    plan,
    run_check,
)
from nsbench.testing._problem import check_problem
from nsbench.testing._supervised import is_plugin, supervised_checks

__all__ = [
    "CHECKS",
    "Check",
    "CheckResult",
    "check_integrator",
    "check_problem",
    "checks_for",
    "is_plugin",
    "supervised_checks",
    "first_call_cost",
    "FirstCall",
    "FIRST_CALL_RATIO",
    "FIRST_CALL_FLOOR",
    "parametrize_with_checks",
    "run_check",
    "as_integrator",
    "checking_on",
    "checking_with",
    "configure",
    "configured",
    "plan",
    "step_levels",
    "EVENT_BOUND",
    "ENERGY_BOUND",
]
