"""INRIA Siconos as an engine, run in its own interpreter: ``siconos-moreau-jean`` and ``siconos-event-driven``.

``siconos-moreau-jean`` is Siconos's time-stepping of the friction chain and the bouncing
ball; ``siconos-event-driven`` (:class:`SiconosEventDriven`) its event-driven scheme
(``EventDriven``, ``LsodarOSI``) on the bouncing ball.

Debian packages Siconos (``apt-get install python3-siconos``, version 4.4) for the system
Python and numpy 1.x, so it cannot be imported here: each run starts the system
interpreter (``NSBENCH_SICONOS_PYTHON``, default ``/usr/bin/python3``) on
:mod:`nsbench.integrators._siconos_worker` and exchanges plain arrays (JSON in, ``.npy``
files out). The model: the chain as Siconos's first-order linear system, one relay per
block on its velocity relative to the belt, the ``EulerMoreauOSI`` theta-scheme (the same
discrete equations as ``moreau-jean`` on these linear systems), the relay problem solved
by Lemke's method. A step's mode is read off the relay (stuck while the friction force is
inside ``(-fr, fr)``, slipping against its sign at a bound) and returned, but the event
inference reads the phases off the trajectory, as for ``moreau-jean``, so the two give the
same event times from the same trajectory.

The bouncing ball is Siconos's classic (``LagrangianLinearTIDS`` under gravity,
``LagrangianLinearTIR`` on the height, ``NewtonImpactNSL(e)``, ``MoreauJeanOSI(theta)``, an
LCP per step): the same discrete equations and contact activation as ``moreau-jean``'s
ball, its impulses handed to the event inference; the other impact problems are refused.

Siconos's relay has one friction level, so problems with stiction above the kinetic level
(``fr != fs``) are refused, as are cubic springs and the harmonic force (a time-dependent
input needs a compiled Siconos plug-in); the block on the ground (``fs = fr``) and the
belt problems with ``r_f = 1`` run. Where the package is absent every problem is refused
with that reason and ``nsbench list integrators`` shows it as unavailable.
"""

from __future__ import annotations

import json
import os
import subprocess
import tempfile
from pathlib import Path
from typing import TYPE_CHECKING, Any, cast

import numpy as np

from nsbench.errors import UnsupportedProblemError
from nsbench.integrators.base import Capabilities, Option
from nsbench.integrators.moreau_jean import stiffness_matrix, uniform_steps
from nsbench.integrators.whole import SystemRequest, SystemResult, WholeSystem
from nsbench.status import Status

if TYPE_CHECKING:  # pragma: no cover
    from nsbench.problems.oscillator import FrictionOscillator

WORKER = Path(__file__).with_name("_siconos_worker.py")
_PROBE: dict[str, str | None] = {}


def siconos_python() -> str:
    """The interpreter that has Siconos: ``NSBENCH_SICONOS_PYTHON`` or ``/usr/bin/python3``."""
    return os.environ.get("NSBENCH_SICONOS_PYTHON", "/usr/bin/python3")


def unavailable_reason() -> str | None:
    """Why Siconos cannot run here, or ``None`` (probed once per process)."""
    exe = siconos_python()
    if exe not in _PROBE:
        if not Path(exe).exists():
            _PROBE[exe] = f"no interpreter {exe} (set NSBENCH_SICONOS_PYTHON)"
        else:
            try:
                out = subprocess.run(
                    [exe, str(WORKER)], input=json.dumps({"probe": True}), capture_output=True, text=True, timeout=120
                )
                _PROBE[exe] = (
                    None
                    if out.returncode == 0
                    else (
                        f"Siconos is not importable by {exe} (apt-get install python3-siconos): "
                        + (out.stderr.strip().splitlines() or ["no message"])[-1]
                    )
                )
            except (OSError, subprocess.TimeoutExpired) as exc:
                _PROBE[exe] = f"{exe} could not be run: {exc}"
    return _PROBE[exe]


