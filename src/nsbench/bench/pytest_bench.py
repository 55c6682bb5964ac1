"""Helpers for pytest-benchmark suites (``benchmarks/``): parameters over the registry,
and one call that times a case and stores its accuracy metrics in ``extra_info``.

The ``extra_info`` of each benchmark holds the tidy-row columns (configs, counters,
metrics), so ``nsbench ingest FILE.json`` rebuilds the same rows the runner writes.
"""

from __future__ import annotations

import math
import os
from typing import Any

import numpy as np

from nsbench.bench.execute import base_row
from nsbench.bench.metrics import case_metrics
from nsbench.bench.reference import Reference, candidates, compute_reference, reference_key
from nsbench.bench.suite import Case

#: (problem, case) pairs of the benchmark suite: the 1-DOF standard scenario and 2-DOF cases 1-4.
BENCH_PROBLEMS: tuple[tuple[str, int], ...] = (
    ("one-dof", 1),
    ("two-dof", 1),
    ("two-dof", 2),
    ("two-dof", 3),
    ("two-dof", 4),
)
REFERENCES = ("exact", "reference")
DENSE_POINTS = 100
#: Row columns that pytest-benchmark's own statistics provide (see nsbench.bench.ingest).
_TIMING = (
    "wall_time",
    "wall_time_min",
    "wall_time_max",
    "wall_spread",
    "wall_times",
    "n_repeats",
    "integrator_time",
    "integrator_times",
    "setup_time_timed",
    "warmup_time",
    "timestamp",
)


def bench_t_end() -> float:
    """Time span of the benchmarks: ``NSBENCH_BENCH_T_END`` or 100."""
    return float(os.environ.get("NSBENCH_BENCH_T_END", "100"))


def bench_span(full: float) -> float:
    """Span of a benchmark whose full size integrates over ``full`` time units.

    Parameters
    ----------
    full
        The benchmark's own span when ``NSBENCH_BENCH_T_END`` is unset.

    Returns
    -------
    float
        ``min(full, NSBENCH_BENCH_T_END)`` when the variable is set, else ``full``:
        the variable bounds every benchmark module (a quick smoke run), while a
        module whose full size differs from :func:`bench_t_end`'s default of 100
        keeps its own size when it is unset.
    """
    value = os.environ.get("NSBENCH_BENCH_T_END")
    return float(full) if value is None else min(float(full), float(value))


def registered_integrators() -> list[str]:
    """Every integrator in the registry (entry points and plug-ins alike)."""
    from nsbench.integrators import list_integrators

    return list_integrators()


def problem_params() -> list:
    """``pytest.param`` of each benchmark problem config, with ids like ``two-dof-2``."""
    import pytest

    return [pytest.param(problem_config(name, case), id=f"{name}-{case}") for name, case in BENCH_PROBLEMS]


def problem_config(name: str, case: int, **params: Any) -> dict[str, Any]:
    from nsbench.problems import get_problem

    return get_problem(name, case=case, **params).config()


def get_reference(cache: dict[str, Reference], problem: dict[str, Any], t_end: float) -> Reference:
    """The reference of ``problem`` over ``[0, t_end]``, computed once per ``cache``."""
    cands = candidates(REFERENCES)
    key = reference_key(problem, cands, 0.0, t_end, DENSE_POINTS)
    if key not in cache:
        cache[key] = compute_reference(problem, cands, 0.0, t_end, DENSE_POINTS)
    return cache[key]


def _json_safe(value: Any) -> Any:
    if value is None or isinstance(value, (str, bool, int)):
        return value
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, (list, tuple, np.ndarray)):
        return [_json_safe(v) for v in value]
    return value.item() if hasattr(value, "item") else str(value)


