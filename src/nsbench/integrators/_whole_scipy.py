"""A whole-system right-hand side stepped by a scipy ODE solver, as a :class:`~nsbench.integrators.whole.SystemResult`.

Shared by ``smoothing`` and ``switch-model``: the solver's own step loop
(``scipy.integrate`` ``OdeSolver`` classes), so the step budget is respected; each
step is returned with ``refine - 1`` points of the solver's dense output inside it
(the event inference interpolates linearly between the points it is given), and
the states at ``t_eval`` come from the dense output.
"""

from __future__ import annotations

from typing import Any, Callable

import numpy as np

from nsbench.integrators.whole import SystemRequest, SystemResult
from nsbench.status import Status

SOLVERS = ("RK45", "DOP853", "Radau", "BDF", "LSODA")


def run_scipy(
    request: SystemRequest,
    fun: Callable,
    jac: Callable | None,
    method: str,
    rtol: float,
    atol: float,
    refine: int,
    modes_of: Callable | None = None,
    max_step: float = np.inf,
) -> SystemResult:
    """Step ``y' = fun(t, y)`` over the request's span with scipy's ``method``.

    ``modes_of(t, y)`` gives the mode of each returned point (``y`` one row per
    point), or ``None`` when the method does not know it.
    """
    from scipy import integrate

    cls = getattr(integrate, method)
    kwargs: dict[str, Any] = {"rtol": rtol, "atol": atol, "max_step": max_step}
    if jac is not None and method in ("Radau", "BDF", "LSODA"):
        kwargs["jac"] = jac
    calls = {"fun": 0, "jac": 0}

    def counted_fun(t, y):
        calls["fun"] += 1
        return fun(t, y)

    def counted_jac(t, y):
        calls["jac"] += 1
        return jac(t, y)

    if "jac" in kwargs:
        kwargs["jac"] = counted_jac
    solver = cls(counted_fun, request.t0, np.array(request.y0, dtype=float), request.t_end, **kwargs)
    ts, ys = [request.t0], [np.array(request.y0, dtype=float)]
    grid = request.t_eval
    y_eval = np.empty((grid.size, len(request.y0)))
    j = 0
    while j < grid.size and grid[j] <= request.t0:
        y_eval[j] = request.y0
        j += 1
    status, message, steps = Status.SUCCESS, "", 0
    inner = np.arange(1, refine) / refine
    while solver.status == "running":
        if steps >= request.max_steps:
            status = Status.BUDGET_EXHAUSTED
            message = f"{request.max_steps} steps used by t = {solver.t:.6g}"
            break
        t_old = solver.t
        msg = solver.step()
        steps += 1
        if solver.status == "failed":
            status, message = Status.INTEGRATOR_FAILURE, f"{method} failed at t = {solver.t:.6g}: {msg}"
            break
        dense = solver.dense_output()
        if refine > 1:
            for tt in t_old + inner * (solver.t - t_old):
                ts.append(float(tt))
                ys.append(np.asarray(dense(tt), dtype=float))
        ts.append(float(solver.t))
        ys.append(np.array(solver.y, dtype=float))
        k = j
        while k < grid.size and grid[k] <= solver.t:
            k += 1
        if k > j:
            y_eval[j:k] = np.asarray(dense(grid[j:k]), dtype=float).T
            j = k
    t = np.array(ts)
    y = np.array(ys)
    if status.ok:
        t[-1] = request.t_end
    modes = None if modes_of is None else modes_of(t, y)
    return SystemResult(
        t=t,
        y=y,
        modes=modes,
        y_eval=y_eval if status.ok else None,
        nfev=int(getattr(solver, "nfev", calls["fun"])),
        njev=int(getattr(solver, "njev", calls["jac"])),
        nsteps=steps,
        status=status,
        message=message,
    )