def run_worker(req: dict, worker: Path = WORKER) -> tuple[np.ndarray, np.ndarray, dict] | str:
    """Run one request in Siconos's interpreter: its two ``.npy`` arrays and its JSON line, or why it failed."""
    with tempfile.TemporaryDirectory(prefix="nsbench-siconos-") as tmp:
        out = str(Path(tmp) / "run")
        run = subprocess.run(
            [siconos_python(), str(worker)],
            input=json.dumps({**req, "out": out}),
            capture_output=True,
            text=True,
            timeout=3600,
        )
        if run.returncode != 0:
            tail = (run.stderr.strip().splitlines() or ["no message"])[-1]
            return f"Siconos failed: {tail}"
        info = json.loads((run.stdout.strip().splitlines() or ["{}"])[-1])
        return np.load(out + ".z.npy"), np.load(out + ".lambda.npy"), info


def failed(request: SystemRequest, message: str) -> SystemResult:
    """A run that Siconos's process ended with an error: the start state only, and the message."""
    return SystemResult(
        t=np.array([request.t0]),
        y=np.array(request.y0, dtype=float).reshape(1, -1),
        status=Status.INTEGRATOR_FAILURE,
        message=message,
    )


def _step_times(request: SystemRequest, h: float, done: int, n_steps: int) -> np.ndarray:
    """The times of a fixed-step run's ``done`` steps; a whole run ends exactly at ``t_end``."""
    t = request.t0 + h * np.arange(done + 1)
    if done == n_steps:
        t[-1] = request.t_end  # t0 + n h may round off it
    return t


def _ending(request: SystemRequest, n_steps: int, done: int, budget: bool) -> tuple[Status, str]:
    """The status of a fixed-step run: cut by the step budget, stopped early by Siconos, or whole."""
    if budget:
        return Status.BUDGET_EXHAUSTED, f"{n_steps} steps needed, budget {request.max_steps}"
    if done < n_steps:
        return Status.INTEGRATOR_FAILURE, f"Siconos stopped after {done} of {n_steps} steps"
    return Status.SUCCESS, ""


