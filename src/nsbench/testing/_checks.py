"""The conformance checks: one function per property an nsbench integrator must have.

Each check takes a configured :class:`~nsbench.integrators.Integrator` (a fresh
copy built from its config) and raises ``AssertionError`` with a reason when
the integrator falls short. :data:`CHECKS` lists them with the capability
test that decides whether each applies. The problem is a registered problem
(:func:`checking_on`). On the belt oscillators (``two-dof`` by default,
``one-dof``, ``{"name": "chain", "n": 5}``) the checks use their presets: case 2
(linear, forced: both kinds of guard, the forcing, ``exact`` as the reference),
case 1 for a stuck phase, case 3 and 4 for cubic springs. On any other problem
(``bouncing-ball``, a plug-in's) they run on that problem as given, against
``reference``; the checks that need the belt's presets are skipped with that reason.
"""

from __future__ import annotations

import json
import math
import re
from contextlib import contextmanager
from contextvars import ContextVar
from dataclasses import dataclass
from typing import Any, Callable, Iterator

import numpy as np

from nsbench.errors import ConfigError, UnsupportedProblemError
from nsbench.integrators.base import ArcRequest, ArcResult, Capabilities, Integrator, Option
from nsbench.integrators.whole import is_whole_system
from nsbench.results import Status

#: Arithmetic of an integrator's core (``Capabilities.precision``); ``mp``: arbitrary precision (mpmath).
PRECISIONS = ("double", "long double", "quad", "mp")
#: Largest event-time difference from the reference allowed by ``event-times`` (case 2, tau in
#: [0, 60], against ``exact``) and ``cubic-event-times`` (case 4, tau in [0, 30], against ``reference``).
EVENT_BOUND = 1e-5
#: Largest energy-balance residual allowed by ``energy-balance`` (case 2, tau in [0, 40]).
ENERGY_BOUND = 1e-6
#: ``stuck-stays-stuck``: largest error of block 1's slip time, and largest drift of a stuck block
#: from the belt (speed, and block 1's position) before it.
SLIP_BOUND, DRIFT_BOUND = 1e-6, 1e-9
#: Largest end-state error of the smooth arc at the tightest level allowed by ``convergence``.
CONVERGED_BOUND = 1e-5
#: The checks that run one configuration of the integrator (see :func:`configured`).
ONE_CONFIGURATION = ("event-times", "cubic-event-times", "stuck-stays-stuck", "energy-balance")
#: The checks that step the step option over several configurations (see :func:`step_levels`).
STEPPED = ("declared-order", "convergence")


#: The problem the checks run on: a registry name and its parameters (``case`` is each
#: check's own on the belt oscillators). Set for a run by :func:`checking_on`.
FAMILY: ContextVar[tuple[str, dict[str, Any]]] = ContextVar("nsbench_check_family", default=("two-dof", {}))
#: The options the user gave for this run of the kit (:func:`given_options`): every check
#: runs with them. Set for a run by :func:`checking_with`.
GIVEN: ContextVar[dict[str, Any]] = ContextVar("nsbench_check_given", default={})


def problem_family(spec: str | dict[str, Any] | None) -> tuple[str, dict[str, Any]]:
    """A problem from ``'two-dof'``, ``{'name': 'chain', 'n': 5}``, ``'bouncing-ball'`` or ``None`` (2-DOF).

    Built at once (at every preset for the belt oscillators), so a bad name or
    parameter raises a ``ConfigError`` before any check runs.
    """
    from nsbench.problems import get_problem

    if spec is None:
        return FAMILY.get()
    if isinstance(spec, str):
        name, params = spec, {}
    elif isinstance(spec, dict) and isinstance(spec.get("name"), str):
        params = {k: v for k, v in spec.items() if k != "name"}
        name = spec["name"]
    else:
        raise ConfigError(f"a conformance problem is a registry name or a dict with 'name', got {spec!r}")
    problem = get_problem(name, **params)
    if _is_belt(problem):
        if "case" in params:
            raise ConfigError(f"the checks choose the case; remove 'case' from the problem {spec!r}")
        for case in (1, 2, 3, 4):
            get_problem(name, case=case, **params)
    return name, params


def _is_belt(problem) -> bool:
    """A belt oscillator with Coulomb friction (the friction family with a moving belt): the checks use its
    presets 1-4. With another friction law (e.g. ``one-dof`` at ``case='leine'``) the problem is checked as
    given, against ``reference``: presets 1 and 2 are no longer piecewise linear."""
    from nsbench.problems.oscillator import FrictionOscillator

    return isinstance(problem, FrictionOscillator) and problem.v0 > 0.0 and problem.law_spec.is_coulomb


