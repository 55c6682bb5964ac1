"""Benchmarking: suites, the parallel runner, metrics against a reference, storage,
reports, comparisons and pytest-benchmark ingestion.

>>> from nsbench.bench import Suite, run_suite            # doctest: +SKIP
>>> suite = Suite(problems=[{"name": "one-dof", "case": 1}], t_span=(0, 50))
>>> run_suite(suite, "out/")                              # doctest: +SKIP
"""

from __future__ import annotations

from nsbench.bench.runner import RunSummary, run_suite
from nsbench.bench.storage import load_results
from nsbench.bench.suite import Case, Suite, default_suite, load_suite

__all__ = ["Suite", "Case", "RunSummary", "run_suite", "load_results", "load_suite", "default_suite"]