class SiconosMoreauJean(WholeSystem):
    """INRIA Siconos: EulerMoreauOSI with a relay per block (friction), MoreauJeanOSI with an LCP (the ball)."""

    name = "siconos-moreau-jean"
    ecosystem = "Siconos"
    capabilities = Capabilities(
        event_location="inferred-from-status",
        order=1,
        adaptive=False,
        supports_nonlinear=False,
        step_option="h",
        family="time-stepping",
        # the friction oscillators (one relay per block) and the bouncing ball (Siconos's classic)
        accepts=("belt_blocks", "falling_mass"),
    )
    options = {
        "h": Option(1e-3, float, lower=0.0, doc="fixed step (rounded down so whole steps fill the span)"),
        "theta": Option(0.5, float, lower=0.5, lower_inclusive=True, upper=1.0, doc="theta of the scheme"),
    }
    accuracy_levels = ({"h": 1e-2}, {"h": 1e-3}, {"h": 1e-4})
    known_gaps = {
        "event-times": "first order in h, as moreau-jean",
        "energy-balance": "time-stepping: the balance closes to O(h), as moreau-jean",
    }

    @classmethod
    def unavailable(cls) -> str | None:
        """Why it cannot run on this machine (``nsbench list`` shows it), or ``None``."""
        return unavailable_reason()

    def smooth_order(self) -> int:
        return 2 if self.settings["theta"] == 0.5 else 1

    def setup(self, problem) -> None:
        super().setup(problem)
        if problem.traits.impacts:
            if not problem.traits.falling_mass:
                raise UnsupportedProblemError(
                    f"{self.name}: of the impact problems it runs the bouncing ball only, "
                    f"not {problem.name} (its contact is not a mass falling onto a fixed ground)"
                )
            reason = unavailable_reason()
            if reason:
                raise UnsupportedProblemError(f"{self.name}: {reason}")
            return
        c = problem.coefficients
        if any(abs(a - b) > 1e-15 * max(abs(b), 1.0) for a, b in zip(c.fs, c.fr)):
            raise UnsupportedProblemError(
                f"{self.name}: Siconos's relay has one friction level; {problem.name} has kinetic friction "
                f"{list(c.fs)} below its static limit {list(c.fr)} (use moreau-jean, or r_f = 1)"
            )
        if c.F != 0.0:
            raise UnsupportedProblemError(
                f"{self.name}: the harmonic force (F = {c.F:g}) needs a compiled Siconos "
                "plug-in; unforced problems only"
            )
        reason = unavailable_reason()
        if reason:
            raise UnsupportedProblemError(f"{self.name}: {reason}")

    def _ball(self, request: SystemRequest, n_steps: int, n_run: int, h: float, budget: bool) -> SystemResult:
        """Siconos's bouncing ball (``MoreauJeanOSI``, an LCP per step); the impulses go to the event inference."""
        problem: Any = request.problem  # a falling mass (its traits say so): it declares g and e
        arrays = run_worker(
            {
                "model": "ball",
                "g": float(problem.g),
                "e": float(problem.e),
                "theta": float(self.settings["theta"]),
                "h": h,
                "n_steps": n_run,
                "t0": float(request.t0),
                "y0": [float(v) for v in request.y0],
            }
        )
        if isinstance(arrays, str):
            return failed(request, arrays)
        z, imp, _ = arrays
        done = z.shape[0] - 1
        t = _step_times(request, h, done, n_steps)
        # moreau-jean's resting label (its kernel mj_ball): from the first step whose impulse is positive
        # while the speed it reverses, e |v_k|, is at most one step's gain under gravity, g h
        resting = (imp[1:, 0] > 0.0) & (problem.e * np.abs(z[:-1, 1]) <= problem.g * h)
        modes = np.concatenate([[0], np.maximum.accumulate(resting.astype(np.int64))]).reshape(-1, 1)
        status, message = _ending(request, n_steps, done, budget)
        return SystemResult(t=t, y=z, modes=modes, impulses=imp, nsteps=done, status=status, message=message)

    def integrate(self, request: SystemRequest) -> SystemResult:
        problem = request.problem
        n_steps, h = uniform_steps(request.t0, request.t_end, self.settings["h"])
        budget = n_steps > request.max_steps
        n_run = min(n_steps, int(request.max_steps))
        if problem.traits.falling_mass:
            return self._ball(request, n_steps, n_run, h, budget)
        c = cast("FrictionOscillator", problem).coefficients  # blocks on a belt (its traits say so)
        arrays = run_worker(
            {
                "m": list(c.m),
                "C": np.diag(c.c).tolist(),
                "K": stiffness_matrix(c.k).tolist(),
                "fr": list(c.fr),
                "v0": float(c.v0),
                "theta": float(self.settings["theta"]),
                "h": h,
                "n_steps": n_run,
                "t0": float(request.t0),
                "y0": [float(v) for v in request.y0],
            }
        )
        if isinstance(arrays, str):
            return failed(request, arrays)
        z, lam, _ = arrays
        done = z.shape[0] - 1
        t = _step_times(request, h, done, n_steps)
        fr = np.array(c.fr, dtype=float)
        stuck = np.abs(lam) < fr * (1.0 - 1e-9)
        modes = np.where(stuck, 0, -np.sign(lam)).astype(np.int64)
        modes[0] = problem.initial_mode(request.t0, request.y0)
        status, message = _ending(request, n_steps, done, budget)
        return SystemResult(t=t, y=z, modes=modes, nsteps=done, status=status, message=message)