def on_presets() -> bool:
    """Whether the checks run on the belt oscillators' presets (else on one problem as given)."""
    from nsbench.problems import get_problem

    name, params = FAMILY.get()
    return _is_belt(get_problem(name, **params))


@contextmanager
def checking_on(spec: str | dict[str, Any] | None) -> Iterator[tuple[str, dict[str, Any]]]:
    """Run the checks inside this block on the problem ``spec`` (see :func:`problem_family`)."""
    family = problem_family(spec)
    token = FAMILY.set(family)
    try:
        yield family
    finally:
        FAMILY.reset(token)


def _problem(case: int):
    """The belt's preset ``case``, or the problem as given when it has no presets."""
    from nsbench.problems import get_problem

    name, params = FAMILY.get()
    if not on_presets():
        return get_problem(name, **params)
    return get_problem(name, case=case, **params)


def _span(problem, belt: float) -> float:
    """``belt`` on the belt oscillators, the problem's own :attr:`~nsbench.problems.base.HybridProblem.check_span`
    (60 time scales unless it declares a shorter one) on any other problem."""
    return belt if on_presets() else problem.check_span


def _simulate(integ: Integrator, problem, t_end: float, **kwargs):
    from nsbench.engine import simulate

    # the checks compare each run with exact or reference themselves: no check points (their states
    # would be integrator work beside what the check measures)
    kwargs.setdefault("check_points", 0)
    return simulate(problem, integ, t_end, **kwargs)


class CheckSkipped(Exception):
    """Raised inside a check that cannot run on this problem (no reference for it): reported as skipped."""


def _reference_for(problem):
    """``reference``, set up on ``problem``; a problem it cannot solve skips the check (:class:`CheckSkipped`)."""
    from nsbench.integrators.reference import Reference

    ref = Reference()
    try:
        ref.setup(problem)
    except UnsupportedProblemError as exc:
        raise CheckSkipped(f"no reference for {problem.name}: {exc}") from None
    return ref


def given_options(integ: Integrator, options: dict[str, Any] | None = None) -> dict[str, Any]:
    """The options of a configuration that the user chose: ``options``, and the settings of
    ``integ`` that differ from the class defaults (a configured instance), validated.

    Raises
    ------
    ConfigError
        An unknown option or a bad value (the integrator's own message).
    """
    cls = type(integ)
    chosen = {k: v for k, v in integ.settings.items() if k in cls.options and v != cls.options[k].default}
    if options:
        settings = cls(**{**chosen, **options}).settings  # validates and converts
        chosen.update({k: settings[k] for k in options})
    return chosen


@contextmanager
def checking_with(options: dict[str, Any]) -> Iterator[dict[str, Any]]:
    """Run the checks inside this block with the user's ``options`` (see :func:`given_options`)."""
    token = GIVEN.set(dict(options))
    try:
        yield dict(options)
    finally:
        GIVEN.reset(token)


def describe(integ: Integrator) -> str:
    """The options of ``integ`` that were given or differ from its defaults, as ``'h=0.5, N=10'``
    (``'defaults'`` if none)."""
    cls, given = type(integ), GIVEN.get()
    parts = [
        f"{k}={v:g}" if isinstance(v, float) else f"{k}={v!r}" if isinstance(v, str) else f"{k}={v}"
        for k, v in integ.settings.items()
        if k in given or (k in cls.options and v != cls.options[k].default)
    ]
    return ", ".join(parts) or "defaults"


def configured(integ: Integrator) -> tuple[Integrator, str]:
    """The one configuration the single-configuration checks run (:data:`ONE_CONFIGURATION`), and how it was chosen.

    With options given by the user (:data:`GIVEN`): ``integ`` exactly as configured
    (the options not given at their defaults). Without: the *middle accuracy
    level*, ``accuracy_levels[len(accuracy_levels) // 2]`` over the defaults (the
    second of three levels, the third of four), or the defaults if the integrator
    declares no levels.
    """
    levels = type(integ).accuracy_levels
    if GIVEN.get():
        return integ, f"{describe(integ)} (the options given)"
    if not levels:
        return integ, "defaults (no accuracy levels declared)"
    index = len(levels) // 2
    middle = type(integ)(**{**integ.settings, **levels[index]})
    return middle, f"{describe(middle)} (middle accuracy level, {index + 1} of {len(levels)})"


def middle_level(integ: Integrator) -> Integrator:
    """The configuration of the single-configuration checks (see :func:`configured`)."""
    return configured(integ)[0]