def bench_case(
    benchmark,
    cache: dict[str, Reference],
    problem: dict[str, Any],
    integrator: str,
    options: dict[str, Any] | None = None,
    *,
    t_end: float | None = None,
    rounds: int = 3,
) -> dict[str, Any]:
    """Time one case with ``benchmark.pedantic`` and put its tidy row in ``benchmark.extra_info``.

    The timed call is a whole :func:`nsbench.simulate` (setup included) after one
    untimed warm-up run, which also checks that the integrator accepts the problem
    (``pytest.skip`` otherwise). Returns the row.
    """
    import pytest

    from nsbench.engine import simulate
    from nsbench.errors import UnsupportedProblemError
    from nsbench.integrators import get_integrator
    from nsbench.problems import problem_from_config

    t_end = bench_t_end() if t_end is None else float(t_end)
    prob = problem_from_config(problem)
    grid = np.linspace(0.0, t_end, DENSE_POINTS)
    integ = get_integrator(integrator, **dict(options or {}))
    try:
        first = simulate(prob, integ, t_end, t_eval=grid, max_steps=MAX_STEPS)
    except UnsupportedProblemError as exc:
        pytest.skip(str(exc))
    benchmark.pedantic(
        simulate,
        args=(prob, integ, t_end),
        kwargs={"t_eval": grid, "max_steps": MAX_STEPS},
        rounds=rounds,
        iterations=1,
        warmup_rounds=0,
    )
    return record_case(benchmark, cache, problem, integrator, options, first, t_end=t_end, rounds=rounds)


#: Step budget of a benchmarked run.
MAX_STEPS = 2_000_000


def record_case(
    benchmark,
    cache: dict[str, Reference],
    problem: dict[str, Any],
    integrator: str,
    options: dict[str, Any] | None,
    result,
    *,
    t_end: float,
    rounds: int,
) -> dict[str, Any]:
    """The tidy row of a run a benchmark timed itself, stored in ``benchmark.extra_info`` (and returned).

    For benchmark modules that time their own call (:func:`bench_case` is one):
    ``result`` is one of the runs, the :class:`~nsbench.results.SimulationResult`
    whose events and counters the row records; its accuracy metrics are taken
    against the certified reference of ``problem`` over ``[0, t_end]`` (computed
    once per ``cache``); the state errors need ``result`` run with
    ``t_eval = np.linspace(0, t_end, DENSE_POINTS)`` (NaN otherwise). The
    timing columns are left to pytest-benchmark's statistics, which ``nsbench
    ingest`` reads. Keys a module adds to ``extra_info`` itself must not be
    column names (:data:`nsbench.bench.schema.COLUMN_NAMES`): ingest would read
    them as such.
    """
    from nsbench.problems import problem_from_config

    t_end = float(t_end)
    options = dict(options or {})
    case = Case(
        problem=problem,
        integrator=integrator,
        options=options,
        level=-1,
        t0=0.0,
        t_end=t_end,
        repeats=rounds,
        time_limit=math.inf,
        max_steps=MAX_STEPS,
        dense_points=DENSE_POINTS,
    )
    ref = get_reference(cache, problem, t_end)
    prob = problem_from_config(problem)
    row = base_row(case, "pytest-benchmark")
    counters = result.counters.as_dict()
    row.update(
        status=result.status.value,
        message=result.message,
        t_final=result.t_final,
        nfev=counters["nfev"],
        njev=counters["njev"],
        nsteps=counters["nsteps"],
        n_events=counters["n_events"],
        setup_time=result.setup_time,
        **ref.columns(),
    )
    if ref.ok:
        dense = (
            result.trajectory[list(prob.state_names)].to_numpy().T
            if result.ok and len(result.trajectory) == DENSE_POINTS
            else None
        )
        metrics = case_metrics(ref.events, result.events, ref.y_dense, dense, ref.y_final, result.y_final)
        metrics.pop("truncated")
        row.update(metrics)
    for key, value in row.items():
        if key not in _TIMING:  # timing: pytest-benchmark's
            benchmark.extra_info[key] = _json_safe(value)
    return row