class SiconosEventDriven(WholeSystem):
    """INRIA Siconos: the ``EventDriven`` simulation with ``LsodarOSI`` on the bouncing ball (separate interpreter).

    Siconos's ``BouncingBallED`` model: LSODAR (ODEPACK) integrates the flight and its root
    finder locates each impact on the height; an LCP at the velocity level applies
    Newton's law there, and an LCP at the acceleration level keeps a resting contact once
    Siconos has stopped the impacts (the contact in index set 2). It hands back a sample
    at every point of an output grid of step ``h`` and at every impact, the impulse of
    each sample and the resting label, from which nsbench infers the impacts and the rest
    like a time-stepping run's (a sample sits at the impact itself, so the inference adds
    no error). The times of the impact samples and of the first resting one are Siconos's
    own switch times (``SystemResult.switch_times``), reported beside the inferred ones
    (the event log's ``t_located``).

    Only the bouncing ball: ``LsodarOSI`` takes Newton's impact law alone (its
    ``fillDSLinks`` refuses ``NewtonImpactFrictionNSL``; tried on the block on the ground,
    the run died with a bare ``std::exception``), so the friction problems are refused at
    setup, as are the other impact problems. LSODAR's tolerances are Siconos's defaults,
    ``rtol = 10 eps`` and ``atol = 100 eps`` (``LsodarOSI::initialize`` sets them,
    overwriting any earlier ``setTol``), so the run has no accuracy option.

    The family tag is ``event-driven`` (what the scheme is), though nsbench runs it through
    the whole-system protocol (:class:`WholeSystem`): Siconos's own loop locates the
    events, nsbench only reads its samples.
    """

    name = "siconos-event-driven"
    ecosystem = "Siconos"
    capabilities = Capabilities(
        event_location="lsodar-root",
        order=None,
        adaptive=True,
        supports_nonlinear=False,
        step_option=None,
        family="event-driven",
        accepts=("falling_mass",),  # the bouncing ball: LsodarOSI takes Newton's impact law only
    )
    options = {
        "h": Option(
            1e-3,
            float,
            lower=0.0,
            doc="output grid of Siconos's time discretisation (LSODAR picks its own steps between the events)",
        ),
    }
    accuracy_levels = ()  # LSODAR's tolerances are fixed (see the class docstring): it runs at its defaults
    known_gaps = {
        "event-times": "it resolves every impact LSODAR can see (a few dozen on the ball), where exact "
        "extrapolates the accumulation after four: the sequences differ in length"
    }

    @classmethod
    def unavailable(cls) -> str | None:
        """Why it cannot run on this machine (``nsbench list`` shows it), or ``None``."""
        return unavailable_reason()

    def setup(self, problem) -> None:
        if not problem.traits.falling_mass:  # before the generic refusal of the base: with Siconos's reason
            why = (
                "Siconos's LsodarOSI takes Newton's impact law only (it refuses NewtonImpactFrictionNSL: a bare "
                "std::exception on the block on the ground)"
                if problem.traits.belt_blocks
                else "its contact is not a mass falling onto a fixed ground"
            )
            raise UnsupportedProblemError(
                f"{self.name}: the bouncing ball only, not {problem.name}: {why}; "
                "siconos-moreau-jean runs the friction problems with one friction level"
            )
        super().setup(problem)
        reason = unavailable_reason()
        if reason:
            raise UnsupportedProblemError(f"{self.name}: {reason}")

    def integrate(self, request: SystemRequest) -> SystemResult:
        problem: Any = request.problem  # a falling mass (its traits say so): it declares g and e
        arrays = run_worker(
            {
                "model": "ball-event-driven",
                "g": float(problem.g),
                "e": float(problem.e),
                "h": float(self.settings["h"]),
                "t0": float(request.t0),
                "t_end": float(request.t_end),
                "max_events": int(request.max_steps),
                "y0": [float(v) for v in request.y0],
            }
        )
        if isinstance(arrays, str):
            return failed(request, arrays)
        rows, marks, info = arrays
        keep = rows[:, 0] <= request.t_end  # never past the span (Siconos ends on it)
        rows, marks = rows[keep], marks[keep]
        status, message = Status.SUCCESS, ""
        if not info.get("done", False):
            status, message = (
                Status.BUDGET_EXHAUSTED,
                (f"{info.get('events')} events, budget {request.max_steps}; stopped at t = {rows[-1, 0]:.6g}"),
            )
        # the impacts LSODAR's root finder located and the sample where Siconos took the resting contact:
        # its own switch times, reported beside the inferred ones
        own = marks[:, 0] > 0.0
        resting = np.flatnonzero(marks[:, 1] > 0.0)
        if resting.size:
            own[resting[0]] = True
        return SystemResult(
            t=rows[:, 0],
            y=rows[:, 1:],
            modes=marks[:, 1:].astype(np.int64),
            impulses=marks[:, :1],
            switch_times=rows[own, 0].copy(),
            switch_elements=np.zeros(int(own.sum()), np.int64),
            nsteps=int(info.get("events", 0)),
            status=status,
            message=message,
        )