def _compare_events(events, reference, bound: float, what: str, ran_with: str) -> float:
    from nsbench.engine import match_accumulation_tails

    # a Zeno tail is resolved as deep as each integrator's own accuracy allows before the rule
    # extrapolates: the two logs are compared as far as both resolved it (the accumulation events paired)
    events, reference = match_accumulation_tails(events, reference)
    got = list(zip(events["kind"], events["block"]))
    want = list(zip(reference["kind"], reference["block"]))
    if got != want:
        first = next((i for i, (a, b) in enumerate(zip(got, want)) if a != b), min(len(got), len(want)))
        saw = got[first] if first < len(got) else "no event"
        wanted = want[first] if first < len(want) else "no event"
        raise AssertionError(
            f"at {ran_with}: event sequence differs from {what} at event {first}: got (kind, block) {saw}, "
            f"{what} has {wanted}; {len(got)} events against {len(want)}"
        )
    err = float(np.max(np.abs(events["t"].to_numpy() - reference["t"].to_numpy()))) if got else 0.0
    assert err <= bound, f"at {ran_with}: event times differ from {what} by {err:.3g} > {bound:g}"
    return err


def _same(a: Any, b: Any) -> bool:
    """Equal, two NaNs counting as equal (an event log holds NaN where a column does not apply)."""
    both_nan = isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b)
    return both_nan or a == b


def _log_diff(first, other) -> str:
    """Where two event logs part: their lengths and the first row that differs."""
    if len(first) != len(other):
        return f"{len(first)} events against {len(other)}"
    for i in range(len(first)):
        a, b = first.iloc[i].to_dict(), other.iloc[i].to_dict()
        if a != b:
            cols = {k: (a[k], b.get(k)) for k in a if not _same(a[k], b.get(k))}
            if cols:
                return f"event {i} differs in {cols}"
    return "same rows, different columns or types"


# ---------------------------------------------------------------------- the checks
def check_protocol_and_counters(integ: Integrator) -> None:
    """Class attributes, one arc through ``advance``, and honest counters on a full run."""
    cls = type(integ)
    assert re.fullmatch(r"[a-z0-9]+(-[a-z0-9]+)*", cls.name or ""), f"name {cls.name!r} is not kebab-case"
    caps = cls.capabilities
    assert isinstance(caps, Capabilities), f"capabilities is a {type(caps).__name__}, not a Capabilities instance"
    assert caps.precision in PRECISIONS, f"precision {caps.precision!r} not in {PRECISIONS}"
    assert caps.event_location, f"capabilities.event_location is {caps.event_location!r}: say how events are located"
    loose = {k: type(o).__name__ for k, o in cls.options.items() if not isinstance(o, Option)}
    assert not loose, f"options {loose} are not Option declarations"
    if caps.step_option is not None:
        assert caps.step_option in cls.options, f"step_option {caps.step_option!r} is not an option"
    for level in cls.accuracy_levels:
        assert set(level) <= set(cls.options), (
            f"accuracy level {level} names unknown options {sorted(set(level) - set(cls.options))}"
        )
        cls(**{**integ.settings, **level})
    problem = _problem(2)
    integ.setup(problem)
    if is_whole_system(integ):
        _check_whole_protocol(integ, problem)
    else:
        _check_one_arc(integ, problem)
    res = _simulate(integ, problem, _span(problem, 30.0))
    assert res.ok, f"run failed: {res.message}"
    c = res.counters
    assert c.nsteps > 0 or c.nfev > 0, "no work reported: nsteps and nfev are both 0"
    negative = {k: v for k, v in (("nfev", c.nfev), ("njev", c.njev), ("nsteps", c.nsteps)) if v < 0}
    assert not negative, f"negative counters {negative}: a counter counts work done, from 0"
    if caps.needs_jacobian and on_presets():
        # on the belt every such method evaluates it; elsewhere a method that takes a Jacobian only once
        # the problem turns stiff (LSODA on the falling ball) may rightly evaluate none
        assert c.njev > 0, "declares needs_jacobian but reports njev = 0"
    for key, value in c.extra.items():
        assert isinstance(value, (int, float)) and math.isfinite(value), f"extra counter {key} = {value!r}"


