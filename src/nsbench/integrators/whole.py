"""The protocol of whole-system methods: time-stepping, the switch model, smoothing.

An event-driven integrator (:class:`~nsbench.integrators.base.Integrator`) advances
one frozen mode and locates that mode's guards; the hybrid core switches modes.
A *whole-system* method instead advances the whole non-smooth system over
``[t0, t_end]`` itself, through the problem's set-valued law (Moreau-Jean
time-stepping), a stick band with force-based switching (Leine's switch model)
or a regularised law (smoothing), and hands back its discrete trajectory (and,
optionally, its own labels, the impulses of an impact problem and the switches it
located itself). nsbench then infers the switching events from the trajectory by one
documented rule, the same for every method
(:func:`nsbench.hybrid.inference.infer_events`), so the event log, the
trajectory and every metric of the bench are those of an event-driven run.

A plug-in subclasses :class:`WholeSystem`, sets ``capabilities.family`` to one of
``'time-stepping'``, ``'switch-model'``, ``'smoothing'``, implements
:meth:`WholeSystem.integrate`, and registers under the ``nsbench.integrators``
entry point like any integrator.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np

from nsbench.errors import ConfigError, UnsupportedProblemError
from nsbench.integrators.base import Integrator
from nsbench.status import Status

if TYPE_CHECKING:  # pragma: no cover
    from nsbench.integrators.base import ArcRequest, ArcResult
    from nsbench.problems.base import HybridProblem


@dataclass(frozen=True, eq=False)
class SystemRequest:
    """One call of :meth:`WholeSystem.integrate`: the whole system from ``(t0, y0)`` to ``t_end``.

    Attributes
    ----------
    problem
        The problem (its parameters, its law).
    t0, y0
        Start time and state (``y0`` read-only, shape ``(n_states,)``).
    t_end
        End of the span.
    max_steps
        Step budget: a method that would need more steps stops after this many
        with ``Status.BUDGET_EXHAUSTED``.
    t_eval
        Sorted times in ``[t0, t_end]`` where states are wanted; a method with a
        dense output of its own may return them (``SystemResult.y_eval``), else
        nsbench interpolates the steps linearly.
    """

    problem: "HybridProblem"
    t0: float
    y0: np.ndarray
    t_end: float
    max_steps: int = 10**7
    t_eval: np.ndarray = field(default_factory=lambda: np.empty(0))


@dataclass
class SystemResult:
    """What :meth:`WholeSystem.integrate` returns: the discrete trajectory and its cost.

    Attributes
    ----------
    t
        Step times, shape ``(k,)``, increasing, ``t[0] = t0``; the last is
        ``t_end`` unless the run stopped early (a failure, the budget).
    y
        States at those times, shape ``(k, n_states)`` (one *row* per step).
    modes
        The method's own label of each step, shape ``(k, mode_size)`` in the
        problem's mode vocabulary (friction: per block 0 stick, +1 slip+, -1
        slip-; the ball: 1 resting contact), or ``None``. The event inference
        reads it for the impact problems only (the ball's resting contact); the
        phases of the friction family are read off the trajectory by one rule
        for every method (:mod:`nsbench.hybrid.inference`, rule 1), with the
        method's stick band (:meth:`WholeSystem.stick_band`).
    impulses
        For impact problems: the impulse of each contact in the step ending at each
        time, shape ``(k, n_contacts)`` (0: none), or ``None``. A positive impulse
        while the contact approaches is an impact (:mod:`nsbench.hybrid.inference`).
    switch_times
        Times of the switches the method located itself (an FESD-type method's
        switch detection, an event-driven scheme's root finder), shape ``(n,)``,
        or ``None``. They do not place the events (the inference does, the same
        for every method); each is paired with the inferred event it belongs to
        and reported beside it (the event log's ``t_located`` column, the
        bench's ``located_err_max``).
    switch_elements
        The element (0-based block or contact) of each located switch, shape
        ``(n,)``, or ``None`` (paired by time alone).
    y_eval
        States at ``request.t_eval`` from the method's own dense output, shape
        ``(len(t_eval), n_states)``, or ``None`` (linear interpolation of the steps).
    nfev, njev, nsteps
        Right-hand-side and Jacobian evaluations, steps.
    extra
        Method-specific counters (one-step problems solved, enumerations, ...).
    status, message
        ``Status.SUCCESS``, or the failure and its reason.
    internal
        The method's own states beside the problem's at each step (a friction model's bristle
        deflections, ``lugre``), shape ``(k, len(internal_names))``, or ``None``: they take no part
        in the event inference or the metrics, and reach the user as ``SimulationResult.internal``.
    internal_names
        The names of the columns of ``internal`` (``('z1', 'z2')``).
    """

    t: np.ndarray
    y: np.ndarray
    modes: np.ndarray | None = None
    impulses: np.ndarray | None = None
    switch_times: np.ndarray | None = None
    switch_elements: np.ndarray | None = None
    y_eval: np.ndarray | None = None
    nfev: int = 0
    njev: int = 0
    nsteps: int = 0
    extra: dict[str, float] = field(default_factory=dict)
    status: Status = Status.SUCCESS
    message: str = ""
    internal: np.ndarray | None = None
    internal_names: tuple[str, ...] = ()


class WholeSystem(Integrator):
    """Base class of the whole-system methods (see the module docstring).

    An implementer sets ``name``, ``capabilities`` (with ``family`` one of
    ``'time-stepping'``, ``'switch-model'``, ``'smoothing'``) and ``options`` as
    for any integrator, refuses in :meth:`setup` the problems it cannot run (with
    ``UnsupportedProblemError`` and the reason; it may compile there, untimed), and
    implements :meth:`integrate`. Like every integrator it is deterministic,
    never mutates ``request.y0``, respects ``request.max_steps``, and reports a
    numerical failure as a ``Status``, never as an exception. It does not
    implement ``advance``: there are no frozen-mode arcs.

    Which problems it runs is declared in its capabilities
    (:attr:`~nsbench.integrators.base.Capabilities.accepts`), by the problems'
    :class:`~nsbench.problems.base.Traits` whose events
    :func:`nsbench.hybrid.inference.infer_events` infers: blocks on a belt (one-dof,
    two-dof, chain, block-on-ground, den-hartog;
    :data:`~nsbench.integrators.base.WHOLE_SYSTEM_ACCEPTS`, when it declares none), impacts for a method that reports ``impulses``, sliding for one
    that reports its side of each surface.
    """

    whole_system: ClassVar[bool] = True

    #: Whether the method's stick/slip law is Coulomb's only (it refuses the other friction laws at setup).
    COULOMB_ONLY: bool = False
    #: Whether :meth:`setup` runs one short ``integrate`` (:meth:`Integrator.warm_first_call`): a method whose
    #: first call loads compiled code (the law's functions through ``problem.rhs``, a solver's) sets it.
    WARM_IN_SETUP: ClassVar[bool] = False

    def setup(self, problem: "HybridProblem") -> None:
        super().setup(problem)  # refuses a problem without one of the traits it accepts
        law = getattr(problem, "law_spec", None)
        if self.COULOMB_ONLY and law is not None and not law.is_coulomb:
            raise UnsupportedProblemError(
                f"{self.name} regularises Coulomb's law (a constant slip force fs); {problem.name} has the "
                f"{law.name} friction law"
            )
        if self.WARM_IN_SETUP:
            # the integrate of the class that asked for it: a subclass's own (a test's crash) is not run here
            owner: Any = next(c for c in type(self).__mro__ if c.__dict__.get("WARM_IN_SETUP"))
            span = 1e-3 * problem.time_scale
            self.warm_first_call(
                problem, lambda: owner.integrate(self, SystemRequest(problem, 0.0, problem.initial_state(), span))
            )

    def integrate(self, request: SystemRequest) -> SystemResult:  # pragma: no cover - abstract
        """Advance the whole system over ``[request.t0, request.t_end]``; see :class:`SystemResult`."""
        raise NotImplementedError

    def stick_band(self, problem: "HybridProblem") -> float:
        """Half-width of the band ``|v - v_belt| <= band`` that counts as stuck, in the problem's velocity units.

        Used by the event inference: a block *enters* stick where ``|v - v_belt|``
        crosses the band downwards and *leaves* it where it crosses upwards
        (0: the method sticks exactly and leaves by its force law).
        """
        return 0.0

    def smooth_order(self) -> int | None:
        """Convergence order on a smooth arc at this configuration (default ``capabilities.order``)."""
        return type(self).capabilities.order

    def advance(self, request: "ArcRequest") -> "ArcResult":
        raise ConfigError(
            f"{self.name} is a whole-system method ({type(self).capabilities.family}): it has no "
            "frozen-mode arcs; run it with nsbench.simulate"
        )


def is_whole_system(integ: Integrator) -> bool:
    """Whether ``integ`` follows the whole-system protocol (its family is not event-driven)."""
    return isinstance(integ, WholeSystem)


def check_result(name: str, request: SystemRequest, res: Any, n_states: int, mode_size: int) -> str:
    """The first way ``res`` breaks the protocol, or ``''`` (the driver turns it into a failure status)."""
    if not isinstance(res, SystemResult):
        return f"{name}.integrate returned {type(res).__name__}, not SystemResult"
    t, y = np.asarray(res.t), np.asarray(res.y)
    if t.ndim != 1 or t.size < 1:
        return f"{name}: t has shape {t.shape}; one time per step, at least t0"
    if y.shape != (t.size, n_states):
        return f"{name}: y has shape {y.shape}; the protocol wants (n_steps, n_states) = ({t.size}, {n_states})"
    if t[0] != request.t0 or np.any(np.diff(t) <= 0) or t[-1] > request.t_end:
        return f"{name}: step times must start at t0 = {request.t0!r}, increase, and stay <= t_end"
    if res.modes is not None and np.shape(res.modes) != (t.size, mode_size):
        return f"{name}: modes has shape {np.shape(res.modes)}; wanted ({t.size}, {mode_size})"
    if res.switch_times is not None:
        located = np.asarray(res.switch_times, dtype=float)
        if located.ndim != 1 or not np.all(np.isfinite(located)):
            return f"{name}: switch_times must be a 1-d array of finite times, not shape {located.shape}"
        if res.switch_elements is not None and np.shape(res.switch_elements) != located.shape:
            return f"{name}: switch_elements has shape {np.shape(res.switch_elements)}; wanted {located.shape}"
    if res.y_eval is not None and np.shape(res.y_eval) != (request.t_eval.size, n_states):
        return f"{name}: y_eval has shape {np.shape(res.y_eval)}; wanted ({request.t_eval.size}, {n_states})"
    if res.internal is not None and np.shape(res.internal) != (t.size, len(res.internal_names)):
        return (
            f"{name}: internal has shape {np.shape(res.internal)}; wanted ({t.size}, {len(res.internal_names)}), "
            "one row per step and a name per column (internal_names)"
        )
    if res.status.ok and t[-1] != request.t_end:
        return f"{name}: stopped at t = {t[-1]!r} < t_end = {request.t_end!r} with status success"
    return ""
