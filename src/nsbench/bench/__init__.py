"""Benchmarking: suites, the parallel runner, metrics against a reference, storage,
reports, comparisons and pytest-benchmark ingestion.

>>> from nsbench.bench import Suite, run_suite            # doctest: +SKIP
>>> suite = Suite(problems=[{"name": "one-dof", "case": 1}], t_span=(0, 50))
>>> run_suite(suite, "out/")                              # doctest: +SKIP
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from nsbench.bench.runner import RunSummary, run_suite
    from nsbench.bench.storage import load_results
    from nsbench.bench.suite import Case, Suite, default_suite, load_suite

__all__ = ["Suite", "Case", "RunSummary", "run_suite", "load_results", "load_suite", "default_suite"]

#: Where each public name lives. They are imported on first use: a module of this package (a
#: worker process, the message protocol) must not pay for the runner's imports (pandas, ...).
_HOME = {
    "RunSummary": "runner",
    "run_suite": "runner",
    "load_results": "storage",
    "Case": "suite",
    "Suite": "suite",
    "default_suite": "suite",
    "load_suite": "suite",
}


def __getattr__(name: str) -> Any:
    home = _HOME.get(name)
    if home is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(f"{__name__}.{home}"), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(list(globals()) + __all__)