def _check_whole_protocol(integ, problem) -> None:
    """One call of ``integrate`` of a whole-system method keeps the protocol (:mod:`nsbench.integrators.whole`)."""
    from nsbench.integrators.whole import SystemRequest, check_result

    # the family is what the scheme is: usually time-stepping, switch-model or smoothing, but an external
    # engine that locates its own events over the whole system (Siconos's EventDriven) is event-driven
    # (Capabilities checks that it is one of FAMILIES)
    t_eval = np.array([0.01, 0.02, 5.0])
    request = SystemRequest(problem=problem, t0=0.0, y0=problem.initial_state(), t_end=5.0, t_eval=t_eval)
    res = integ.integrate(request)
    broken = check_result(type(integ).name, request, res, problem.n_states, problem.mode_size)
    assert not broken, f"integrate broke the SystemResult protocol: {broken}"
    assert res.status.ok, f"integrate failed over [0, 5]: {res.message}"


def _check_one_arc(integ, problem) -> None:
    """One arc through ``advance`` keeps the protocol."""
    mode = problem.initial_mode(0.0, problem.initial_state())
    t_eval = np.array([0.01, 0.02, 5.0])
    arc = integ.advance(
        ArcRequest(
            problem=problem,
            mode=mode,
            t0=0.0,
            y0=problem.initial_state(),
            t_end=5.0,
            guards=problem.guards(mode),
            t_eval=t_eval,
        )
    )
    assert isinstance(arc, ArcResult), f"advance returned {type(arc).__name__}, not ArcResult"
    assert isinstance(arc.status, Status) and arc.status.ok, f"first arc failed: {arc.message}"
    assert 0.0 < arc.t <= 5.0, f"first arc over [0, 5] stopped at t = {arc.t!r}, outside (0, 5]"
    assert np.shape(arc.y) == (problem.n_states,), (
        f"arc.y has shape {np.shape(arc.y)}, expected (n_states,) = ({problem.n_states},)"
    )
    if on_presets():
        assert arc.fired is not None and 0 <= arc.fired < len(problem.guards(mode)), (
            f"the first arc of case 2 ends at a guard (block 2 sticks at t ~ 0.067); got fired = {arc.fired!r} "
            f"at t = {arc.t:.6g} of {len(problem.guards(mode))} guards"
        )
    else:
        assert arc.fired is None or 0 <= arc.fired < len(problem.guards(mode)), f"fired = {arc.fired}: no such guard"
    expected = int(np.searchsorted(t_eval, arc.t, side="right"))
    shape = np.shape(arc.y_eval)
    assert shape != (expected, problem.n_states) or expected == problem.n_states, (
        f"y_eval has shape {shape}: transposed? It must be (n_states, n_points) = "
        f"({problem.n_states}, {expected}), one column per time of t_eval <= t"
    )
    assert shape == (problem.n_states, expected), (
        f"y_eval has shape {shape}, expected (n_states, n_points) = ({problem.n_states}, {expected}): "
        f"one column per time of t_eval <= t = {arc.t:.6g}"
    )


def check_determinism(integ: Integrator) -> None:
    """The same run twice (same instance, then a fresh copy) gives identical events and counters."""
    problem = _problem(2)
    span = _span(problem, 20.0)
    runs = [
        _simulate(integ, problem, span),
        _simulate(integ, problem, span),
        _simulate(type(integ).from_config(integ.config()), problem, span),
    ]
    for other in runs[1:]:
        assert other.events.equals(runs[0].events), (
            f"event logs differ between identical runs: {_log_diff(runs[0].events, other.events)}"
        )
        a, b = runs[0].counters.as_dict(), other.counters.as_dict()
        diff = {k: (a.get(k), b.get(k)) for k in sorted(set(a) | set(b)) if a.get(k) != b.get(k)}
        assert not diff, f"counters differ between identical runs (first run, other run): {diff}"


def check_inputs_not_mutated(integ: Integrator) -> None:
    """``advance`` leaves the request's state and times alone (given writable copies)."""
    problem = _problem(2)
    integ.setup(problem)
    if on_presets():
        y0, scale = np.resize([0.2, -0.1, 0.3, 0.05], problem.n_states), 1.0
    else:
        y0, scale = problem.initial_state().copy(), problem.time_scale
    t_eval = np.linspace(0.1, 3.0, 7) * scale
    saved = (y0.copy(), t_eval.copy())
    if is_whole_system(integ):
        from nsbench.integrators.whole import SystemRequest

        integ.integrate(SystemRequest(problem=problem, t0=0.0, y0=y0, t_end=3.0 * scale, t_eval=t_eval))
        assert np.array_equal(y0, saved[0]), f"integrate changed request.y0 from {saved[0]} to {y0}"
        assert np.array_equal(t_eval, saved[1]), f"integrate changed request.t_eval from {saved[1]} to {t_eval}"
        return
    mode = problem.initial_mode(0.0, y0)
    integ.advance(
        ArcRequest(
            problem=problem, mode=mode, t0=0.0, y0=y0, t_end=3.0 * scale, guards=problem.guards(mode), t_eval=t_eval
        )
    )
    assert np.array_equal(y0, saved[0]), f"advance changed request.y0 from {saved[0]} to {y0}"
    assert np.array_equal(t_eval, saved[1]), f"advance changed request.t_eval from {saved[1]} to {t_eval}"


