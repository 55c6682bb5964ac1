"""What a problem is: a hybrid automaton given as data and compiled functions.

A problem declares its state (names), its modes (int64 vectors of a fixed size
encoding any finite set), its law (per mode the vector field and its Jacobian,
the guards with the sign each keeps inside the mode, per guard the transition:
the next mode and a reset of the state; the initial-mode rule; optionally the
limit behaviour of an accumulation of events), its event kinds, and its
parameters by name. :class:`HybridProblem` is the base class: a family sets
the class attributes and implements the few methods marked below; everything
the core, the integrators and the reports need is derived here from the law
(:mod:`nsbench.model.law`).

A third party adds a problem by writing one module: the compiled law, a
subclass of :class:`HybridProblem` and a factory ``f(case=None,
dimensional=False, **params)``, registered through the ``nsbench.problems``
entry point (``examples/problem_plugin`` is a complete example).
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from types import ModuleType
from typing import Any, ClassVar

import numpy as np

Mode = tuple[int, ...]


@dataclass(frozen=True)
class Traits:
    """What a problem is, declared as data: what integrators and apps ask of a problem instead of its
    name or its ``family`` (a label for reports).

    Every trait is ``False`` by default, so a plug-in problem that declares none runs through its
    hybrid law only (rhs, guards, transitions): no integrator takes a path written for a
    formulation the problem did not declare.

    Attributes
    ----------
    belt_blocks
        The friction oscillators' formulation: blocks (state ``x1, v1, x2, v2, ...``) on a belt
        moving at ``v0``, one phase per block (``-1``, ``0`` stuck, ``+1``), and the
        ``coefficients`` (masses, springs, friction levels) that the SUNDIALS, heyoka, mp and
        time-stepping kernels read, with ``n_blocks`` and ``v0``.
    impacts
        Velocities jump at impacts (Newton's restitution) and a contact can rest on its stop: the
        events of a time-stepper are inferred from its contact modes and impulses.
    falling_mass
        One point mass under constant gravity onto a fixed ground with Newton's restitution ``e``
        (the bouncing ball): what the time-steppers' contact kernels (``moreau-jean``, Siconos)
        are written for.
    sliding
        A first-order field that switches across surfaces and may slide on them (Filippov): the
        events of a time-stepper are inferred from its side of each surface or its sliding.
    """

    belt_blocks: bool = False
    impacts: bool = False
    falling_mass: bool = False
    sliding: bool = False

    #: What each trait is, in the words of a refusal ("on problems with ...").
    WORDS: ClassVar[dict[str, str]] = {
        "belt_blocks": "blocks on a belt (the friction oscillators' formulation)",
        "impacts": "impacts",
        "falling_mass": "a mass falling onto a fixed ground (the bouncing ball)",
        "sliding": "a switched first-order field with sliding (the relay family)",
    }

    def has_any(self, names: tuple[str, ...]) -> bool:
        """Whether any of the traits ``names`` holds."""
        return any(getattr(self, n) for n in names)

    @classmethod
    def words(cls, names: tuple[str, ...]) -> str:
        """``names`` as a refusal names them (``"blocks on a belt (...) or impacts"``)."""
        return " or ".join(cls.WORDS[n] for n in names)


#: Span of the conformance kit's event checks on a problem without the belt's presets, in its time
#: scales (:attr:`HybridProblem.check_span`), as ``tau`` in [0, 60] on the belt.
CHECK_TIME_SCALES = 60.0
#: The names of the traits (what :attr:`nsbench.integrators.base.Capabilities.accepts` may name).
TRAIT_NAMES: tuple[str, ...] = tuple(f.name for f in fields(Traits))


def problem_traits(problem: Any) -> Traits:
    """``problem``'s declared :class:`Traits`; none (all ``False``) for an object that declares none."""
    traits = getattr(problem, "traits", None)
    return traits if isinstance(traits, Traits) else Traits()


@dataclass(frozen=True, eq=False)
class Guard:
    """A switching surface of the current mode.

    Attributes
    ----------
    problem
        The problem that evaluates it.
    block
        1-based index of the element the guard belongs to (the block of a
        friction chain, the contact of an impact problem).
    kind
        The guard's kind, one of the problem's ``guard_kinds``.
    expected_sign
        Sign of the guard while the mode is valid. The mode ends when
        ``expected_sign * value`` reaches zero. At the start of a phase the guard
        of that phase may be exactly zero, so integrators must test against
        this sign, never against the sign at the start of the arc.
    mode
        The mode the guard belongs to.
    """

    problem: "HybridProblem"
    block: int
    kind: str
    expected_sign: int
    mode: Mode = ()

    @property
    def code(self) -> int:
        """The guard kind's code in the problem's law."""
        return self.problem.guard_kinds.index(self.kind)

    @property
    def name(self) -> str:
        return self.problem.guard_name(self)

    def value(self, t, y):
        """Guard value at ``(t, y)``; ``y`` of shape ``(n,)`` or ``(n, k)``."""
        return self.problem.guard_value(self, t, y)

    def rate(self, t, y, dydt):
        """Time derivative of the guard along ``dydt`` (same shapes as ``y``)."""
        return self.problem.guard_rate(self, t, y, dydt)

    def __repr__(self) -> str:
        return f"Guard({self.name}, expected_sign={self.expected_sign:+d})"


@dataclass(frozen=True)
class Transition:
    """What happens when a guard fires: the new mode, the state after the reset, the event kind."""

    mode: Mode
    y: np.ndarray
    kind: str
    block: int


class HybridProblem:
    """Base of every problem (see the module docstring).

    Class attributes a family sets
    ------------------------------
    family
        Short name of the family (``'friction'``, ``'impact'``), a label for reports: nothing
        branches on it (what integrators and apps ask is in ``traits``).
    traits
        What the problem is, as data (:class:`Traits`): the formulation integrators may have
        kernels for, impacts, sliding.
    problem_class
        The class of non-smooth behaviour reports group problems by (``'friction'``,
        ``'impact'``, ``'sliding'``, ``'smooth'``, ``'impact-friction'``); empty: the family's name
        (:meth:`HybridProblem.behaviour`).
    law_module
        The module holding the compiled law (:mod:`nsbench.model.law`), or its import path (so that
        building a problem loads no compiler).
    guard_kinds, event_kinds
        Names of the guard kind and event kind codes of the law, in code order.
    mode_columns
        Names of the entries of the mode vector (trajectory columns).

    Instance attributes a family sets (in ``__init__``)
    ---------------------------------------------------
    name, case, dimensional, params, parameters
        Registry name, preset, units, the user's overrides, every value by name. ``case``,
        ``dimensional`` and ``params`` are what :meth:`config` hands back to the factory: they must
        rebuild the same parameter vector and start state (the conformance kit checks it,
        :func:`nsbench.testing.check_problem`).
    cases
        The cases the factory names (each a value of its ``case`` argument), ``()`` for a problem
        of one form; the round-trip check rebuilds every one of them.
    state_names
        Names of the state's entries.
    position_rates
        ``position -> rate`` for every state whose time derivative is another state (``x1 -> v1``
        of a block, ``x -> px`` of a Hamiltonian), ``{}`` for a first-order law (a thermostat, a
        relay's feedback loop): what a ``peaks`` section records, declared so that a command can
        check a section without running the field. ``None`` (the default, for a plug-in that
        does not say) lets :func:`nsbench.sections.rate_state` find them on the field; the
        conformance kit checks a declaration against the field.
    packed
        The parameter vector of the law (a named layout of the family).
    """

    family: ClassVar[str] = ""
    traits: ClassVar[Traits] = Traits()
    problem_class: ClassVar[str] = ""
    law_module: ClassVar[ModuleType | str]
    guard_kinds: ClassVar[tuple[str, ...]] = ()
    event_kinds: ClassVar[tuple[str, ...]] = ()
    mode_columns: tuple[str, ...] = ()  # a class value, or per instance (the chain's one per block)

    name: str
    case: int | str | None = None
    cases: tuple[int | str, ...] = ()
    dimensional: bool = False
    params: dict[str, float]
    parameters: dict[str, float]
    state_names: tuple[str, ...]
    position_rates: dict[str, str] | None = None
    packed: np.ndarray

    def _given(
        self,
        name: str,
        params: dict[str, Any],
        parameters: dict[str, float],
        state_names: tuple[str, ...],
        position_rates: dict[str, str] | None = None,
    ) -> None:
        """Keep what every problem without presets or units holds: its name, the user's overrides, every
        value by name, its states' names and (where declared) which state is which position's rate."""
        self.name, self.case, self.dimensional = name, None, False
        self.params, self.parameters = dict(params), dict(parameters)
        self.state_names = tuple(state_names)
        if position_rates is not None:
            self.position_rates = dict(position_rates)

    # ------------------------------------------------------------------ what a family implements
    def initial_state(self) -> np.ndarray:
        """The start state of the problem's standard run (from its parameters)."""
        raise NotImplementedError

    def mode_name(self, mode: Mode) -> str:
        """A mode as the event log writes it."""
        return "|".join(str(int(v)) for v in mode)

    def parse_mode(self, text: str) -> Mode:
        """The inverse of :meth:`mode_name`."""
        return tuple(int(part) for part in text.split("|"))

    def guard_name(self, guard: Guard) -> str:
        """A guard as messages write it."""
        return f"{guard.kind}{guard.block}"

    @property
    def is_linear(self) -> bool:
        """Whether every mode is affine with constant and harmonic forcing and every guard linear
        (then :meth:`linear_form` and :meth:`guard_row` exist and ``exact`` solves the problem)."""
        return False

    def linear_form(self, mode: Mode) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``(A, b0, bc, bs)`` with ``y' = A y + b0 + bc cos(w t) + bs sin(w t)`` in ``mode`` (linear problems)."""
        raise ValueError(f"{self.name}: no linear form (the problem is not piecewise linear)")

    def guard_row(self, mode: Mode, kind: int, index: int) -> np.ndarray:
        """``q`` with guard ``(kind, index)`` ``= q . [y, 1, cos w t, sin w t]`` (linear problems)."""
        raise ValueError(f"{self.name}: no linear guards (the problem is not piecewise linear)")

    @property
    def forcing_frequency(self) -> float:
        """``w`` of the harmonic terms of :meth:`linear_form`."""
        return 0.0

    @property
    def is_forced(self) -> bool:
        """Whether :meth:`linear_form` has harmonic terms."""
        return self.forcing_frequency != 0.0

    @property
    def time_scale(self) -> float:
        """The problem's unit of time in the dimensionless form (event storms are judged in it)."""
        return 1.0

    @property
    def check_span(self) -> float:
        """The span the conformance kit's event checks integrate over on this problem
        (:mod:`nsbench.testing`, off the belt's presets): :data:`CHECK_TIME_SCALES` time scales.

        A problem whose state grows or decays without bound over that span declares a shorter one,
        so that the kit measures the method and not the range of a double.
        """
        return CHECK_TIME_SCALES * self.time_scale

    def config(self) -> dict[str, Any]:
        """The small dict that rebuilds this problem with :func:`nsbench.get_problem`."""
        return {"name": self.name, "case": self.case, "dimensional": self.dimensional, "params": dict(self.params)}

    def behaviour(self) -> str:
        """The problem class reports group by: the declared ``problem_class``, else the family."""
        return self.problem_class or self.family

    # ------------------------------------------------------------------ derived from the law
    @property
    def law(self):
        """The compiled law (:class:`nsbench.model.law.Law`), loaded once per process."""
        from nsbench.model.law import law_of

        return law_of(self.law_module)

    @property
    def data(self):
        """The problem as compiled code sees it: the parameter vector in its law's data class
        (:func:`nsbench.model.law.data_class`), through which compiled code reaches the law."""
        cached = self.__dict__.get("_data")
        if cached is None:
            cached = self.__dict__["_data"] = self.law.data_class(np.ascontiguousarray(self.packed, dtype=float))
        return cached

    @property
    def n_states(self) -> int:
        return len(self.state_names)

    @property
    def mode_size(self) -> int:
        return len(self.mode_columns)

    @property
    def n_elements(self) -> int:
        """Number of element indices guards may carry (the size of the ``fresh`` marks)."""
        return self.mode_size

    @property
    def max_guards(self) -> int:
        """An upper bound on the number of guards of a mode (the size of the guard arrays)."""
        return 2 * self.mode_size

    @staticmethod
    def mode_array(mode: Mode) -> np.ndarray:
        return np.ascontiguousarray(mode, dtype=np.int64)

    def rhs(self, mode: Mode, t, y) -> np.ndarray:
        """Frozen-mode vector field at ``y`` of shape ``(n,)`` or columns ``(n, k)`` (same shape out)."""
        from nsbench.model.law import evaluate_rhs

        return evaluate_rhs(self.data, self.mode_array(mode), t, y)

    def jacobian(self, mode: Mode, t, y) -> np.ndarray:
        """Jacobian of :meth:`rhs`: ``(n, n)``, or ``(n, n, k)`` for columns."""
        from nsbench.model.law import evaluate_jacobian

        return evaluate_jacobian(self.data, self.mode_array(mode), t, y)

    def guards(self, mode: Mode) -> tuple[Guard, ...]:
        """Guards of ``mode`` in the law's order (also the tie order)."""
        cache = self.__dict__.setdefault("_guards", {})
        cached = cache.get(mode)
        if cached is None:
            g = [np.zeros(self.max_guards, np.int64) for _ in range(3)]
            ng = self.law.guards_of(self.data.p, self.mode_array(mode), *g)
            cached = cache[mode] = tuple(
                Guard(self, int(g[1][q]) + 1, self.guard_kinds[int(g[0][q])], int(g[2][q]), tuple(int(v) for v in mode))
                for q in range(ng)
            )
        return cached

    def _guard_mode(self, guard: Guard) -> np.ndarray:
        return self.mode_array(guard.mode if guard.mode else (0,) * self.mode_size)

    def guard_value(self, guard: Guard, t, y):
        """Value of ``guard`` at ``(t, y)`` (vectorised over columns)."""
        from nsbench.model.law import evaluate_guard

        return evaluate_guard(self.data, self._guard_mode(guard), guard.code, guard.block - 1, t, y)

    def guard_rate(self, guard: Guard, t, y, dydt):
        """d(guard)/dt along ``dydt`` (vectorised over columns)."""
        from nsbench.model.law import evaluate_guard

        return evaluate_guard(self.data, self._guard_mode(guard), guard.code, guard.block - 1, t, y, dydt)

    def initial_mode(self, t: float, y) -> Mode:
        """The mode a state starts in (the law's rule)."""
        mode = np.zeros(self.mode_size, np.int64)
        self.law.initial_mode(self.data.p, float(t), np.ascontiguousarray(y, dtype=float), mode)
        return tuple(int(v) for v in mode)

    def transition(self, mode: Mode, guard: Guard, t: float, y) -> Transition:
        """The law's transition when ``guard`` fires at ``(t, y)``: new mode, reset state, event kind."""
        new = self.mode_array(mode).copy()
        y_new = np.array(y, dtype=float, copy=True)
        fresh = np.zeros(self.n_elements, np.bool_)
        code = self.law.transition(self.data.p, new, guard.code, guard.block - 1, float(t), y_new, fresh)
        return Transition(tuple(int(v) for v in new), y_new, self.event_kinds[code], guard.block)

    def __getstate__(self) -> dict[str, Any]:
        """Without the compiled views: their function addresses belong to this process (a pickled problem
        is rebuilt in another one)."""
        state = dict(self.__dict__)
        state.pop("_data", None)
        state.pop("_guards", None)
        return state

    def __repr__(self) -> str:
        case = f", case={self.case}" if self.case is not None else ""
        extra = f", params={self.params}" if self.params else ""
        return f"<{self.name}{case}{extra}>"


class NamedModes:
    """Modes of one column, each with a name (``mode_names``: code -> name), as event logs write them.

    Mixed in before :class:`HybridProblem` by the families whose mode is one discrete state
    (contact or flight, the relay's side, the side of a section plane).
    """

    mode_names: ClassVar[dict[int, str]] = {}

    def mode_name(self, mode: Mode) -> str:
        return self.mode_names[int(mode[0])]

    def parse_mode(self, text: str) -> Mode:
        for code, name in self.mode_names.items():
            if name == text:
                return (code,)
        raise ValueError(f"unknown mode {text!r}; one of {', '.join(map(repr, self.mode_names.values()))}")
