"""The ``nsbench lyapunov`` command as a function: :func:`run_lyapunov` runs a :class:`LyapunovRequest`.

One request (:class:`nsbench.bifurcation.request.LyapunovRequest`, checked at its construction)
in, one :class:`LyapunovOutcome` out: the estimate (:class:`~nsbench.bifurcation.lyapunov.LyapunovResult`)
and the one line saying why the command exits 1 (a plug-in problem's factory failed, or members
failed and no exponent was estimated). Refused input raises a :class:`~nsbench.errors.ConfigError`
before any member runs (the command exits 2). The command line (:mod:`nsbench.cli.lyapunov`) maps
its arguments onto the request and prints the outcome's failure line; the estimate and what was
written are printed here.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

from nsbench.bifurcation.request import LyapunovRequest
from nsbench.status import Status

if TYPE_CHECKING:  # pragma: no cover
    from nsbench.bifurcation.lyapunov import LyapunovResult

#: Step budget of the transient (the core's default): a fixed step that needs more is refused up front.
TRANSIENT_MAX_STEPS = 5_000_000


@dataclass(frozen=True)
class LyapunovOutcome:
    """What :func:`run_lyapunov` did: the estimate (``None`` when nothing ran) and why the command
    exits 1 (``None``: it exits 0)."""

    result: LyapunovResult | None
    failure: str | None = None

    @property
    def exit_code(self) -> int:
        return 0 if self.failure is None else 1


def run_lyapunov(request: LyapunovRequest) -> LyapunovOutcome:
    """Build the request's problem, estimate the exponent over an ensemble of Benettin runs
    (:func:`nsbench.bifurcation.lyapunov.largest_exponent`), print it and write ``out``.

    A plug-in problem's factory runs first in a supervised worker under ``setup_limit``: one that
    loops, crashes or raises is the outcome's failure, and nothing runs.

    Raises
    ------
    ConfigError
        An unknown problem or integrator, or a fixed step too small for the transient.
    """
    from nsbench.factory_probe import probe_problem

    fault = probe_problem(request.problem, [request.problem_arguments], request.setup_limit)
    if fault is not None:
        return LyapunovOutcome(None, f"{fault}; nothing was run")
    from nsbench.bifurcation.lyapunov import largest_exponent
    from nsbench.inputs import check_fixed_step
    from nsbench.integrators import get_integrator
    from nsbench.problems import get_problem

    problem = get_problem(request.problem, **request.problem_arguments)
    name = request.integrator or ("exact" if problem.is_linear else "henon-rk4")
    # the transient is one run with the core's default step budget; the whole run is longer (mapping
    # points after it), so the step is not compared with the transient itself
    transient = request.transient
    integrator = get_integrator(name, **request.options)
    check_fixed_step(integrator, problem, transient, f"--transient {transient:g}", TRANSIENT_MAX_STEPS)
    res = largest_exponent(
        problem,
        name,
        options=request.options,
        transient=transient,
        iterations=request.iterations,
        members=request.members,
        d0=request.d0,
        seed=request.seed,
        workers=request.workers,
        member_limit=request.member_limit,
        worker_log=f"{request.out}.worker-errors.log" if request.out else None,  # else a temporary file
    )
    print(f"{problem!r} with {name}")
    print(res.summary())
    if res.message:
        print(res.message)
    if request.out:
        _write_logs(res, request.out)
        print(f"log growth per member and iteration -> {request.out}")
    if res.status != Status.SUCCESS:  # the members' reasons are printed above
        failed = res.message.count("member ") or "some"
        return LyapunovOutcome(res, f"no exponent: {failed} member(s) failed (reasons above)")
    return LyapunovOutcome(res)


def _write_logs(res: LyapunovResult, path: str) -> None:
    """``log(d/d0)`` of each member at each iteration, one row each."""
    import numpy as np
    import pandas as pd

    members, per = res.logs.shape
    pd.DataFrame(
        {
            "member": np.repeat(np.arange(members), per),
            "iteration": np.tile(np.arange(1, per + 1), members),
            "log_growth": res.logs.ravel(),
        }
    ).to_csv(path, index=False)