def _smooth_error(integ: Integrator) -> float:
    """End-state error of one smooth arc, against the closed form.

    Without the belt's presets: the problem's first arc from its start state,
    over half the time ``reference`` takes to its first guard (or its
    ``check_span``), against ``reference``. On the belt: case 1 over 4 time units,
    against ``exact``; every block slips backwards near the mode's equilibrium (spring ``i`` carries
    the kinetic friction of blocks ``i..n``: for two blocks x1 = rf1 + rf2,
    x2 = x1 + rf2) with speeds well below the belt's, so no guard fires.
    """
    from nsbench.integrators.exact import ExactIntegrator

    if not on_presets():
        if is_whole_system(integ):
            raise CheckSkipped("the smooth arc of a whole-system method is checked on the belt's presets only")
        return _first_arc_error(integ)
    problem = _problem(1)
    c = problem.coefficients
    nb = problem.n_blocks
    y0 = np.zeros(problem.n_states)
    x = 0.0
    for i in range(nb):
        x += sum(c.fs[i:]) / c.k[i]  # the equilibrium of the linear springs
        y0[2 * i] = x + (0.02 if i % 2 == 0 else -0.02)
    y0[-1] = 0.01
    mode = (-1,) * nb
    request = ArcRequest(problem=problem, mode=mode, t0=0.0, y0=y0, t_end=4.0, guards=problem.guards(mode))
    exact = ExactIntegrator()
    exact.setup(problem)
    if is_whole_system(integ):  # the whole system over the arc: no switch may be inferred on it
        res = _simulate(integ, problem, 4.0, y0=y0)
        assert res.ok and len(res.events) == 0, (
            f"at {describe(integ)}: smooth arc did not stay smooth: {res.message or list(res.events['kind'])}"
        )
        return float(np.max(np.abs(res.y_final - exact.advance(request).y)))
    integ.setup(problem)
    arc = integ.advance(request)
    assert arc.status.ok and arc.fired is None and arc.t == 4.0, (
        f"at {describe(integ)}: smooth arc did not reach its end: "
        f"{arc.message or f'guard {arc.fired} fired at {arc.t}'}"
    )
    return float(np.max(np.abs(arc.y - exact.advance(request).y)))


def _first_arc_error(integ: Integrator) -> float:
    problem = _problem(0)
    ref = _reference_for(problem)
    y0 = problem.initial_state()
    mode = problem.initial_mode(0.0, y0)
    span = problem.check_span
    first = ref.advance(ArcRequest(problem=problem, mode=mode, t0=0.0, y0=y0, t_end=span, guards=problem.guards(mode)))
    t_end = span if first.fired is None else 0.5 * first.t
    request = ArcRequest(problem=problem, mode=mode, t0=0.0, y0=y0, t_end=t_end, guards=problem.guards(mode))
    integ.setup(problem)
    arc = integ.advance(request)
    assert arc.status.ok and arc.fired is None and arc.t == t_end, (
        f"at {describe(integ)}: smooth arc did not reach its end: "
        f"{arc.message or f'guard {arc.fired} fired at {arc.t}'}"
    )
    return float(np.max(np.abs(arc.y - ref.advance(request).y)))


def _around(integ: Integrator, value: float) -> list[dict[str, Any]]:
    """Three values of the step option from loose to tight around ``value`` (a factor 4 apart for a
    fixed step, 1000 for a tolerance), the looser or tighter side moved inwards where the option's range ends."""
    cls, name = type(integ), type(integ).capabilities.step_option
    factor = 4.0 if not cls.capabilities.adaptive else 1e3
    option = cls.options[name]

    def allowed(v: float) -> bool:
        try:
            option.check(cls.name, name, v)
        except ConfigError:
            return False
        return True

    for candidates in (
        [value * factor, value, value / factor],
        [value, value / factor, value / factor**2],
        [value * factor**2, value * factor, value],
    ):
        if all(allowed(v) for v in candidates):
            return [{name: v} for v in candidates]
    raise ConfigError(
        f"{cls.name}: no three values of {name} a factor {factor:g} apart around {value:g} fit the option's range"
    )


