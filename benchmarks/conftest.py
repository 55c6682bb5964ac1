"""Shared fixtures of the pytest-benchmark suites (generic: any benchmark module may use them).

``nsbench_references`` caches one reference run per problem for the whole
session; ``nsbench_bench(problem_config, integrator, options)`` times a case and
stores its tidy row (configs, counters, accuracy metrics) in ``extra_info``,
which ``nsbench ingest`` reads back. Run with ``pytest benchmarks/ --benchmark-only``.
"""

from __future__ import annotations

import pytest

from nsbench.bench.pytest_bench import bench_case


@pytest.fixture(scope="session")
def nsbench_references() -> dict:
    return {}


@pytest.fixture
def nsbench_bench(benchmark, nsbench_references):
    """``run(problem_config, integrator, options=None, *, t_end=None, rounds=3) -> row``."""

    def run(problem: dict, integrator: str, options: dict | None = None, **kwargs):
        return bench_case(benchmark, nsbench_references, problem, integrator, options, **kwargs)

    return run
