"""The ``Integrator`` protocol: what every integrator, built-in or plug-in, implements.

The hybrid engine (:mod:`nsbench.engine`) owns the stick/slip/reverse logic; an
integrator owns how it advances one *frozen-mode* vector field and how it
locates the crossings of that mode's guards, since that is what nsbench measures.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np

from nsbench.errors import ConfigError, UnsupportedProblemError
from nsbench.status import Status

if TYPE_CHECKING:  # pragma: no cover
    from nsbench.model.abi import RunLimits, RunState, Sections
    from nsbench.model.records import Records
    from nsbench.problems.base import Guard, HybridProblem, Mode
    from nsbench.sections import StateSection


#: The four families of methods for non-smooth systems (Leine & Nijmeijer; Acary & Brogliato).
FAMILIES = ("event-driven", "time-stepping", "switch-model", "smoothing")


@dataclass(frozen=True)
class Capabilities:
    """Tags that generic code (runner, conformance kit) branches on, never names.

    Attributes
    ----------
    event_location
        How guard crossings are located: ``'exact-root'``, ``'dense-output-root'``,
        ``'henon'``, ``'collocation-newton'``, ``'taylor-root'``, ...
    order
        Convergence order of the method for smooth problems, ``None`` if it is
        not a fixed-order method (exact, variable-order).
    adaptive
        Whether the step size is chosen from error estimates.
    needs_jacobian
        Whether the method evaluates the mode Jacobian.
    supports_nonlinear
        Whether it may run on cubic-spring problems.
    precision
        Floating-point arithmetic of the core: ``'double'``, ``'long double'``, ``'quad'``,
        ``'mp'`` (arbitrary precision, mpmath).
    step_option
        Name of the option that sets the step/tolerance for convergence studies
        (``'h'`` for fixed-step methods, ``'rtol'`` for adaptive ones), or ``None``.
    reference_grade
        A reference solution (a closed form, or extended precision at its
        tightest), not a method under test: reports show it apart and never rank it.
    family
        The family of numerical methods for non-smooth systems it belongs to
        (:data:`FAMILIES`): ``'event-driven'`` (locates every switch, integrates
        one frozen mode per arc: this protocol), or a whole-system method
        (:class:`nsbench.integrators.whole.WholeSystem`): ``'time-stepping'``,
        ``'switch-model'``, ``'smoothing'``.
    checks_steps
        Whether the integrator checks every guard on every accepted step itself, so
        that a crossing pair inside one step is located, not stepped over: its sign
        at both ends and an extremum test on the step's interpolant (or a rigorous
        bound on the step). The engine then adds no check points of its own
        (:func:`nsbench.engine.run`); an integrator that finds only the sign changes
        between step ends (the default, for a plug-in) is checked at evenly spaced
        states instead (docs/core.md, "Missed events").
    accepts
        The problems it runs, by their declared traits
        (:class:`~nsbench.problems.base.Traits` field names): it accepts a problem that declares any
        of them and refuses, at set-up and with the reason, one that declares none. ``None`` (the
        default): every problem, through its hybrid law (``rhs``, guards, transitions). A
        whole-system method (:class:`nsbench.integrators.whole.WholeSystem`) must name traits whose
        events nsbench infers from its steps; with ``None`` it takes blocks on a belt only.
        ``nsbench list coverage`` shows the problems each integrator accepts and why it refuses the
        others.
    """

    event_location: str
    order: int | None
    adaptive: bool
    needs_jacobian: bool = False
    supports_nonlinear: bool = True
    precision: str = "double"
    step_option: str | None = None
    reference_grade: bool = False
    family: str = "event-driven"
    checks_steps: bool = False
    accepts: tuple[str, ...] | None = None

    def __post_init__(self) -> None:
        if self.family not in FAMILIES:
            raise ConfigError(f"capabilities: family {self.family!r} is not one of {', '.join(FAMILIES)}")
        if self.accepts is not None:
            from nsbench.problems.base import TRAIT_NAMES

            ok = isinstance(self.accepts, tuple) and self.accepts and all(t in TRAIT_NAMES for t in self.accepts)
            if not ok:
                raise ConfigError(
                    f"capabilities: accepts = {self.accepts!r} must be a non-empty tuple of trait names "
                    f"({', '.join(TRAIT_NAMES)}), or None for every problem"
                )


#: What a whole-system method that declares no ``accepts`` runs: the friction oscillators, whose
#: events :func:`nsbench.hybrid.inference.infer_events` infers from the blocks' phases.
WHOLE_SYSTEM_ACCEPTS: tuple[str, ...] = ("belt_blocks",)


def accepted_traits(integ: "Integrator | type[Integrator]") -> tuple[str, ...] | None:
    """The traits of the problems ``integ`` runs (any of them), or ``None`` for every problem: its
    :attr:`Capabilities.accepts`, or :data:`WHOLE_SYSTEM_ACCEPTS` for a whole-system method that
    declares none."""
    accepts = integ.capabilities.accepts
    if accepts is None and getattr(integ, "whole_system", False):
        return WHOLE_SYSTEM_ACCEPTS
    return accepts


def refuse_without_traits(integ: "Integrator", problem: "HybridProblem", accepts: tuple[str, ...]) -> None:
    """Raise :class:`UnsupportedProblemError` unless ``problem`` declares one of the traits ``accepts``."""
    from nsbench.problems.base import Traits, problem_traits

    if problem_traits(problem).has_any(accepts):
        return
    raise UnsupportedProblemError(
        f"{integ.name} runs problems with {Traits.words(accepts)} only (Capabilities.accepts); "
        f"{problem.name} declares none of these traits"
    )


@dataclass(frozen=True)
class Option:
    """Declaration of one integrator option: default, type and allowed range."""

    default: Any
    kind: type = float
    lower: float | None = None
    lower_inclusive: bool = False
    upper: float | None = None
    choices: tuple[Any, ...] | None = None
    nullable: bool = False
    doc: str = ""
    #: Whether ``inf`` is allowed, meaning no limit (a largest step); other numbers must be finite.
    unbounded: bool = False

    def check(self, owner: str, name: str, value: Any) -> Any:
        """Return ``value`` converted to ``kind``, or raise a ``ConfigError`` naming it."""
        if value is None and self.nullable:
            return None
        if self.choices is not None:
            if value not in self.choices:
                raise ConfigError(
                    f"{owner}: option {name} = {value!r} is not allowed; choose one of "
                    + ", ".join(repr(c) for c in self.choices)
                )
            return value
        if self.kind in (int, float):
            if isinstance(value, bool):
                raise ConfigError(f"{owner}: option {name} = {value!r} must be a number")
            try:
                number = float(value)
            except (TypeError, ValueError):
                raise ConfigError(f"{owner}: option {name} = {value!r} is not a number") from None
            if math.isnan(number) or (math.isinf(number) and not (self.unbounded and self.kind is float)):
                raise ConfigError(f"{owner}: option {name} = {value!r} must be a finite number")
            if self.kind is int:
                if number != int(number):
                    raise ConfigError(f"{owner}: option {name} = {value!r} must be an integer")
                number = int(number)
            if self.lower is not None:
                bad = number < self.lower if self.lower_inclusive else number <= self.lower
                if bad:
                    op = ">=" if self.lower_inclusive else ">"
                    raise ConfigError(f"{owner}: option {name} = {value!r} must be {op} {self.lower:g}")
            if self.upper is not None and number > self.upper:
                raise ConfigError(f"{owner}: option {name} = {value!r} must be <= {self.upper:g}")
            return number
        if not isinstance(value, self.kind):
            raise ConfigError(f"{owner}: option {name} = {value!r} must be of type {self.kind.__name__}")
        return value


@dataclass(frozen=True, eq=False)
class ArcRequest:
    """One call of :meth:`Integrator.advance`: integrate ``mode`` from ``(t0, y0)``.

    Attributes
    ----------
    problem
        The problem (vector field, Jacobian, guards).
    mode
        The frozen mode of this arc.
    t0, y0
        Start of the arc. ``y0`` is read-only; a phase starts on its own
        surface, so a guard may be exactly zero at ``t0``.
    t_end
        Stop here if no guard fires first.
    guards
        Guards of ``mode``, ordered by block, with their expected signs.
    sections
        Non-terminal state sections to record (they never stop the arc).
    t_eval
        Sorted times in ``(t0, t_end]`` where states are wanted (trajectory and
        stroboscopic sections), from the integrator's dense output or steps.
    max_steps
        Step budget left for the whole run.
    t0_lo
        Low-order part of the start time: the arc starts at the exact sum
        ``t0 + t0_lo`` (``|t0_lo|`` at most an ulp of ``t0``). The engine keeps
        event times in this compensated form so that the rounding of ``t0`` to a
        double does not accumulate over many events; integrators that measure
        time from the arc start may use it (and report ``ArcResult.t_lo``),
        others ignore it.
    sections_from
        Crossings of ``sections`` before this time are not wanted (a sweep's
        transient): the core drops them. An integrator may skip looking for
        them there, which costs nothing in accuracy; one that reports them
        anyway is still right. ``-inf``: every crossing is wanted.
    """

    problem: "HybridProblem"
    mode: "Mode"
    t0: float
    y0: np.ndarray
    t_end: float
    guards: tuple["Guard", ...]
    sections: tuple["StateSection", ...] = ()
    t_eval: np.ndarray = field(default_factory=lambda: np.empty(0))
    max_steps: int = 10**7
    t0_lo: float = 0.0
    sections_from: float = -math.inf

    def rhs(self, t, y):
        """The frozen-mode vector field of this arc."""
        return self.problem.rhs(self.mode, t, y)

    def jacobian(self, t, y):
        """The frozen-mode Jacobian of this arc."""
        return self.problem.jacobian(self.mode, t, y)


@dataclass(frozen=True)
class SectionHit:
    """A crossing of ``request.sections[index]`` at ``(t, y)``."""

    index: int
    t: float
    y: np.ndarray


@dataclass
class ArcResult:
    """What :meth:`Integrator.advance` returns.

    Attributes
    ----------
    t, y
        Where the arc stopped: the located event time and state (before the
        transition), or ``t_end``.
    fired
        Index into ``request.guards`` of the guard that fired, or ``None`` if the
        arc reached ``t_end``. If several fire at the same time, the lowest index.
    y_eval
        States at every ``request.t_eval`` that is ``<= t``: a float array of
        shape ``(n_states, n_points)``, one *column* per time (``y_eval[:, j]``
        is the state at the ``j``-th such time; ``np.empty((n_states, 0))`` when
        there is none). Not ``(n_points, n_states)``: the conformance kit
        reports a transposed array as such.
    section_hits
        Crossings of ``request.sections`` in ``(t0, t]``, in time order.
    nfev, njev, nsteps
        Cost of this arc: right-hand-side and Jacobian evaluations (each state
        counts one, also in vectorised calls), steps or segments.
    extra
        Integrator-specific counters (summed over arcs by the engine).
    status, message
        ``Status.SUCCESS``, or the failure and its reason.
    t_lo
        Optional low-order part of an event time: the event is at ``t + t_lo``
        (see ``ArcRequest.t0_lo``); 0 when not computed.
    """

    t: float
    y: np.ndarray
    fired: int | None
    y_eval: np.ndarray
    section_hits: list[SectionHit] = field(default_factory=list)
    nfev: int = 0
    njev: int = 0
    nsteps: int = 0
    extra: dict[str, float] = field(default_factory=dict)
    status: Status = Status.SUCCESS
    message: str = ""
    t_lo: float = 0.0


#: Values of the ``loop`` option (:data:`LOOP_OPTION`): who runs the event loop.
LOOPS = ("auto", "native", "per-arc")
#: How a run went through the core, as recorded on the result (``SimulationResult.loop``) and the bench rows:
#: the integrator's own loop (:meth:`Integrator.run`), the core's loop with one ``advance`` per arc, the
#: core's loop with a compiled arc kernel, or a whole-system method (:mod:`nsbench.integrators.whole`).
LOOP_PATHS = ("native", "per-arc", "kernel", "whole-system")

#: The option an integrator with a whole-run path declares (as ``options["loop"]``), so that a config, a
#: bench row and a suite can force either path and compare them.
LOOP_OPTION = Option(
    "auto",
    str,
    choices=LOOPS,
    doc=(
        "who runs the event loop: 'auto' (the integrator's own, where it can: the run records which), "
        "'native' (the integrator's own, forced), 'per-arc' (the hybrid core's, one advance per arc)"
    ),
)


@dataclass(frozen=True, eq=False)
class RunRequest:
    """One whole run handed to an integrator that runs the event loop itself (:meth:`Integrator.run`).

    The hybrid core has prepared the run as for its own loop and applied the start rule
    (:func:`nsbench.model.native.begin`): the integrator goes on in ``state.mode`` from
    ``state.y`` at ``state.sf[SF_T] + state.sf[SF_TLO]``, whose guards are the first
    ``state.si[SI_NG]`` entries of ``state.gk``, ``state.gi``, ``state.gs`` (kind, element
    index, expected sign; slots of :mod:`nsbench.model.abi`).

    Attributes
    ----------
    problem
        The problem: its compiled law (``problem.law``, ``problem.data``) is what the core's
        steps call.
    sections
        The state sections of the run (their compiled form is ``section_bundle``).
    limits
        :class:`~nsbench.model.abi.RunLimits`: ``t_end``, the step and event budgets, the storm
        span, ``record_from``, the stop rule, the Zeno rule's streak.
    section_bundle
        :class:`~nsbench.model.abi.Sections`: coefficients, levels, directions, ``hit_from``, ``hit_stop``.
    records
        The run's buffers (:class:`~nsbench.model.records.Records`): events, section hits, and the
        states at the requested times ``records.dense.t``; grown through its methods.
    state
        The run's :class:`~nsbench.model.abi.RunState`, as the compiled loop keeps it.
    """

    problem: "HybridProblem"
    sections: tuple["StateSection", ...]
    limits: "RunLimits"
    section_bundle: "Sections"
    records: "Records"
    state: "RunState"

    @property
    def t_end(self) -> float:
        return float(self.limits.t_end)

    @property
    def t_eval(self) -> np.ndarray:
        """The requested times (sorted); their states go into ``records.dense.y``, one row each."""
        return self.records.dense.t


@dataclass
class RunReport:
    """What :meth:`Integrator.run` returns beside the run's buffers.

    Attributes
    ----------
    integrator_time
        Seconds spent inside the integrator (its steps and event location), without the core's
        steps and the integrator's own glue: ``wall_time - integrator_time`` is what the run cost
        outside the integrator. NaN if not measured.
    extra
        Method-specific counters of the run (``nfev``, ``njev``, ``nsteps`` go into ``state.cnt``).
    message
        Why the run failed, when it ended with ``RUN_FAILURE``, ``RUN_STEP_BUDGET`` or ``RUN_NONFINITE``
        and the core's own message would not say (empty: the core's).
    prepare_time
        Seconds of first-use work inside the run (compiling a model for more sections): setup, not run.
    """

    integrator_time: float = math.nan
    extra: dict[str, float] = field(default_factory=dict)
    message: str = ""
    prepare_time: float = 0.0


class Integrator:
    """Base class and written contract of every nsbench integrator.

    Everything a plug-in needs is importable from ``nsbench.integrators.base``:
    ``Integrator`` (subclass it), ``Capabilities``, ``Option``, ``ArcRequest``
    (what :meth:`advance` receives), ``ArcResult`` and ``SectionHit`` (what it
    returns), ``Status`` (the outcome of an arc: ``Status.SUCCESS`` or a
    failure: ``Status.BUDGET_EXHAUSTED``, ``Status.INTEGRATOR_FAILURE``) and ``UnsupportedProblemError``
    (raised by :meth:`setup` for a problem it cannot solve); ``ConfigError``
    lives in ``nsbench.errors``. Options reach the instance validated and with
    their defaults filled in, as the dict ``self.settings`` (for example
    ``self.settings["rtol"]``); :meth:`advance` and :meth:`setup` read them there.
    Arrays: ``request.y0`` and ``ArcResult.y`` have shape ``(n_states,)``
    (``problem.n_states``: ``x1, v1, x2, v2, ...``); ``ArcResult.y_eval`` has
    shape ``(n_states, n_points)``. Register the class under its ``name`` with an
    entry point in the group ``nsbench.integrators`` (or
    ``nsbench.registry.register`` at run time), and run
    ``nsbench check NAME`` (the conformance kit, :mod:`nsbench.testing`).

    An implementer must:

    1. Set the class attributes ``name`` (lowercase kebab-case, the registry
       name), ``capabilities`` (a :class:`Capabilities`) and ``options`` (a dict
       of :class:`Option`; the defaults are the recommended settings), and
       optionally ``accuracy_levels`` (option sets from loose to tight),
       ``known_gaps`` (conformance checks it knowingly fails, with the reason) and
       ``kernel_group`` (a name shared with integrators that compile the same kernels).
    2. Keep every configured instance describable by :meth:`config`, a small
       dict that :meth:`from_config` turns back into an equal integrator.
    3. In :meth:`setup`, do the once-per-problem work (compilation, operators)
       and refuse a problem it cannot solve with ``UnsupportedProblemError``.
       The engine times ``setup`` separately from the run.
    4. In :meth:`advance`, integrate only the frozen-mode field
       ``request.rhs`` from ``(t0, y0)`` towards ``t_end``; never switch mode
       and never evaluate the field of another mode.
    5. Locate guard crossings itself: the arc ends at the first time ``t > t0``
       where ``guard.expected_sign * guard.value(t, y)`` reaches zero (or the
       other side). Test against the expected sign, never against the sign at
       ``t0``: the guard of a phase that just started is exactly zero there.
       Report the earliest guard; on an exact tie, the lowest index.
    6. Record crossings of ``request.sections`` without stopping, and return
       states at every ``request.t_eval <= t`` from its own dense output or steps.
    7. Never mutate ``request.y0`` or anything else it did not create.
    8. Fill the counters ``nfev``, ``njev``, ``nsteps`` honestly (one per state
       evaluated) and put method-specific counters in ``extra``.
    9. Respect ``request.max_steps``; on a numerical failure or an exhausted
       budget, return an :class:`ArcResult` with the matching ``Status`` and a
       message instead of raising. Never loop forever.
    10. Be deterministic: the same request gives the same result.

    **The whole-run protocol** (optional). An integrator that can run the event loop itself (a
    *native* run: heyoka with transition callbacks, SUNDIALS with a compiled loop) declares the
    option ``"loop": LOOP_OPTION`` and implements :meth:`native_refusal` and :meth:`run`; the core
    (:func:`nsbench.hybrid.run.run_hybrid`, so also sweeps, Lyapunov exponents, periodic orbits)
    then hands it whole runs wherever :meth:`native_refusal` returns ``''`` and the option allows,
    and records the path taken (``SimulationResult.loop``, :data:`LOOP_PATHS`). A native run:

    11. Applies no transition of its own: at each crossing of a guard of ``state.mode`` (located
        as in rule 5, from the expected sign; the earliest, the lowest index on a tie) it calls
        the core's compiled step :func:`nsbench.model.native.event` with the state *before* the
        transition (from compiled code, or from Python through :class:`nsbench.model.native.Views`),
        which applies the problem's ``law.transition`` through :func:`nsbench.model.rules.settle`
        (the guards that fire at once, storms, the event budget, the Zeno rule), records the events
        and applies the stop rule; then it goes on in the new ``state.mode`` from ``state.y`` at
        ``state.sf[SF_T]`` (which the Zeno rule may have moved forward), with the new guards.
    12. Records section crossings through :func:`~nsbench.model.native.hit` and the states at
        ``request.t_eval`` in ``records.dense.y`` (:func:`~nsbench.model.native.dense_row`), from its
        own dense output; the states of an arc are stored before its event, or checked per arc with
        :func:`~nsbench.model.native.missed_over`, so the missed-crossing check sees them.
    13. Stops at any return of those steps but ``GO_ON``: ``NEED_EVENTS``/``NEED_HITS`` (grow the
        buffer through ``request.records``, make the same call again), or the run's outcome. It ends
        a run that reaches ``t_end`` with :func:`~nsbench.model.native.arrive`, and one that it cannot
        go on with :func:`~nsbench.model.native.fail`: the step budget (``limits.max_steps`` steps in
        all: ``RUN_STEP_BUDGET``), a non-finite state (``RUN_NONFINITE``), a failure of its own.
    14. Adds its evaluations and steps to ``state.cnt`` (``NFEV``, ``NJEV``, ``NSTEPS``) and returns
        a :class:`RunReport` (the time inside the integrator, extra counters, a failure's message).
    15. Gives the same events as its per-arc path (``advance``) within its tolerance, and is
        deterministic. What it cannot run (a start its event detection cannot see past, a binding
        that does not load) it refuses in :meth:`native_refusal`, before the run, and the per-arc
        path runs instead.
    """

    name: ClassVar[str] = ""
    capabilities: ClassVar[Capabilities]
    options: ClassVar[dict[str, Option]] = {}
    #: Whether it advances the whole system (:class:`nsbench.integrators.whole.WholeSystem`) instead of arcs.
    whole_system: ClassVar[bool] = False
    #: The software the method comes from (reports group by it beside the family): ``'nsbench'`` for the
    #: bench's own methods, else the library it runs (``'scipy'``, ``'SUNDIALS'``, ``'CyRK'``, ...).
    ecosystem: ClassVar[str] = "nsbench"
    #: Option sets from loose to tight (typically three) that benchmark suites and
    #: convergence checks use by default; empty means "the defaults only".
    accuracy_levels: ClassVar[tuple[dict[str, Any], ...]] = ()
    #: Conformance checks (:mod:`nsbench.testing`) this integrator knowingly does
    #: not pass, as ``{check name: reason}``; reported as expected failures.
    known_gaps: ClassVar[dict[str, str]] = {}
    #: Integrators that compile the same kernels name one group here (``ofapi`` and ``mcpi`` share their
    #: Picard kernels); ``''``: its own kernels. A bench run warms up two integrators of one group one
    #: after the other, not side by side, since the second would only wait for the first's compilation.
    kernel_group: ClassVar[str] = ""

    def __init__(self, **options: Any) -> None:
        values = {}
        for key, value in options.items():
            if key not in self.options:
                allowed = ", ".join(self.options) or "none"
                raise ConfigError(f"{self.name}: unknown option {key!r}; allowed: {allowed}")
            values[key] = self.options[key].check(self.name, key, value)
        self.settings: dict[str, Any] = {k: o.default for k, o in self.options.items()}
        self.settings.update(values)
        self.check_settings()

    def check_settings(self) -> None:
        """Cross-option validation (override when options constrain each other)."""

    def config(self) -> dict[str, Any]:
        """``{'name': ..., 'options': {...}}`` with every option, defaults included."""
        return {"name": self.name, "options": dict(self.settings)}

    @classmethod
    def from_config(cls, config: dict[str, Any]) -> "Integrator":
        """Rebuild an integrator from :meth:`config`."""
        if config.get("name", cls.name) != cls.name:
            raise ConfigError(f"config is for {config.get('name')!r}, not {cls.name!r}")
        return cls(**dict(config.get("options", {})))

    def setup(self, problem: "HybridProblem") -> None:
        """Prepare for ``problem``; the default refuses a problem without any of the accepted traits
        (:attr:`Capabilities.accepts`) and nonlinear problems if not supported."""
        accepts = accepted_traits(self)
        if accepts is not None:
            refuse_without_traits(self, problem, accepts)
        if not self.capabilities.supports_nonlinear and not problem.is_linear:
            reason = getattr(problem, "nonlinear_reason", "")
            what = f"has {reason}" if reason else "is not piecewise linear"
            raise UnsupportedProblemError(
                f"{self.name} solves piecewise-linear problems only ({problem!r} {what}; "
                "use a numerical integrator or 'reference')"
            )

    def check_problem(self, problem: "HybridProblem") -> None:
        """Refuse ``problem`` as :meth:`setup` would, without its costly part where the two can be told
        apart (compiling, loading compiled code): a command checks its input with this in its own
        process and sets up in its workers. The default runs :meth:`setup` with ``self._checking`` set,
        which a setup that compiles can test to stop after its refusals (:meth:`warm_first_call` does)."""
        self._checking = True
        try:
            self.setup(problem)
        finally:
            self._checking = False

    def warm_first_call(self, problem: "HybridProblem", call) -> None:
        """Run ``call()`` (one short arc, or a whole-system run over a short span) untimed, once per process
        for each configuration and law: what a first call loads or compiles (the law's functions, the
        step check) is then :meth:`setup`'s, not the first run's. Nothing under :meth:`check_problem`.

        A failure here is left to the run itself, which reports it with its own status."""
        if getattr(self, "_checking", False):
            return
        key = (type(self), repr(sorted(self.settings.items())), problem.law.source)
        if key in _FIRST_CALLS:
            return
        try:
            call()
        except Exception:  # the timed run meets the same failure and reports it as a status, with its message
            return
        _FIRST_CALLS.add(key)

    def sections_refusal(self, problem: "HybridProblem") -> str:
        """Why this integrator records no state sections (``request.sections``) on ``problem``; ``''``
        if it does (the default). A command asks before its workers start (a sweep's ``peaks``), so
        that a refusal is one line, not one failure per value."""
        return ""

    def advance(self, request: ArcRequest) -> ArcResult:  # pragma: no cover - abstract
        """Integrate one arc of a frozen mode; see the class docstring."""
        raise NotImplementedError

    def native_refusal(self, problem: "HybridProblem", forced: bool = False) -> str:
        """Why this configuration does not run ``problem`` with its own event loop (:meth:`run`); ``''`` if it does.

        Called by the core before each run on the set-up integrator (whole-run protocol, rules
        11-15). ``forced``: the ``loop`` option says ``'native'``, so only what makes a native run
        impossible counts (no such path, a binding that did not load), not what makes it unwise (a
        start its event detection cannot see past). One line, naming the reason and the fallback's
        cause; the default: this integrator has no native path.
        """
        return f"{self.name} has no event loop of its own (it runs one arc per call)"

    def run(self, request: RunRequest) -> RunReport:  # pragma: no cover - abstract
        """Run the whole simulation of ``request`` with the integrator's own event loop (rules 11-15)."""
        raise NotImplementedError(f"{self.name} has no event loop of its own")

    def kernel(self, problem: "HybridProblem"):
        """The compiled arc kernel for ``problem`` (an :class:`~nsbench.model.kernel.ArcKernel`), or ``None``.

        ``None`` (the default) means the hybrid core calls :meth:`advance` once per
        arc. Built-in integrators with a compiled kernel derive from
        :class:`CompiledArcs`; their whole run, events included, stays in compiled code.
        """
        return None

    def __repr__(self) -> str:
        opts = ", ".join(f"{k}={v!r}" for k, v in self.settings.items())
        return f"{type(self).__name__}({opts})"


#: Compiled kernels (integrator class, address table) that have run an arc in this process: loaded.
_KERNELS_RUN: set[tuple[type, bytes]] = set()
#: The (class, settings, law) of every :meth:`Integrator.warm_first_call` made in this process.
_FIRST_CALLS: set[tuple[type, str, str]] = set()


class CompiledArcs(Integrator):
    """Base of the integrators whose arcs run in a compiled kernel of the hybrid core.

    A subclass implements :meth:`build_kernel` (an :class:`~nsbench.model.kernel.ArcKernel`
    over its compiled ``arc`` function, :mod:`nsbench.model.abi`) and lists the names of
    its method-specific counters in ``counter_names``; :meth:`advance` then runs one arc
    of that kernel, so the Python protocol holds too, and :func:`nsbench.simulate` runs
    whole simulations in compiled code.
    """

    counter_names: ClassVar[tuple[str, ...]] = ()

    def build_kernel(self, problem: "HybridProblem"):  # pragma: no cover - abstract
        """The :class:`~nsbench.model.kernel.ArcKernel` of this configuration for ``problem``."""
        raise NotImplementedError

    def setup(self, problem: "HybridProblem") -> None:
        """Build the kernel's data and compile (or load) its arc, then run one short arc, untimed."""
        super().setup(problem)
        if getattr(self, "_checking", False):  # check_problem: the refusals above only
            return
        self._kernel = self.build_kernel(problem)
        self._kernel_problem = problem
        key = (type(self), self._kernel.table.tobytes())
        if key in _KERNELS_RUN:  # its compiled code has run in this process: a sweep's next value
            return
        mode = problem.initial_mode(0.0, problem.initial_state())
        kernel_advance(self, ArcRequest(problem, mode, 0.0, problem.initial_state(), 1e-3, problem.guards(mode)))
        _KERNELS_RUN.add(key)

    def __getstate__(self) -> dict[str, Any]:
        """Without the kernel: its function addresses belong to this process (set up again after unpickling)."""
        state = dict(self.__dict__)
        state.pop("_kernel", None)
        state.pop("_kernel_problem", None)
        return state

    def compiled_kernel(self, problem: "HybridProblem"):
        """The kernel itself, also for a subclass that overrides :meth:`advance` (which then calls it)."""
        if getattr(self, "_kernel_problem", None) is not problem:
            self.setup(problem)
        return self._kernel

    def kernel(self, problem: "HybridProblem"):
        if type(self).advance is not CompiledArcs.advance:
            return None  # a subclass that overrides advance is run through it, once per arc
        if getattr(self, "_kernel_problem", None) is not problem:
            self.setup(problem)
        return self._kernel

    def advance(self, request: ArcRequest) -> ArcResult:
        return kernel_advance(self, request)


def kernel_advance(integ: CompiledArcs, request: ArcRequest) -> ArcResult:
    """``advance`` of an integrator with a compiled kernel: one arc of the kernel, as an :class:`ArcResult`.

    The kernel takes all the guards of the mode in the order of ``problem.guards(mode)``,
    or none (a free arc of the mode).
    """
    from nsbench.model import abi
    from nsbench.model.kernel import one_arc

    problem = request.problem
    kernel = integ.compiled_kernel(problem)
    guards = problem.guards(tuple(int(v) for v in request.mode))
    given = tuple(request.guards)
    if given and [(g.kind, g.block, g.expected_sign) for g in given] != [
        (g.kind, g.block, g.expected_sign) for g in guards
    ]:
        raise ConfigError(
            f"{integ.name}: a compiled kernel takes all the guards of the mode in the order of "
            f"problem.guards(mode) (or none), not {list(given)}"
        )
    size = max(problem.max_guards, 1)
    gk, gi, gs = (np.zeros(size, np.int64) for _ in range(3))
    for q, g in enumerate(guards):
        gk[q], gi[q], gs[q] = g.code, g.block - 1, g.expected_sign
    out = one_arc(
        kernel,
        problem.data,
        request.mode,
        (gk, gi, gs),
        len(guards) if given else 0,
        request.t0,
        request.t0_lo,
        request.y0,
        request.t_end,
        request.max_steps,
        request.sections,
        request.t_eval,
    )
    message, code = "", Status.SUCCESS
    if out.status == abi.K_BUDGET:
        code, message = Status.BUDGET_EXHAUSTED, f"step budget exhausted at t = {out.t:.6g}"
    elif out.status == abi.K_NONFINITE:
        code, message = Status.INTEGRATOR_FAILURE, f"non-finite state after t = {out.t:.6g}"
    elif out.status >= abi.K_FAIL:
        code = Status.INTEGRATOR_FAILURE
        message = kernel.failure(out.status, out.t) if kernel.failure else f"failure code {out.status}"
    hits = [SectionHit(k, t, y) for k, t, y in out.hits]
    extra: dict[str, float] = {name: int(out.counters[abi.X0 + k]) for k, name in enumerate(kernel.counters)}
    return ArcResult(
        t=out.t,
        y=out.y,
        fired=None if out.fired < 0 else out.fired,
        y_eval=out.y_eval,
        section_hits=hits,
        nfev=int(out.counters[abi.NFEV]),
        njev=int(out.counters[abi.NJEV]),
        nsteps=int(out.counters[abi.NSTEPS]),
        extra=extra,
        status=code,
        message=message,
        t_lo=out.t_lo,
    )


def require_event_driven(integ: Any, use: str = "") -> None:
    """``ConfigError`` unless ``integ`` (an integrator or its class) runs arcs of frozen modes: the
    hybrid core runs only those (sweeps, Lyapunov exponents and periodic orbits are made of its
    runs). ``use`` names what the caller was asked for (``"a sweep"``), for the message."""
    family = getattr(getattr(integ, "capabilities", None), "family", "event-driven")
    if family != "event-driven" or getattr(integ, "whole_system", False):  # Siconos's event-driven scheme
        what = (
            f"{use} needs an event-driven integrator"
            if use
            else "the hybrid core runs event-driven integrators only (sweeps, Lyapunov exponents and periodic "
            "orbits need one)"
        )
        raise ConfigError(
            f"{integ.name} is a whole-system method (family {family}): {what}; `nsbench list integrators` "
            f"shows each one's family (nsbench.simulate runs {integ.name})"
        )