def step_levels(integ: Integrator) -> tuple[list[dict[str, Any]], str]:
    """The configurations of the stepped checks (:data:`STEPPED`), loose to tight, and how they were chosen.

    Each is ``integ``'s settings with the level on top. Without options given by
    the user: the declared accuracy levels (two or more), else three values of
    the step option around its default. With the step option given: three values
    around it (the given one in the middle), every other option as configured.
    With other options given: the declared levels with the given options on top.
    """
    cls, name = type(integ), type(integ).capabilities.step_option
    given = GIVEN.get()
    declared = [dict(level) for level in cls.accuracy_levels]
    if name in given:
        levels, why = _around(integ, float(given[name])), f"around the given {name}"
    elif len(declared) >= 2:
        levels = [{**level, **{k: v for k, v in given.items() if k in level}} for level in declared]
        why = "the declared accuracy levels" + (" with the options given" if given else "")
    else:
        levels = _around(integ, float(integ.settings[name] or cls.options[name].default or 1e-6))
        why = f"around the configured {name}"
    shown = ", ".join(f"{level[name]:g}" for level in levels)
    others = {k for k in given if k != name}
    return levels, f"{name} = {shown} ({why})" + (f", with {describe(integ)}" if others else "")


def check_declared_order(integ: Integrator) -> None:
    """Step halving on a smooth arc shows the declared convergence order (within 0.6)."""
    caps, name = type(integ).capabilities, type(integ).capabilities.step_option
    levels, ran_with = step_levels(integ)
    steps, errors = [], []
    for level in levels:
        errors.append(_smooth_error(type(integ)(**{**integ.settings, **level})))
        steps.append(float(level[name]))
    floor = 1e-12
    orders = [
        math.log(errors[i] / errors[i + 1]) / math.log(steps[i] / steps[i + 1])
        for i in range(len(errors) - 1)
        if errors[i + 1] > floor
    ]
    if not orders:
        assert max(errors) <= floor, f"at {ran_with}: errors {errors} do not decrease"
        return  # already at rounding level at every step: accurate beyond measurement
    declared = integ.smooth_order() if is_whole_system(integ) else caps.order
    assert abs(orders[-1] - declared) <= 0.6, (
        f"at {ran_with}: observed order {orders[-1]:.2f} (errors {errors}) against declared {declared}"
    )


def check_convergence(integ: Integrator) -> None:
    """Tightening the step option (loose to tight) never makes a smooth arc less accurate."""
    levels, ran_with = step_levels(integ)
    errors = [_smooth_error(type(integ)(**{**integ.settings, **lv})) for lv in levels]
    for a, b in zip(errors, errors[1:]):
        assert b <= max(a, 1e-12) * 1.5, f"at {ran_with}: errors {errors} grow as the step option tightens"
    assert errors[-1] < CONVERGED_BOUND, (
        f"at {ran_with}: tightest level still has error {errors[-1]:.3g} >= {CONVERGED_BOUND:g}"
    )


def check_event_times(integ: Integrator) -> None:
    """Event sequence and times of case 2 over [0, 60] within :data:`EVENT_BOUND` of ``exact`` (:func:`configured`);
    without the belt's presets, of the problem over its ``check_span`` against ``reference``."""
    from nsbench.integrators.exact import ExactIntegrator

    problem = _problem(2)
    span = _span(problem, 60.0)
    if on_presets():
        ref, what = _simulate(ExactIntegrator(), problem, span), "exact"
    else:
        ref, what = _simulate(_reference_for(problem), problem, span), "reference"
    assert ref.ok, f"the {what} run failed: {ref.message}"
    run, ran_with = configured(integ)
    res = _simulate(run, problem, span)
    assert res.ok, f"at {ran_with}: {res.message}"
    _compare_events(res.events, ref.events, EVENT_BOUND, what, ran_with)


def check_cubic_event_times(integ: Integrator) -> None:
    """Case 4 (cubic springs, forced) over [0, 30] within :data:`EVENT_BOUND` of ``reference`` (:func:`configured`)."""
    from nsbench.integrators.reference import Reference

    problem = _problem(4)
    ref = _simulate(Reference(), problem, 30.0).events
    run, ran_with = configured(integ)
    res = _simulate(run, problem, 30.0)
    assert res.ok, f"at {ran_with}: {res.message}"
    _compare_events(res.events, ref, EVENT_BOUND, "reference", ran_with)


def check_refuses_unsupported_problems(integ: Integrator) -> None:
    """A linear-only integrator refuses cubic springs with ``UnsupportedProblemError``."""
    try:
        integ.setup(_problem(3))
    except UnsupportedProblemError:
        return
    raise AssertionError("declares supports_nonlinear=False but accepts a cubic problem")


