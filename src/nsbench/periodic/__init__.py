"""Periodic orbits of the friction oscillators, the impact oscillator and the relay: shooting, Floquet
multipliers, continuation, bifurcations.

- :mod:`~nsbench.periodic.flow`: the hybrid flow with its Jacobian (state-transition
  and saltation matrices);
- :mod:`~nsbench.periodic.shooting`: periodic orbits by Newton's method, multipliers;
- :mod:`~nsbench.periodic.continuation`: natural-parameter continuation with step
  control, every branch over a range (:func:`trace`), branch switching at period doublings;
- :mod:`~nsbench.periodic.bifurcations`: bifurcations located by bisection to 1e-11 and
  named by their mechanism and the paper's category;
- :mod:`~nsbench.periodic.degenerate`: the degenerate events and arcs of the impact oscillator
  and the relay (grazing, sliding onset), measured from the closed form of each mode.
"""

from nsbench.periodic.bifurcations import Bifurcation, classify, locate, survey
from nsbench.periodic.continuation import Branch, Continuation, continue_orbit, double, locate_target, trace
from nsbench.periodic.flow import HybridFlow, Pass, saltation
from nsbench.periodic.shooting import PeriodicOrbit, ShootingError, canonical_pattern, find_orbit, guess, shoot

__all__ = [
    "Bifurcation",
    "Branch",
    "Continuation",
    "HybridFlow",
    "Pass",
    "PeriodicOrbit",
    "ShootingError",
    "canonical_pattern",
    "classify",
    "continue_orbit",
    "double",
    "find_orbit",
    "guess",
    "locate",
    "locate_target",
    "saltation",
    "shoot",
    "survey",
    "trace",
]
