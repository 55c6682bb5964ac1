"""A whole-system right-hand side stepped by SUNDIALS CVODE (scikit-sundae), as a :class:`~nsbench.integrators.whole.SystemResult`.

The twin of :mod:`nsbench.integrators._whole_scipy` for ``smoothing`` and
``switch-model``: CVODE's own step loop (``onestep`` towards ``t_end`` with
``tstop`` there, so no step passes the span), each step returned with
``refine - 1`` points of CVODE's interpolant inside it and the states at
``t_eval`` read from the same interpolant (a ``normal`` request inside the last
internal step interpolates without stepping; one at the step's end then puts the
solver back there, or its next one-step call would return that end again). No root function: the whole-system
methods locate nothing, nsbench infers the events afterwards.
"""

from __future__ import annotations

from typing import Callable

import numpy as np

from nsbench.integrators._sundials_loop import TSTOP_RETURN
from nsbench.integrators.whole import SystemRequest, SystemResult
from nsbench.status import Status

#: The ``solver`` option values that run on CVODE, and CVODE's method for each.
CVODE_METHODS = {"CVODE-BDF": "BDF", "CVODE-Adams": "Adams"}


def run_cvode(
    request: SystemRequest,
    fun: Callable,
    jac: Callable | None,
    method: str,
    rtol: float,
    atol: float,
    refine: int,
    modes_of: Callable | None = None,
) -> SystemResult:
    """Step ``y' = fun(t, y)`` over the request's span with CVODE's ``method`` (``'BDF'`` or ``'Adams'``).

    ``jac(t, y)`` is the analytic Jacobian (dense); ``None`` lets CVODE form it by
    difference quotients. ``modes_of(t, y)`` as in :func:`~nsbench.integrators._whole_scipy.run_scipy`.
    """
    from sksundae.cvode import CVODE

    def rhsfn(t, y, yp):
        yp[:] = fun(t, y)

    def jacfn(t, y, yp, jj):
        jj[:, :] = jac(t, y)

    solver = CVODE(
        rhsfn, method=method, jacfn=None if jac is None else jacfn, rtol=rtol, atol=atol, max_num_steps=10**9
    )
    y0 = np.array(request.y0, dtype=float)
    t_end = float(request.t_end)
    ts, ys = [float(request.t0)], [y0.copy()]
    grid = request.t_eval
    y_eval = np.empty((grid.size, y0.size))
    j = 0
    while j < grid.size and grid[j] <= request.t0:
        y_eval[j] = y0
        j += 1
    status, message, steps, nfev, njev = Status.SUCCESS, "", 0, 0, 0
    inner = np.arange(1, refine) / refine
    t = float(request.t0)
    try:
        solver.init_step(t, y0)
        while t < t_end:
            if steps >= request.max_steps:
                status, message = Status.BUDGET_EXHAUSTED, f"{request.max_steps} steps used by t = {t:.6g}"
                break
            res = solver.step(t_end, method="onestep", tstop=t_end)
            if res.status < 0:
                status, message = (
                    Status.INTEGRATOR_FAILURE,
                    f"CVODE {method} failed at t = {float(res.t):.6g}: {res.message}",
                )
                break
            steps += 1
            t_old, t = t, float(res.t)
            y_new = np.array(res.y, dtype=float)
            nfev, njev = int(res.nfev), int(res.njev)
            # points inside the step and the requested times in it, from the interpolant of this step
            wanted = [float(tt) for tt in t_old + inner * (t - t_old)] if refine > 1 else []
            k = j
            while k < grid.size and grid[k] <= t:
                k += 1
            for t_in in wanted:
                ts.append(t_in)
                ys.append(np.array(solver.step(t_in, method="normal").y, dtype=float))
            inside = False
            for q in range(j, k):
                if grid[q] == t:
                    y_eval[q] = y_new
                else:
                    y_eval[q] = np.asarray(solver.step(float(grid[q]), method="normal").y)
                    inside = True
            j = k
            if inside or wanted:
                # back to the step's end: after a reading inside the step, CVODE's next one-step call
                # would return that end again instead of stepping
                solver.step(t, method="normal")
            ts.append(t)
            ys.append(y_new)
            if res.status == TSTOP_RETURN:
                t = t_end
    except RuntimeError as exc:  # SUNDIALS errors surface as RuntimeError in scikit-sundae
        status, message = Status.INTEGRATOR_FAILURE, f"CVODE {method}: {exc}"
    times = np.array(ts)
    y = np.array(ys)
    if status.ok:
        times[-1] = t_end
        y_eval[j:] = y[-1]  # requested times at t_end that rounding left after the last step
    modes = None if modes_of is None else modes_of(times, y)
    return SystemResult(
        t=times,
        y=y,
        modes=modes,
        y_eval=y_eval if status.ok else None,
        nfev=nfev,
        njev=njev,
        nsteps=steps,
        status=status,
        message=message,
    )