def check_stuck_block_stays_stuck(integ: Integrator) -> None:
    """Every block stuck inside its sliding region: no event until block 1 slips, no drift."""
    problem = _problem(1)
    v0 = problem.v0
    # every block at x = 0.3: only the ground spring is stretched, so R1 ~ 0.304 grows at v0
    # per time unit, reaching 1 at t ~ 8.35, and the other blocks feel only their damping
    y0 = [0.3, v0] * problem.n_blocks
    grid = np.linspace(0.0, 8.0, 161)
    run, ran_with = configured(integ)
    res = _simulate(run, problem, 10.0, y0=y0, t_eval=grid)
    assert res.ok, f"at {ran_with}: {res.message}"
    ev = res.events
    assert len(ev) >= 1 and (ev["kind"].iloc[0], ev["block"].iloc[0]) == ("slip", 1), (
        f"at {ran_with}: expected block 1 to slip first, got {list(zip(ev['kind'], ev['block']))[:3]}"
    )
    t_slip = (1.0 - problem.coefficients.c[0] * v0 - 0.3) / v0  # R1 is linear in t while stuck
    assert abs(ev["t"].iloc[0] - t_slip) < SLIP_BOUND, (
        f"at {ran_with}: slip at {ev['t'].iloc[0]:.9g}, expected {t_slip:.9g}"
    )
    tr = res.trajectory
    blocks = range(1, problem.n_blocks + 1)
    assert all((tr[f"phase{b}"] == 0).all() for b in blocks), f"at {ran_with}: a stuck block left stick before t = 8"
    drift = max(max(np.abs(tr[f"v{b}"] - v0).max() for b in blocks), np.abs(tr["x1"] - (0.3 + v0 * tr["t"])).max())
    assert drift <= DRIFT_BOUND, f"at {ran_with}: stuck blocks drift by {drift:.3g} from the belt"


def check_energy_balance(integ: Integrator) -> None:
    """Energy change equals the work of friction, damping and force along case 2's trajectory."""
    from nsbench.energy import energy_balance

    problem = _problem(2)
    run, ran_with = configured(integ)
    res = _simulate(run, problem, 40.0, t_eval=np.linspace(0.0, 40.0, 4001))
    assert res.ok, f"at {ran_with}: {res.message}"
    worst = float(energy_balance(res)["residual"].abs().max())
    assert worst <= ENERGY_BOUND, f"at {ran_with}: energy-balance residual {worst:.3g} > {ENERGY_BOUND:g}"


def check_failure_is_a_status(integ: Integrator) -> None:
    """An exhausted step budget ends the run with a status and a message, never an exception."""
    problem = _problem(2)
    span = _span(problem, 300.0)
    res = _simulate(integ, problem, span, max_steps=3)
    if res.ok and res.counters.nsteps <= 3:  # a field the method integrates in one step per arc (constant)
        raise CheckSkipped(
            f"the whole run over [0, {span:g}] takes {res.counters.nsteps} steps: no budget of 3 to exhaust"
        )
    assert not res.ok, f"a budget of 3 steps did not stop a run over [0, {span:g}]"
    assert res.status in (Status.BUDGET_EXHAUSTED, Status.INTEGRATOR_FAILURE), (
        f"a budget of 3 steps ended the run as {res.status.value!r}, expected "
        f"{Status.BUDGET_EXHAUSTED.value!r} (or {Status.INTEGRATOR_FAILURE.value!r})"
    )
    assert res.message, f"the run ended as {res.status.value!r} with an empty message: say what stopped it"
    assert res.t_final < span, f"the run ended as {res.status.value!r} at t_final = {res.t_final:g}, its end {span:g}"


def check_config_round_trip(integ: Integrator) -> None:
    """``config()`` is a small JSON-able dict that rebuilds an equal integrator; bad options are refused."""
    cls = type(integ)
    for level in [{}, *cls.accuracy_levels]:
        one = cls(**{**integ.settings, **level})
        config = one.config()
        assert config["name"] == cls.name, f"config() names {config['name']!r}, the class is {cls.name!r}"
        assert set(config["options"]) == set(cls.options), (
            f"config() has options {sorted(config['options'])}, the class declares {sorted(cls.options)}"
        )
        text = json.dumps(config)
        again = cls.from_config(json.loads(text))
        assert type(again) is cls and again.config() == config, f"{config} does not round-trip"
    try:
        cls(**{"no_such_option_name": 1})
    except ConfigError:
        pass
    else:
        raise AssertionError("an unknown option was accepted")


