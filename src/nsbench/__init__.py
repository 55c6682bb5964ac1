"""nsbench: a bench for time integrators on non-smooth (stick-slip) dynamical systems.

>>> import nsbench
>>> problem = nsbench.get_problem("two-dof", case=1)
>>> result = nsbench.simulate(problem, "exact", t_end=50.0)
>>> list(result.events.columns)
['t', 'kind', 'block', 'x1', 'v1', 'x2', 'v2']

Importing nsbench is light: heavy backends (heyoka, scikit-sundae, numba,
matplotlib) are imported only by the components that use them.
"""

from __future__ import annotations

from importlib import import_module
from typing import Any

__version__ = "0.1.0"

_EXPORTS = {
    "get_problem": "nsbench.problems",
    "list_problems": "nsbench.problems",
    "problem_from_config": "nsbench.problems",
    "get_integrator": "nsbench.integrators",
    "list_integrators": "nsbench.integrators",
    "integrator_from_config": "nsbench.integrators",
    "Integrator": "nsbench.integrators",
    "Capabilities": "nsbench.integrators",
    "simulate": "nsbench.engine",
    "SimulationResult": "nsbench.results",
    "Status": "nsbench.results",
    "Counters": "nsbench.results",
    "ConfigError": "nsbench.errors",
    "pi_groups": "nsbench.units",
}

__all__ = sorted(_EXPORTS) + ["__version__"]


def __getattr__(name: str) -> Any:
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module 'nsbench' has no attribute {name!r}")
    value = getattr(import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return __all__
