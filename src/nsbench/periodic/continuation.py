"""Natural-parameter continuation of a periodic orbit, with step control and located bifurcations.

From an orbit at ``start``, the parameter advances by at most
``h_max = |stop - start| / steps``; each step re-solves the orbit by shooting
from the previous one's mid-arc anchor. A step that fails (Newton diverges, or
the flow has no orbit of that kind) is halved down to ``h_max / 2**10``; a step
that succeeds after a halving lets the next one double again. Between two
accepted steps whose signatures (event pattern, unstable multiplier count)
differ, the bifurcation is located by bisection and classified
(:mod:`nsbench.periodic.bifurcations`). The branch ends at ``stop``, after
``max_steps``, or where no step of the smallest size succeeds; that end is
located too, and the reason is kept in :attr:`Branch.end_reason`. At a
period doubling, :func:`double` starts the doubled orbit's branch (branch
switching along the multiplier's eigenvector).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields
from typing import Any, Callable

import numpy as np
import pandas as pd

from nsbench.errors import ConfigError
from nsbench.periodic.bifurcations import Bifurcation, _reanchored, format_multipliers, locate, signature
from nsbench.periodic.flow import HybridFlow, is_friction
from nsbench.periodic.shooting import PeriodicOrbit, ShootingError, resolve, shoot

#: Halvings of the step before a branch is declared ended.
MAX_HALVINGS = 10


@dataclass
class Branch:
    """A continued branch: one orbit per accepted step, the located bifurcations and why it ended."""

    param: str
    values: list[float] = field(default_factory=list)
    orbits: list[PeriodicOrbit] = field(default_factory=list)
    bifurcations: list[Bifurcation] = field(default_factory=list)
    end_reason: str = ""
    label: str = "1"
    #: the converged orbit nearest each bifurcation, on the side the branch came from
    near_orbits: list[PeriodicOrbit] = field(default_factory=list)

    def frame(self) -> pd.DataFrame:
        """One row per step: value, period, stability, multipliers, pattern, start point."""
        rows = []
        for value, o in zip(self.values, self.orbits):
            row = {
                "branch": self.label,
                "param": self.param,
                "value": value,
                "period": o.period,
                "forcing_periods": o.forcing_periods if o.forced else np.nan,
                "stable": o.stable,
                "max_multiplier": o.max_multiplier,
                "unstable_multipliers": o.unstable_count,
                "multipliers": format_multipliers(o.multipliers),
                "pattern": o.pattern_text(),
                "events_per_period": len(o.events),
                "t0": o.t0,
                "mode0": " ".join(map(str, o.mode0)),
                "residual": o.residual,
                "newton_iterations": o.iterations,
            }
            for name, v in zip(o.problem.state_names, o.y0):
                row[f"{name}_0"] = v
            rows.append(row)
        return pd.DataFrame(rows)

    def bifurcation_frame(self) -> pd.DataFrame:
        cols = [f.name for f in fields(Bifurcation)]
        frame = pd.DataFrame([b.row() for b in self.bifurcations], columns=cols)
        frame.insert(0, "branch", self.label)
        return frame


def continue_orbit(
    flow: HybridFlow,
    problem_at: Callable[[float], object],
    param: str,
    orbit: PeriodicOrbit,
    start: float,
    stop: float,
    *,
    steps: int = 200,
    max_steps: int | None = None,
    xtol: float = 1e-11,
    locate_bifurcations: bool = True,
    on_step: Callable[[float], None] | None = None,
    label: str = "1",
) -> Branch:
    """Follow ``orbit`` (converged at ``start``) in ``param`` up to ``stop``.

    Parameters
    ----------
    flow
        The hybrid flow (rebound to each parameter value).
    problem_at
        The problem at a parameter value.
    steps
        Steps over the whole range at the largest step size.
    max_steps
        Accepted steps before giving up (default ``4 * steps``).
    xtol
        Bracket width at which a bifurcation counts as located.
    on_step
        Called with each accepted value (progress).
    """
    if not (math.isfinite(start) and math.isfinite(stop)) or start == stop:
        raise ConfigError(f"continuation range {start}..{stop} must be two different finite numbers")
    if int(steps) != steps or steps < 1:
        raise ConfigError(f"steps = {steps!r} must be a positive whole number")
    max_steps = 4 * int(steps) if max_steps is None else int(max_steps)
    direction = 1.0 if stop > start else -1.0
    h_max = abs(stop - start) / steps
    h_min = h_max / 2**MAX_HALVINGS
    branch = Branch(param, [float(start)], [orbit], label=label)
    value, h = float(start), h_max
    for _ in range(max_steps):
        if direction * (stop - value) <= 0:
            branch.end_reason = f"reached {param} = {stop:g}"
            break
        target = value + direction * min(h, abs(stop - value))
        if abs(target - stop) < 1e-12 * max(1.0, abs(stop)):
            target = stop
        flow.rebind(problem_at(target))
        new = _step(flow, orbit)
        if new is None:
            if h / 2 < h_min:
                branch.end_reason = (
                    f"no orbit of pattern [{orbit.pattern_brief()}] beyond {param} = {value:.10g} (step {h:.2g} failed)"
                )
                if locate_bifurcations:
                    bif, near, _ = locate(flow, problem_at, param, value, orbit, target, None, xtol)
                    branch.bifurcations.append(bif)
                    branch.near_orbits.append(near)
                    branch.end_reason += f"; the branch ends at {param} = {bif.value:.12g} ({bif.kind})"
                break
            h /= 2
            continue
        if locate_bifurcations and signature(new) != signature(orbit):
            bif, near, far = locate(flow, problem_at, param, value, orbit, target, new, xtol)
            branch.bifurcations.append(bif)
            branch.near_orbits.append(near)
            if far is None:  # the orbit ends; Newton found another one beyond: a new branch
                branch.end_reason = (
                    f"the orbit of pattern [{orbit.pattern_brief()}] ends at {param} = {bif.value:.12g} ({bif.kind})"
                )
                break
            if not is_friction(orbit.problem) and signature(far) != signature(new):
                # A second change lies between the bracket and the target (an impacting orbit turns
                # unstable just before it grazes): go on from the bracket's far side, not the target.
                target = bif.value + direction * 0.5 * bif.bracket
                new = _reanchored(flow, far)
            flow.rebind(problem_at(target))

        value, orbit = target, new
        branch.values.append(value)
        branch.orbits.append(orbit)
        if on_step is not None:
            on_step(value)
        h = min(2 * h, h_max)
    else:
        branch.end_reason = f"stopped after {max_steps} steps at {param} = {value:.10g}"
    return branch


def _step(flow: HybridFlow, orbit: PeriodicOrbit) -> PeriodicOrbit | None:
    new = resolve(flow, orbit)
    return None if new is None else _reanchored(flow, new)


def double(
    flow: HybridFlow,
    problem_at: Callable[[float], object],
    bif: Bifurcation,
    orbit: PeriodicOrbit,
    past: float,
    eps: float | None = None,
) -> PeriodicOrbit | None:
    """The period-doubled orbit just past a period doubling at ``past``, or ``None`` if none is found.

    The start guess is the single orbit's start point moved along the eigenvector of
    its multiplier nearest ``-1`` (both ways; by ``eps``, default a few times the
    square root of the distance past the doubling, the doubled orbit's size), with
    twice the period. A solution that is the single orbit run twice is rejected.
    """
    flow.rebind(problem_at(past))
    mu, vec = np.linalg.eig(orbit.monodromy)
    k = int(np.argmin(np.abs(mu + 1.0)))
    direction = np.real(vec[:, k])
    direction /= np.max(np.abs(direction)) or 1.0
    sizes = [eps] if eps is not None else [c * math.sqrt(abs(past - bif.value)) for c in (1.0, 3.0, 0.3)]
    for size in sizes:
        for sign in (1.0, -1.0):
            y = orbit.y0.copy()
            y[orbit.free] += sign * size * direction
            try:
                new = shoot(flow, orbit.t0, y, orbit.mode0, 2.0 * orbit.period, forced=orbit.forced)
            except ShootingError:
                continue
            if new.period > 1.5 * orbit.period:  # not reduced to the single orbit
                return new
    return None


@dataclass
class Continuation:
    """Every branch found over a parameter range, and the values where none was found."""

    param: str
    start: float
    stop: float
    branches: list[Branch] = field(default_factory=list)
    gaps: list[tuple[float, str]] = field(default_factory=list)

    @property
    def bifurcations(self) -> list[Bifurcation]:
        return sorted((b for br in self.branches for b in br.bifurcations), key=lambda b: b.value)

    def frame(self) -> pd.DataFrame:
        frames = [br.frame() for br in self.branches if br.values]
        return pd.concat(frames, ignore_index=True) if frames else pd.DataFrame()

    def bifurcation_frame(self) -> pd.DataFrame:
        frames = [br.bifurcation_frame() for br in self.branches] or [Branch(self.param).bifurcation_frame()]
        return pd.concat(frames, ignore_index=True).sort_values("value", kind="stable", ignore_index=True)


def trace(
    problem_at: Callable[[float], object],
    param: str,
    start: float,
    stop: float,
    *,
    steps: int = 200,
    integrator: str | None = None,
    transient: float = 1500.0,
    xtol: float = 1e-11,
    doubling: int = 2,
    max_branches: int = 50,
    on_step: Callable[[float], None] | None = None,
    origin: float | None = None,
    flow: HybridFlow | None = None,
    on_branch: Callable[[Continuation], None] | None = None,
) -> Continuation:
    """Periodic orbits over ``[start, stop]``: the attractor reached from rest at ``start``, continued;
    where a branch ends, the attractor the motion settles on just beyond, continued; and so on.

    Parameters
    ----------
    problem_at
        The problem at a parameter value.
    steps
        Steps over the whole range at the largest step size (each branch gets its share).
    integrator
        Integrator of the flow (default: :class:`HybridFlow`'s choice).
    transient
        Time integrated before looking for the orbit a motion settles on.
    doubling
        Depth of branch switching at period doublings (0: none).
    origin
        Where to find the first orbit from rest when the motion from rest at ``start``
        is not the wanted one (coexisting attractors): that orbit is continued from
        ``origin`` to ``start`` first (not recorded).
    flow
        A set-up flow to use (it is rebound to each value); ``integrator`` is then ignored.
    on_branch
        Called with the result so far each time a branch and the branches switched from it
        are complete (a supervised worker sends them on, so that a time limit keeps them).
        It may rebind the flow: every use of the flow here rebinds it first.
    """
    from nsbench.periodic.shooting import find_orbit

    direction = 1.0 if stop > start else -1.0
    h_max = abs(stop - start) / steps
    flow = flow if flow is not None else HybridFlow(problem_at(start), integrator)
    result = Continuation(param, float(start), float(stop))
    value, seed = float(start), None  # seed: (t0, y0) to settle from after a branch end
    first: PeriodicOrbit | None = None
    if origin is not None and origin != start:
        flow.rebind(problem_at(origin))
        lead = continue_orbit(
            flow,
            problem_at,
            param,
            find_orbit(flow, transient=transient),
            origin,
            start,
            steps=max(1, int(round(abs(start - origin) / h_max))),
            locate_bifurcations=False,
        )
        if lead.values[-1] != start:
            raise ShootingError(
                f"the orbit from rest at {param} = {origin:g} does not reach {start:g}: {lead.end_reason}"
            )
        first = lead.orbits[-1]
    while direction * (stop - value) > 1e-12 * max(1.0, abs(stop)) and len(result.branches) < max_branches:
        flow.rebind(problem_at(value))
        try:
            kwargs: dict[str, Any] = {} if seed is None else {"t0": seed[0], "y0": seed[1]}
            orbit, first = (
                (first, None) if first is not None else (find_orbit(flow, transient=transient, **kwargs), None)
            )
        except ShootingError as exc:
            result.gaps.append((value, str(exc)))
            value, seed = value + direction * h_max, None
            if on_step is not None:
                on_step(value)
            continue
        share = max(1, int(round(abs(stop - value) / h_max)))
        branch = continue_orbit(
            flow,
            problem_at,
            param,
            orbit,
            value,
            stop,
            steps=share,
            xtol=xtol,
            on_step=on_step,
            label=str(len(result.branches) + 1),
        )
        result.branches.append(branch)
        if doubling:
            _switch(flow, problem_at, branch, stop, result, h_max, xtol, doubling)
        if on_branch is not None:
            on_branch(result)
        last = branch.values[-1]
        if direction * (stop - last) <= 1e-12 * max(1.0, abs(stop)):
            break
        end = branch.bifurcations[-1].value if branch.bifurcations else last
        # settle just past the end, starting on the last orbit: the attractor the motion jumps to
        value = (
            max(end + direction * h_max / 64, last + direction * h_max / 64)
            if direction > 0
            else min(end + direction * h_max / 64, last + direction * h_max / 64)
        )
        seed = (branch.orbits[-1].t0, branch.orbits[-1].y0)
    return result


def _switch(
    flow, problem_at, branch: Branch, stop: float, result: Continuation, h_max: float, xtol: float, depth: int
) -> None:
    """Follow the doubled orbit from every period doubling of ``branch`` (``depth`` levels deep)."""
    direction = 1.0 if stop > branch.values[0] else -1.0
    for bif in list(branch.bifurcations):
        if bif.kind != "period-doubling":
            continue
        # the stable side's orbit nearest the doubling is where the doubled orbit branches off
        k = int(np.argmin(np.abs(np.asarray(branch.values) - bif.value)))
        past = bif.value + direction * h_max / 16
        new = double(flow, problem_at, bif, branch.orbits[k], past)
        if new is None:
            continue
        share = max(1, int(round(abs(stop - past) / h_max)))
        sub = continue_orbit(
            flow,
            problem_at,
            branch.param,
            new,
            past,
            stop,
            steps=share,
            xtol=xtol,
            label=f"{branch.label}.{len(result.branches) + 1}",
        )
        result.branches.append(sub)
        if depth > 1:
            _switch(flow, problem_at, sub, stop, result, h_max, xtol, depth - 1)


def locate_target(
    problem_at: Callable[[float], object],
    param: str,
    origin: float,
    low: float,
    high: float,
    *,
    kind: str | None = None,
    steps: int = 200,
    integrator: str | None = None,
    transient: float = 1500.0,
    xtol: float = 1e-11,
) -> tuple[Bifurcation, PeriodicOrbit]:
    """The first bifurcation in ``[low, high]`` of the orbit reached from rest at ``origin``.

    The orbit is continued from ``origin`` into the bracket (towards ``high`` if
    ``origin <= low``, towards ``low`` if ``origin >= high``), its bifurcations
    located to ``xtol``. Returns the first one inside the bracket (of ``kind`` if
    given) and the converged orbit just before it, on the continuation's side.

    Raises
    ------
    ConfigError
        ``origin`` inside the bracket, or no such bifurcation in it.
    """
    if not low < high or low < origin < high:
        raise ConfigError(f"bracket [{low}, {high}] must be increasing and not contain the origin {origin}")
    far = high if origin <= low else low
    flow = HybridFlow(problem_at(origin), integrator)
    from nsbench.periodic.shooting import find_orbit

    orbit = find_orbit(flow, transient=transient)
    branch = continue_orbit(flow, problem_at, param, orbit, origin, far, steps=steps, xtol=xtol)
    for bif, near in sorted(zip(branch.bifurcations, branch.near_orbits), key=lambda b: abs(b[0].value - origin)):
        if low <= bif.value <= high and (kind is None or bif.kind == kind):
            return bif, near
    raise ConfigError(
        f"no {kind or 'bifurcation'} of the orbit from {param} = {origin:g} in [{low:g}, {high:g}] "
        f"({branch.end_reason})"
    )