def check_problem_config(integ: Integrator) -> None:
    """The problem's ``config()`` rebuilds it (the same parameter vector and start state at every case it
    names), and the rates it declares hold on its field."""
    from nsbench.testing._problem import problem_failures

    name, params = FAMILY.get()
    failures = problem_failures(name, params)
    assert not failures, f"{len(failures)} variant(s) of {name} fail the problem checks: " + "; ".join(failures)


def check_switch_convergence(integ: Integrator) -> None:
    """Whole-system methods: from the loosest accuracy level to the tightest, the switching times of case 1 over
    [0, 20] approach ``exact``'s, and the tightest level has ``exact``'s event sequence."""
    from nsbench.integrators.exact import ExactIntegrator

    levels = [dict(level) for level in type(integ).accuracy_levels]
    assert len(levels) >= 2, "a whole-system method declares at least two accuracy levels, loose to tight"
    problem = _problem(1)
    ref = _simulate(ExactIntegrator(), problem, 20.0).events
    errors = []
    for level in (levels[0], levels[-1]):
        run = type(integ)(**{**integ.settings, **level})
        res = _simulate(run, problem, 20.0)
        assert res.ok, f"at {describe(run)}: {res.message}"
        same = list(zip(res.events["kind"], res.events["block"])) == list(zip(ref["kind"], ref["block"]))
        errors.append(float(np.max(np.abs(res.events["t"].to_numpy() - ref["t"].to_numpy()))) if same else math.inf)
    assert math.isfinite(errors[1]), f"at the tightest level {levels[-1]}: event sequence differs from exact"
    assert errors[1] < errors[0], (
        f"switching-time error {errors[1]:.3g} at {levels[-1]} is not below {errors[0]:.3g} at {levels[0]}"
    )


@dataclass(frozen=True)
class Check:
    """A named check and the capability test that decides whether it applies."""

    name: str
    run: Callable[[Integrator], None]
    applies: Callable[[Capabilities], str | None] = lambda caps: None  # a reason when it does not apply
    #: Runs on the belt oscillators' presets only (stuck phases, cubic springs, the energy balance).
    belt: bool = False
    #: Runs the integrator on the problem (False: a check of configurations alone), so a kit run
    #: in which every such check was skipped has checked nothing of the integrator's results.
    runs: bool = True

    def skip_reason(self, caps: Capabilities) -> str | None:
        """Why this check does not run here (capabilities, or a problem without the belt's presets), or None."""
        reason = self.applies(caps)
        if reason is None and self.belt and not on_presets():
            name, params = FAMILY.get()
            reason = f"needs the belt oscillators' presets (cases 1-4); {name} has none"
            if params:  # e.g. one-dof at case='leine': a belt, but its law leaves the presets' Coulomb friction
                given = ", ".join(f"{k}={v!r}" for k, v in params.items())
                reason = f"needs the Coulomb belt presets (cases 1-4); {name} ({given}) runs as given"
        return reason

    @property
    def doc(self) -> str:
        return (self.run.__doc__ or "").strip().splitlines()[0]


def _needs(test: Callable[[Capabilities], bool], reason: str) -> Callable[[Capabilities], str | None]:
    return lambda caps: None if test(caps) else reason


CHECKS: tuple[Check, ...] = (
    Check("protocol", check_protocol_and_counters),
    Check("determinism", check_determinism),
    Check("inputs-not-mutated", check_inputs_not_mutated),
    Check(
        "switch-convergence",
        check_switch_convergence,
        _needs(lambda c: c.family != "event-driven", "event-driven: its event location is checked by event-times"),
        belt=True,
    ),
    Check(
        "declared-order",
        check_declared_order,
        _needs(
            lambda c: c.order is not None and c.step_option is not None and not c.adaptive,
            "no fixed order with a step-size option declared",
        ),
    ),
    Check(
        "convergence",
        check_convergence,
        _needs(lambda c: c.step_option is not None, "no step or tolerance option declared"),
    ),
    Check("event-times", check_event_times),
    Check(
        "cubic-event-times",
        check_cubic_event_times,
        _needs(lambda c: c.supports_nonlinear, "linear problems only"),
        belt=True,
    ),
    Check(
        "refuses-unsupported",
        check_refuses_unsupported_problems,
        _needs(lambda c: not c.supports_nonlinear, "supports cubic springs"),
        belt=True,
    ),
    Check("stuck-stays-stuck", check_stuck_block_stays_stuck, belt=True),
    Check("energy-balance", check_energy_balance, belt=True),
    Check("failure-status", check_failure_is_a_status),
    Check("config-round-trip", check_config_round_trip, runs=False),
    Check("problem-config", check_problem_config, runs=False),
)
