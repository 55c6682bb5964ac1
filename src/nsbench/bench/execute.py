"""Running one case (in a worker process): repeats, time limit, metrics, the tidy row.

Nothing a case does may end the suite: an integrator that refuses the problem, fails,
diverges, exceeds its budget or raises comes back as a row with its status and
reason. Only ``KeyboardInterrupt`` (and other ``BaseException``) propagates.
"""

from __future__ import annotations

import datetime as _dt
import json
import math
import statistics
import time
import traceback
from typing import Any

import numpy as np

from nsbench.bench.metrics import case_metrics
from nsbench.bench.reference import Reference
from nsbench.bench.schema import COLUMN_NAMES
from nsbench.bench.suite import Case
from nsbench.errors import UnsupportedProblemError
from nsbench.integrators.base import ArcRequest, ArcResult, Integrator
from nsbench.results import Status


class TimeLimited(Integrator):
    """Wraps an integrator so that a run ends once ``limit`` seconds have passed.

    The check happens between arcs (one arc spans at most one phase), so a run
    overshoots the limit by at most one arc. The wrapped integrator's name, config
    and capabilities are reported unchanged.
    """

    def __init__(self, inner: Integrator, limit: float) -> None:  # no option parsing: a wrapper
        self.inner = inner
        self.name = inner.name  # type: ignore[misc]
        self.capabilities = inner.capabilities  # type: ignore[misc]
        self.settings = inner.settings
        self.limit = float(limit)
        self.deadline = math.inf
        self.hit = False

    def config(self) -> dict[str, Any]:
        return self.inner.config()

    def setup(self, problem) -> None:
        self.inner.setup(problem)
        self.deadline = time.perf_counter() + self.limit  # the engine times setup separately
        self.hit = False

    def advance(self, request: ArcRequest) -> ArcResult:
        if time.perf_counter() > self.deadline:
            self.hit = True
            return ArcResult(t=request.t0, y=np.array(request.y0), fired=None,
                             y_eval=np.empty((request.problem.n_states, 0)),
                             status=Status.BUDGET_EXHAUSTED,
                             message=f"wall-clock limit of {self.limit:g} s reached at t = {request.t0:.6g}")
        return self.inner.advance(request)


def _jsonable(obj: Any) -> str:
    return json.dumps(obj, sort_keys=True, default=float)


def problem_label(config: dict[str, Any]) -> str:
    """``'two-dof/2'`` plus any parameter overrides."""
    label = f"{config['name']}/{config.get('case')}"
    if config.get("dimensional"):
        label += " dimensional"
    params = config.get("params") or {}
    if params:
        label += " " + " ".join(f"{k}={v:g}" for k, v in sorted(params.items()))
    return label


def base_row(case: Case, suite: str) -> dict[str, Any]:
    """The columns known before running: identity, configs, defaults for the rest."""
    from nsbench.integrators import get_integrator, integrator_class

    row: dict[str, Any] = {name: None for name in COLUMN_NAMES}
    cls = integrator_class(case.integrator)
    step_option = cls.capabilities.step_option
    try:
        config = get_integrator(case.integrator, **case.options).config()
    except Exception:  # validated when the suite was expanded; keep the row anyway
        config = {"name": case.integrator, "options": dict(case.options)}
    step_value = config["options"].get(step_option) if step_option else None
    row.update(
        case_id=case.case_id, suite=suite, problem=case.problem["name"], case=case.problem.get("case"),
        problem_label=problem_label(case.problem), problem_config=_jsonable(case.problem),
        integrator=case.integrator, integrator_config=_jsonable(config), options=_jsonable(case.options),
        level=case.level, step_option=step_option or "",
        step_value=float(step_value) if isinstance(step_value, (int, float)) else math.nan,
        t0=case.t0, t_end=case.t_end, message="", wall_times=[], n_repeats=0,
        counters_extra="{}", reference="", reference_config="null", event_t=[], event_err=[],
    )
    return row


def _finish(row: dict[str, Any]) -> dict[str, Any]:
    row["timestamp"] = _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds")
    return row


def run_case(case: Case, reference: Reference, suite: str = "suite") -> dict[str, Any]:
    """Run ``case`` (repeats included) and return its tidy row."""
    from nsbench.engine import simulate
    from nsbench.integrators import get_integrator
    from nsbench.problems import problem_from_config

    row = base_row(case, suite)
    row.update(reference=reference.name or "", reference_config=_jsonable(reference.config),
               reference_status=reference.status)
    grid = np.linspace(case.t0, case.t_end, case.dense_points)
    try:
        problem = problem_from_config(case.problem)
        integ = TimeLimited(get_integrator(case.integrator, **case.options), case.time_limit)
        first = simulate(problem, integ, case.t_end, t0=case.t0, t_eval=grid, max_steps=case.max_steps)
    except UnsupportedProblemError as exc:
        row.update(status="unsupported", message=str(exc))
        return _finish(row)
    except Exception as exc:  # a bug or a refusal we do not know: a row, never a lost suite
        row.update(status="error", message=f"{type(exc).__name__}: {exc} | "
                   + traceback.format_exc(limit=3).strip().splitlines()[-2].strip())
        return _finish(row)
    times = [first.wall_time]
    status = "time limit" if integ.hit else first.status.value
    # Warm repeats: only for cheap, successful cases (an expensive case is its own average).
    if first.ok and not integ.hit and first.wall_time < case.repeat_budget:
        for _ in range(case.repeats - 1):
            again = simulate(problem, integ, case.t_end, t0=case.t0, t_eval=grid, max_steps=case.max_steps)
            times.append(again.wall_time)
    warm = times[1:] or times
    counters = first.counters.as_dict()
    extra = {k: v for k, v in counters.items() if k not in ("nfev", "njev", "nsteps", "n_events")}
    row.update(status=status, message=first.message, t_final=first.t_final,
               nfev=int(counters["nfev"]), njev=int(counters["njev"]), nsteps=int(counters["nsteps"]),
               n_events=int(counters["n_events"]), counters_extra=_jsonable(extra),
               wall_time=float(statistics.median(warm)), wall_times=[float(t) for t in times],
               n_repeats=len(times), setup_time=float(first.setup_time))
    if reference.ok:
        dense = None
        if first.ok and len(first.trajectory) == case.dense_points:
            dense = first.trajectory[list(problem.state_names)].to_numpy().T
        metrics = case_metrics(reference.events, first.events, reference.y_dense, dense,
                               reference.y_final, first.y_final)
        if metrics.pop("truncated"):
            row["message"] = (row["message"] + " | " if row["message"] else "") + \
                "event logs too long: only their starts were aligned"
        row.update(metrics)
    return _finish(row)
