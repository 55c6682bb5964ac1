"""The ``nsbench simulate`` command as a function: :func:`run_simulation` runs a :class:`SimulationRequest`.

One request (checked at its construction) in, one :class:`SimulationOutcome` out: the run's
:class:`~nsbench.results.SimulationResult`, the files written, and the one line saying why the
command exits 1 (a plug-in problem's factory failed, or the run ended short of ``t_end``).
Refused input raises a :class:`~nsbench.errors.ConfigError` before anything is built or run
(the command exits 2). The command line (:mod:`nsbench.cli.simulate`) maps its arguments onto
the request and prints the outcome's failure line; the run's summary, the certified error of a
``reference`` log and the files written are printed here, as they come.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from nsbench.errors import ConfigError
from nsbench.inputs import (
    check_figure_path,
    check_fixed_step,
    check_output_file,
    options_given,
    parse_count,
    parse_real,
)

if TYPE_CHECKING:  # pragma: no cover
    import pandas as pd

    from nsbench.results import SimulationResult

#: Step budget of a run (the engine's default): a fixed step that needs more is refused up front.
MAX_STEPS = 5_000_000
#: The tolerances and the step, which have options of their own (``--rtol``, ``--atol``, ``--h``).
STEP_FLAGS = ("rtol", "atol", "h")


@dataclass(frozen=True)
class SimulationRequest:
    """One run of one problem with one integrator through every event, as asked.

    Each value may be given as the command line's text (``t_end="300"``, ``options=["tol=1e-10"]``)
    or as a Python value (``t_end=300.0``, ``options={"tol": 1e-10}``); the construction parses
    and checks each once, in the order of the command's checks, and keeps the parsed value. A
    message names the command's option (``--t-end = -1 must be ...``). What needs the problem
    (the integrator's options and its fixed step against ``t_end``) is checked by
    :func:`run_simulation` before the run.

    Attributes
    ----------
    problem, case, params, dimensional
        Registered problem, its preset (``None``: the problem's default), parameter overrides
        (``--param``, ``--n``), dimensional units.
    integrator, options
        Registered integrator (``None``: ``exact`` for a linear problem, ``scipy-dop853``
        otherwise) and its options; ``rtol``, ``atol`` and ``h`` are folded into ``options``
        (each is then ``None``) and may not be given twice.
    t_end, samples
        End time; evenly spaced times of the trajectory and, always, of the check for crossings
        stepped over.
    events_out, trajectory_out, plot
        Files to write: the event log (CSV), the trajectory (CSV), a figure.
    setup_limit
        Hard limit (seconds) of a plug-in problem's factory, built first in a worker.
    """

    problem: str
    case: int | str | None = None
    params: dict[str, Any] = field(default_factory=dict)
    dimensional: bool = False
    integrator: str | None = None
    options: dict[str, Any] = field(default_factory=dict)
    rtol: float | None = None
    atol: float | None = None
    h: float | None = None
    t_end: float = 300.0
    samples: int = 3001
    events_out: str | None = None
    trajectory_out: str | None = None
    plot: str | None = None
    setup_limit: float = 1800.0

    def __post_init__(self) -> None:
        def keep(name: str, value: Any) -> None:
            object.__setattr__(self, name, value)

        options = options_given(self.options)
        for flag in STEP_FLAGS:
            value = getattr(self, flag)
            if value is not None:
                if flag in options:
                    raise ConfigError(f"--{flag} and --option {flag}=... are both given; give it once")
                options[flag] = parse_real(str(value), f"--{flag}", low=0.0, low_open=True)
                keep(flag, None)
        keep("options", options)
        keep("t_end", parse_real(str(self.t_end), "--t-end", bound="MAX_SPAN"))  # t_end > t0: the engine's check
        keep("samples", parse_count(str(self.samples), "--samples", low=2, bound="MAX_SAMPLES"))
        for name in ("events_out", "trajectory_out"):
            if getattr(self, name):
                check_output_file(getattr(self, name), "--" + name.replace("_", "-"))
        if self.plot:
            check_figure_path(self.plot, "--plot")
        keep(
            "setup_limit",
            parse_real(str(self.setup_limit), "--setup-limit", low=0.0, low_open=True, bound="MAX_TIME_LIMIT"),
        )
        keep("params", dict(self.params))

    @property
    def problem_arguments(self) -> dict[str, Any]:
        """The ``get_problem`` keyword arguments: the preset, the units and the overrides."""
        return {"case": self.case, "dimensional": self.dimensional, **self.params}


@dataclass(frozen=True)
class SimulationOutcome:
    """What :func:`run_simulation` did: the run (``None`` when nothing ran), the files it wrote,
    and why the command exits 1 (``None``: it exits 0)."""

    result: SimulationResult | None
    written: tuple[Path, ...] = ()
    failure: str | None = None

    @property
    def exit_code(self) -> int:
        return 0 if self.failure is None else 1


def run_simulation(request: SimulationRequest) -> SimulationOutcome:
    """Build the request's problem and integrator, run it through :func:`nsbench.engine.simulate`,
    print its summary and write the files asked for.

    A plug-in problem's factory runs first in a supervised worker under ``setup_limit``: one that
    loops, crashes or raises is the outcome's failure, and nothing runs. The ``samples`` are also
    where the core checks each guard's sign (a crossing pair inside one step ends the run
    ``event missed``), with or without a trajectory written: never a silent false success.

    Raises
    ------
    ConfigError
        An unknown problem, integrator or option, or a fixed step too small for ``t_end``.
    """
    from nsbench.factory_probe import probe_problem

    fault = probe_problem(request.problem, [request.problem_arguments], request.setup_limit)
    if fault is not None:
        return SimulationOutcome(None, failure=f"{fault}; nothing was run")
    from nsbench.engine import simulate
    from nsbench.integrators import get_integrator
    from nsbench.problems import get_problem

    problem = get_problem(request.problem, **request.problem_arguments)
    name = request.integrator or ("exact" if problem.is_linear else "scipy-dop853")
    integrator = get_integrator(name, **request.options)  # an unknown option or a bad value: one line now
    t_end = request.t_end
    step_given = type(integrator).capabilities.step_option in request.options
    check_fixed_step(integrator, problem, t_end, f"--t-end {t_end:g}", MAX_STEPS, given=step_given)
    want_trajectory = bool(request.trajectory_out or request.plot)
    grid = np.linspace(0.0, t_end, request.samples) if want_trajectory and t_end > 0 else None
    checks = request.samples if t_end > 0 else 0
    result = simulate(problem, integrator, t_end, t_eval=grid, max_steps=MAX_STEPS, check_points=checks)
    print(result.summary())
    if "t_located" in result.events:  # a whole-system method that locates switches itself (fesd, Siconos's)
        print(located_line(result.events))
    if name == "reference" and result.ok and len(result.events):
        _certify(problem, result, t_end)
    written = _write(request, result)
    if result.ok:
        return SimulationOutcome(result, written)
    # the reason is in the summary; the failure line says the run fell short
    reason = f"{result.status.value}" + (f": {result.message}" if result.message else "")
    return SimulationOutcome(result, written, f"the run ended at t = {result.t_final:g} of {t_end:g}: {reason}")


def _certify(problem, result: SimulationResult, t_end: float) -> None:
    """The reference's log says how far it can be trusted: an independent quad-precision check, as a
    column of the log and two lines."""
    from nsbench.certify import CERTIFIED, certified_errors

    errors, note = certified_errors(problem, result.events, 0.0, t_end)
    result.events[CERTIFIED] = errors
    finite = errors[np.isfinite(errors)]
    # each value bounds |t - t_true|: the difference from the check plus the check's own error and an ulp
    worst = "no event certified" if not finite.size else f"at most {finite.max():.2g}"
    print(f"certified error of this log: {worst} over {finite.size} of {errors.size} events ({note})")
    if finite.size:
        print(f"certified error by kind: {by_kind(result.events['kind'], errors)}")


def _write(request: SimulationRequest, result: SimulationResult) -> tuple[Path, ...]:
    """The event log, the trajectory and the figure the request asks for, each named as it is written."""
    written = []
    for path, frame, what in (
        (request.events_out, result.events, "events"),
        (request.trajectory_out, result.trajectory, "trajectory"),
    ):
        if path:
            _csv(frame, path)
            print(f"{what:<11} -> {path}")
            written.append(Path(path))
    if request.plot:
        from nsbench.plotting import plot_simulation

        plot_simulation(result, request.plot)
        print(f"plot        -> {request.plot}")
        written.append(Path(request.plot))
    return tuple(written)


def _csv(frame: pd.DataFrame, path: str) -> None:
    frame.to_csv(Path(path), index=False, float_format="%.17g")


def by_kind(kinds, errors: np.ndarray) -> str:
    """The largest certified error of each event kind, ``'impact 9.9e-14, stick 5.1e-12'`` (kinds in the
    order of the log; a kind with no certified event says so)."""
    parts = []
    for kind in dict.fromkeys(kinds):
        mine = errors[np.asarray(kinds) == kind]
        mine = mine[np.isfinite(mine)]
        parts.append(f"{kind} {mine.max():.2g}" if mine.size else f"{kind} not certified")
    return ", ".join(parts)


def located_line(events: pd.DataFrame) -> str:
    """How many of the log's events the method located itself, by kind, and how far from the inferred times."""
    own = np.isfinite(events["t_located"].to_numpy(dtype=float))
    if not own.any():
        return f"located     0 of {own.size} events by the integrator itself (the log's t_located)"
    kinds = events["kind"][own].value_counts(sort=False)
    counts = ", ".join(f"{kind}: {count}" for kind, count in kinds.items())
    gap = float(np.max(np.abs(events["t_located"][own].to_numpy(float) - events["t"][own].to_numpy(float))))
    return (
        f"located     {int(own.sum())} of {own.size} events by the integrator itself ({counts}; the log's "
        f"t_located, at most {gap:.2g} from the inferred t)"
    )
