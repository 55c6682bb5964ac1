"""``heyoka``, ``heyoka-ld``, ``heyoka-q``: heyoka's adaptive Taylor method in double, long double and quad.

One ``taylor_adaptive`` is compiled per problem structure in :meth:`setup`
(see :mod:`nsbench.integrators._heyoka_model`) and kept by the integrator across
setups of problems of that structure (a sweep's values); an arc sets the mode, the
coefficients and the sections as runtime parameters, the time and the state in
the integrator's own precision, and propagates to ``t_end``. Guards are
terminal events located by heyoka on the Taylor polynomial of each step
(direction "decreasing", so a phase that starts on its own surface does not
stop at once); sections are non-terminal events; trajectory points come from
the Taylor polynomial of the step that holds them (``update_d_output`` in a step
callback, :class:`_StepRows`), not from heyoka's continuous output, whose every
propagation builds a compiled evaluator of its own (about 1 ms, a hundred times
an arc here). Times and states cross the protocol as doubles.

Precision across events (``heyoka-ld``, ``heyoka-q``): the state and time where
an arc stopped at an event are kept in the integrator's own precision (the full
heyoka state, with the forcing's cos/sin, and heyoka's double-length time). When
the next request starts where that arc ended (the same ``t0 + t0_lo`` and the
same double state, except velocities the transition set to exactly ``v0``), the
arc continues from the kept state, with those velocities set to ``v0`` in the
integrator's precision; so the state never passes through a double between
arcs. Any other request (a new run, another start) starts from its doubles. The
double ``heyoka`` always starts from the request.

Counters: ``nsteps`` Taylor steps; ``nfev`` counts one Taylor jet (all
coefficients up to the order, about ``order`` field evaluations' worth of
work) per step, and ``extra['taylor_coefficients']`` the jets times the order.
Compilation happens in :meth:`setup` (two section slots); a request with more
sections compiles a wider model once, reported in ``extra['compile_seconds']``.

A problem of another family that writes its field symbolically
(``symbolic_field``, ``symbolic_guard``: ``henon-heiles``) runs through
:mod:`nsbench.integrators._heyoka_symbolic`: one compiled integrator per mode
(compiled in :meth:`setup` for the start mode, on first visit for the others,
reported in ``extra['compile_seconds']``), no state sections. Its state and time
are carried across an event in the integrator's precision when the transition
left the state alone.
"""

from __future__ import annotations

import time
from typing import Any, ClassVar, Sequence

import numpy as np

from nsbench.errors import ConfigError, UnsupportedProblemError
from nsbench.integrators import _heyoka_crossing as crossing
from nsbench.integrators import _heyoka_batch as batch_heyoka
from nsbench.integrators import _heyoka_model as model
from nsbench.integrators import _heyoka_native as native_heyoka
from nsbench.integrators import _heyoka_symbolic as symbolic
from nsbench.integrators._carry import reset_velocities
from nsbench.integrators.base import (
    LOOP_OPTION,
    ArcRequest,
    ArcResult,
    Capabilities,
    Integrator,
    Option,
    RunReport,
    RunRequest,
)
from nsbench.problems.base import problem_traits
from nsbench.problems.modes import STICK
from nsbench.status import Status

_SECTION_SLOTS = 2  # compiled in setup(); a request with more sections compiles a wider model
_ON_SURFACE = object()  # a fresh guard still exactly zero at a step's end (see _first_crossing)
_OUTCOME = model.hy.taylor_outcome
# heyoka's outcomes as Python integers: comparing two of heyoka's enum values costs about 0.4 us,
# and an arc compared several (int() converts one, once per propagation)
_SUCCESS_CODE, _TIME_LIMIT_CODE = int(_OUTCOME.success), int(_OUTCOME.time_limit)
_STEP_LIMIT_CODE, _NONFINITE_CODE = int(_OUTCOME.step_limit), int(_OUTCOME.err_nf_state)


def _any_hits(logs) -> bool:
    """Whether a section callback recorded a crossing in this arc."""
    for log in logs:
        if log.hits:
            return True
    return False


class _Compiled:
    """A compiled Taylor integrator of the friction family with its structure and its arrays.

    heyoka hands its arrays out as numpy views of the integrator's own storage, a new view per
    attribute read (about 0.45 us each; an arc read five to eight of them). The storage is fixed
    when the integrator is built and the views keep the integrator alive, so they are read once.
    """

    __slots__ = ("st", "ta", "state", "pars", "tc", "order", "logs")

    def __init__(self, st: model.Structure, ta) -> None:
        self.st, self.ta = st, ta
        self.state, self.pars, self.tc = ta.state, ta.pars, ta.tc
        self.order = int(ta.order)
        self.logs = [ev.callback for ev in ta.nt_events]  # the section callbacks (SectionLog)

    def __reduce__(self):
        # A pickled or copied view would be an array of its own, no longer the integrator's storage:
        # the views are read again from the unpickled integrator.
        return _Compiled, (self.st, self.ta)


class _StepRows:
    """A step callback of ``propagate_until``: the states at the requested times, each from the Taylor
    polynomial of the step that holds it, as heyoka takes the step.

    heyoka's continuous output (``c_output=True``) would give the same polynomials, but each
    propagation that asks for it builds an object with its own compiled evaluator: about 1 ms per
    call on heyoka 7.13, where a whole arc of the 2-DOF oscillator takes a few microseconds. The
    callback runs after every step (the last one too, cut short at the arc's terminal event or
    end), so every time up to the step's end is taken from that step's polynomial, and
    ``update_d_output`` evaluates it there.

    ``t_eval``: the request's times (doubles, ascending), of which ``rows`` holds the states of the
    first ``len(rows)`` already; ``fp``: the integrator's precision.
    """

    __slots__ = ("fp", "t_eval", "k", "rows")

    def __init__(self, fp, t_eval: np.ndarray, rows: list) -> None:
        self.fp, self.t_eval, self.k, self.rows = fp, t_eval, len(rows), rows

    def __call__(self, ta) -> bool:
        fp, t_eval, k, t = self.fp, self.t_eval, self.k, ta.time
        while k < t_eval.size:
            te = fp(float(t_eval[k]))
            if te > t:
                break
            self.rows.append(np.array(ta.update_d_output(te), copy=True))
            k += 1
        self.k = k
        return True


def _step_rows(fp, t_eval: np.ndarray, rows: list, t_end: float) -> _StepRows | None:
    """The :class:`_StepRows` of the times of ``t_eval`` after the ``len(rows)`` ones already taken;
    ``None`` if none is before ``t_end`` (the propagation then needs no callback)."""
    if len(rows) >= t_eval.size or t_eval[len(rows)] > t_end:
        return None
    return _StepRows(fp, t_eval, rows)


def _caps(precision: str) -> Capabilities:
    return Capabilities(
        event_location="taylor-root",
        order=None,
        adaptive=True,
        needs_jacobian=False,
        supports_nonlinear=True,
        precision=precision,
        step_option="tol",
        checks_steps=True,
    )


class HeyokaIntegrator(Integrator):
    """Base of the heyoka adapters; subclasses set the precision."""

    ecosystem = "heyoka"

    precision: ClassVar[str] = "double"
    #: The double-zero guard (docs/core.md): a guard that starts an arc on its own surface is kept off
    #: heyoka's event detection for the arc's first Taylor step, and for up to this many steps while it
    #: stays exactly on its surface; its crossings there are found on the steps' polynomials. 0 turns
    #: the guard off (heyoka alone: tests show what it then does).
    fresh_steps: ClassVar[int] = 8
    options = {
        "tol": Option(
            None,
            float,
            lower=0.0,
            upper=1e-2,
            nullable=True,
            doc="Taylor tolerance (relative and absolute); None: the precision's epsilon",
        ),
        "high_accuracy": Option(False, bool, doc="heyoka's compensated summation for long runs"),
        "compact_mode": Option(None, bool, nullable=True, doc="compile in compact mode; None: only for quad precision"),
        "loop": LOOP_OPTION,
    }
    accuracy_levels = ({"tol": 1e-6}, {"tol": 1e-10}, {"tol": 1e-14})

    @staticmethod
    def _written_symbolically(problem) -> bool:
        """Whether ``problem`` runs through its symbolic form (every family but friction's)."""
        return not problem_traits(problem).belt_blocks

    def check_problem(self, problem) -> None:
        """The refusals of :meth:`setup`, without compiling (and without keeping any state)."""
        super().setup(problem)
        if self._written_symbolically(problem) and not symbolic.supports(problem):
            raise UnsupportedProblemError(
                f"{self.name} builds heyoka's expressions of the friction family's field; {problem!r} is of the "
                f"{problem.family or 'other'!r} family, which has no heyoka form"
            )

    def sections_refusal(self, problem) -> str:
        if self._written_symbolically(problem):
            return (
                f"{self.name} records no state sections on {problem.name} (its heyoka form has no section events; "
                "the friction family's has)"
            )
        return ""

    def native_refusal(self, problem, forced: bool = False) -> str:
        """heyoka runs a friction problem's whole run itself (:mod:`nsbench.integrators._heyoka_native`),
        except where a slip starts on a double zero of its guard (see the module docstring), and in long
        double and quad unless asked (``loop = 'native'``): the core's step between two arcs of a native
        run takes the event's time and state as doubles, so an extended precision's events would come
        out at double accuracy (seen: 2.7e-14 from exact-mp where the per-arc path gives 1.7e-23)."""
        if self.precision != "double" and not forced:
            return (
                f"the core's step between the arcs of a native run works in doubles, which would round "
                f"{self.name}'s {self.precision} event times (loop = 'native' runs it so all the same)"
            )
        if self._written_symbolically(problem):
            if not getattr(problem, "symbolic_modes", ()):
                return f"{problem.name} names no symbolic_modes, which {self.name}'s own loop selects among"
            if forced:
                return ""
            if problem.problem_class == "sliding":
                return (
                    "a sliding mode is left where the field is tangent to the switching surface: the next phase "
                    "starts on a double zero of its guard, which heyoka's event detection cannot see past"
                )
            return ""
        if forced:
            return ""
        c = problem.coefficients
        double = [i + 1 for i in range(c.n_blocks) if c.fs[i] >= c.fr[i]]
        if double:
            blocks = ", ".join(str(b) for b in double)
            return (
                f"a slip that starts at the static limit starts on a double zero of its guard (fs >= fr on block "
                f"{blocks}), which heyoka's event detection cannot see past"
            )
        return ""

    def _native_model(self, sections: tuple = ()):
        """The native integrator for these sections (compiled once per structure and directions, kept across
        setups as the per-arc models are); the seconds a compilation took (0 if it was there)."""
        compact = self.settings["compact_mode"]
        if compact is None:
            compact = self.precision == "quad"
        if self._symbolic:  # one selector per mode (the problem's symbolic_modes); no sections
            problem = self._problem
            key = ("native", problem.name, problem.packed.tobytes(), self.precision, self.settings["tol"])
            key += (self.settings["high_accuracy"], compact)
            own = self.__dict__.setdefault("_own_models", {})
            if key not in own:
                ta, seconds = native_heyoka.compiled_symbolic(problem, *key[3:])
                modes = tuple(tuple(int(v) for v in m) for m in problem.symbolic_modes)
                own[key] = native_heyoka.NativeModel(None, ta, self.precision, modes)
                return own[key], seconds
            return own[key], 0.0
        st = model.Structure.of(self._problem, len(sections))
        directions = tuple(int(sec.direction) for sec in sections)
        key = ("native", st, directions, self.precision, self.settings["tol"], self.settings["high_accuracy"], compact)
        own = self.__dict__.setdefault("_own_models", {})
        if key in own:
            return own[key], 0.0
        ta, seconds = native_heyoka.compiled(st, directions, *key[3:])
        own[key] = native_heyoka.NativeModel(st, ta, self.precision)
        return own[key], seconds

    def run(self, request: RunRequest) -> RunReport:
        """The whole run with heyoka's own event loop (whole-run protocol; :mod:`._heyoka_native`)."""
        problem = request.problem
        if getattr(self, "_problem", None) is not problem:
            self.setup(problem)
        if self._symbolic and request.sections:
            return native_heyoka.refuse(request, self.sections_refusal(problem))
        # compiled on a configuration's first native run (a per-arc one never needs it), timed as setup
        tic = time.perf_counter()
        m, seconds = self._native_model(request.sections)
        native_heyoka.warm_up(problem, self.precision)
        self.compile_time += seconds
        prepared = time.perf_counter() - tic
        report = native_heyoka.run(m, request, np.zeros(0) if self._symbolic else self._coefficients)
        report.prepare_time += prepared
        return report

    def batch_size(self) -> int:
        """Runs one batch takes (heyoka's SIMD lanes for doubles; :meth:`run_batch`)."""
        return batch_heyoka.lanes()

    def batch_refusal(self, problems: Sequence, sections: tuple = ()) -> str:
        """Why ``problems`` (with these sections) do not run together in heyoka's batch mode; ``''`` if they do.

        A batch takes problems of one structure (:class:`~nsbench.integrators._heyoka_model.Structure`:
        blocks, cubic springs, forcing, friction law; the same sections) that differ only in the
        runtime parameters, each of which this configuration runs natively (:meth:`native_refusal`), in
        double precision (a long double or quad run rounds the core's step to doubles: value by value).
        """
        if self.precision != "double":
            return f"{self.name} runs value by value: heyoka's batch mode here is double precision only"
        if self.settings.get("loop", "auto") == "per-arc":
            return "loop = 'per-arc'"
        if not problems:
            return "no problems"
        first = None
        for problem in problems:
            if self._written_symbolically(problem):
                return f"{problem.name} is written symbolically; its native run has no batch form"
            refusal = self.native_refusal(problem)
            if refusal:
                return refusal
            key = (model.Structure.of(problem, len(sections)), type(problem.data), problem.mode_size)
            if first is None:
                first = key
            elif key != first:
                return f"{problem.name} differs in structure from {problems[0].name} ({key[0]} vs {first[0]})"
        return ""

    def _batch_model(self, sections: tuple):
        """The batch integrator for these sections (compiled once per structure and directions, kept)."""
        st = model.Structure.of(self._problem, len(sections))
        directions = tuple(int(sec.direction) for sec in sections)
        compact = bool(self.settings["compact_mode"])
        key = ("batch", st, directions, self.settings["tol"], self.settings["high_accuracy"], compact)
        own = self.__dict__.setdefault("_own_models", {})
        if key in own:
            return own[key], 0.0
        ta, seconds = batch_heyoka.compiled(st, directions, *key[3:])
        own[key] = batch_heyoka.BatchModel(st, ta)
        return own[key], seconds

    def run_batch(self, requests: Sequence[RunRequest]) -> list[RunReport]:
        """Whole runs of up to :meth:`batch_size` problems that :meth:`batch_refusal` accepts, one per SIMD
        lane of one heyoka integrator (:mod:`._heyoka_batch`): a report each, as :meth:`run` gives."""
        problem = requests[0].problem
        if getattr(self, "_problem", None) is not problem:
            self.setup(problem)
        tic = time.perf_counter()
        bm, seconds = self._batch_model(requests[0].sections)
        batch_heyoka.entries(problem)
        native_heyoka.warm_up(problem, "double")
        self.compile_time += seconds
        prepared = time.perf_counter() - tic
        coefficients = [np.array(model.coefficient_values(r.problem), dtype=float) for r in requests]
        reports = batch_heyoka.run(bm, requests, coefficients)
        reports[0].prepare_time += prepared
        return reports

    def setup(self, problem) -> None:
        self.check_problem(problem)
        self._symbolic = self._written_symbolically(problem)
        self._problem = problem
        self._models: dict[int, _Compiled] = {}
        self._fp = model.FP_TYPES.get(self.precision)
        if self._fp is None:  # pragma: no cover - depends on the heyoka build
            raise ConfigError(f"{self.name}: this heyoka build has no {self.precision} type")
        self.compile_time = 0.0
        self._carry = None  # the last event's state in our precision (see _continued)
        self._pars_sections, self._pars_cache = None, {}  # runtime parameters per mode (see _pars)
        self._compiled_in_advance = 0.0
        self._fresh_plan: dict[tuple, Any] = {}  # per mode and guards: the mode array and the guards' kinds
        self._n_states = problem.n_states
        self._no_rows = np.empty((problem.n_states, 0))
        self._no_rows.flags.writeable = False
        self._root = np.zeros(1)  # where _velocity_crossing writes its root
        self._v0 = None if self._symbolic else float(problem.coefficients.v0)
        if self._symbolic:
            self._mode_tas: dict[tuple[int, ...], Any] = {}
            # every mode the problem names (else its start mode) now, so that no run compiles or copies one
            start = problem.initial_mode(0.0, problem.initial_state())
            for mode in getattr(problem, "symbolic_modes", (start,)):
                self._mode_ta(mode)
            self._compiled_in_advance = 0.0
            return
        self._coefficients = np.array(model.coefficient_values(problem), dtype=float)
        self._model(_SECTION_SLOTS)
        if self.precision == "double":
            crossing.warm_up()  # load (or, once per install, compile) the compiled search: not a run's cost
        # the law's guard function as _fresh_guards calls it, loaded (or compiled) here, not in a run
        self._state = np.array(problem.initial_state(), dtype=float)
        start = problem.initial_mode(0.0, self._state)
        problem.law.guard_value(problem.data.p, problem.mode_array(start), 0, 0, 0.0, self._state)
        self._compiled_in_advance = 0.0

    def _model(self, n_sections: int):
        """The compiled integrator with at least ``n_sections`` section slots."""
        if n_sections <= _SECTION_SLOTS and _SECTION_SLOTS in self._models:  # every arc of most runs
            return self._models[_SECTION_SLOTS]
        usable = [n for n in self._models if n >= n_sections]
        if usable:
            return self._models[min(usable)]
        compact = self.settings["compact_mode"]
        if compact is None:
            compact = self.precision == "quad"
        st = model.Structure.of(self._problem, max(n_sections, _SECTION_SLOTS))
        key = (st, self.precision, self.settings["tol"], self.settings["high_accuracy"], compact)
        # kept across setups: a sweep's next value has the same structure, and its coefficients, like
        # the mode, are runtime parameters (a copy of heyoka's compiled integrator costs milliseconds)
        own = self.__dict__.setdefault("_own_models", {})
        if key in own:
            ta, seconds = own[key], 0.0
        else:
            ta, seconds = model.compiled(*key)
            own[key] = ta
        self.compile_time += seconds  # setup's share lands in setup_time; later ones in extra
        self._compiled_in_advance = getattr(self, "_compiled_in_advance", 0.0) + seconds
        self._models[st.n_sections] = _Compiled(st, ta)
        return self._models[st.n_sections]

    def _continued(self, request: ArcRequest):
        """The kept event state, in our precision, if ``request`` continues from it; else ``None``.

        The request continues the last arc if it starts at that arc's returned
        time (both parts) with its returned double state, up to velocities that
        the transition set to exactly ``v0``; those are set to ``v0`` here in
        our precision (``v0`` is a double, so the conversion is exact).
        Returns ``(dtime, state)``.
        """
        carry = self._carry
        if carry is None:
            return None
        problem, t, t_lo, y_out, dtime, state = carry
        reset = reset_velocities(request, t, t_lo, y_out) if request.problem is problem else None
        if reset is None:
            return None
        state = np.array(state, copy=True)
        state[reset] = self._fp(float(problem.coefficients.v0))
        return dtime, state

    def _keep(self, request: ArcRequest, fired, t_stop: float, t_lo: float, y_out, dtime, y_fp) -> None:
        """Keep the state where an arc stopped at an event, for :meth:`_continued` (extended precisions)."""
        self._carry = None
        if fired is None:  # the arc ended at t_end: the next request starts afresh
            return
        self._carry = (
            request.problem,
            t_stop,
            t_lo,
            np.array(y_out, dtype=float, copy=True),
            dtime,
            np.array(y_fp, copy=True),
        )

    def _pars(self, st: model.Structure, request: ArcRequest, sections: bool = True) -> np.ndarray:
        """The runtime parameters of an arc (coefficients, mode, guards, sections) in our precision.

        ``sections=False``: every section slot off (its event function a constant, so heyoka
        calls no section callback), for the part of an arc before ``request.sections_from``.
        Kept per mode and structure for the sections of the last request (one run
        hands every arc the same sections): an arc of a mode seen before only copies them in.
        """
        if request.sections is not self._pars_sections:
            self._pars_sections, self._pars_cache = request.sections, {}
        # first by the identity of the guards (the problem hands one tuple per mode; the tuple is
        # kept in the entry, so its id is not reused), then by what the parameters depend on
        quick = self._pars_cache.get((id(st), id(request.guards), sections))
        if quick is not None and quick[0] is request.guards and quick[1] == request.mode:
            return quick[2]
        key = (id(st), request.mode, tuple((g.kind, g.block, g.expected_sign) for g in request.guards), sections)
        cached = self._pars_cache.get(key)
        if cached is not None:
            self._pars_cache[(id(st), id(request.guards), sections)] = (request.guards, request.mode, cached)
            return cached
        pars = np.zeros(st.n_pars)
        pars[: self._coefficients.size] = self._coefficients
        nb = st.n_blocks
        for i, phase in enumerate(request.mode):
            pars[st.mode_offset + i] = 1.0 if phase == STICK else 0.0
            pars[st.mode_offset + nb + i] = float(phase)
        for guard in request.guards:
            off = st.guard_par(guard)
            pars[off + model.GUARD_ACTIVE], pars[off + model.GUARD_SIGN] = 1.0, float(guard.expected_sign)
        for q, sec in enumerate(request.sections if sections else ()):
            off = st.section_offset(q)
            pars[off + model.SECTION_ACTIVE], pars[off + model.SECTION_LEVEL] = 1.0, sec.level
            coeffs = off + model.SECTION_COEFFS
            pars[coeffs : coeffs + st.n_mech] = sec.coeffs
        cached = self._pars_cache[key] = pars.astype(self._fp)
        self._pars_cache[(id(st), id(request.guards), sections)] = (request.guards, request.mode, cached)
        return cached

    @staticmethod
    def _quiet_until(request: ArcRequest) -> float | None:
        """The time up to which the arc runs with its sections off, or ``None`` (sections on throughout).

        Crossings before ``request.sections_from`` are not wanted (a sweep's transient: most of its
        section callbacks, a quarter of a sweep value's time). The arc then stops its propagation
        there, which heyoka's next step starts from; an arc with dense states keeps one
        propagation (its dense output is of one call).
        """
        t = request.sections_from
        if request.sections and request.t0 < t < request.t_end and not request.t_eval.size:
            return t
        return None

    def _load(self, c: _Compiled, request: ArcRequest, carried=None, sections: bool = True):
        """Write coefficients, mode, sections, time and state into ``c.ta``; return the start time.

        ``carried``: ``(dtime, state)`` in our precision from :meth:`_continued`, used instead
        of the request's double time and state. ``sections=False``: the section slots off.
        """
        fp, st, ta = self._fp, c.st, c.ta
        c.pars[:] = self._pars(st, request, sections)
        for log in c.logs:
            if log.hits:
                log.hits.clear()
        if carried is not None:
            ta.dtime = carried[0]
            c.state[:] = carried[1]
            ta.reset_cooldowns()
            return ta.time
        state = request.y0 if fp is float else np.asarray(request.y0, dtype=float).astype(fp)
        # heyoka keeps time as a double-length number: the start t0 + t0_lo is exact.
        ta.dtime = (fp(request.t0), fp(request.t0_lo))
        t0 = ta.time
        if st.forced:
            w = np.array([self._coefficients[st.coefficient("w")]], dtype=float).astype(fp)
            phase = w * (fp(request.t0) + fp(request.t0_lo))
            n = st.n_mech
            c.state[:n] = state
            c.state[n] = np.cos(phase)[0]
            c.state[n + 1] = np.sin(phase)[0]
        else:
            c.state[:] = state
        ta.reset_cooldowns()
        return t0

    # -- problems written symbolically (_heyoka_symbolic)
    def _mode_ta(self, mode):
        ta = self._mode_tas.get(tuple(mode))
        if ta is None:
            compact = self.settings["compact_mode"]
            if compact is None:
                compact = self.precision == "quad"
            ta, seconds = symbolic.compiled(
                self._problem,
                tuple(mode),
                self.precision,
                self.settings["tol"],
                self.settings["high_accuracy"],
                compact,
            )
            self.compile_time += seconds
            self._compiled_in_advance += seconds
            self._mode_tas[tuple(mode)] = ta
        return ta

    def _advance_symbolic(self, request: ArcRequest) -> ArcResult:
        """One arc of a symbolically written problem (see the module docstring)."""
        problem, fp, n = request.problem, self._fp, request.problem.n_states
        if request.sections:
            return ArcResult(
                t=request.t0,
                y=np.array(request.y0, dtype=float),
                fired=None,
                y_eval=np.empty((n, 0)),
                status=Status.INTEGRATOR_FAILURE,
                message=self.sections_refusal(problem),
            )
        ta = self._mode_ta(request.mode)
        carry, self._carry = self._carry, None
        same = (
            carry is not None
            and carry[0] is problem
            and float(request.t0) == carry[1]
            and float(request.t0_lo) == carry[2]
            and np.array_equal(np.asarray(request.y0, float), carry[3])
        )
        if same and self.precision != "double":
            ta.dtime, ta.state[:] = carry[4], carry[5]
        else:
            ta.dtime = (fp(request.t0), fp(request.t0_lo))
            ta.state[:] = np.asarray(request.y0, dtype=float).astype(fp)
        if request.guards:  # (a mode without guards has no events, and heyoka refuses the call)
            ta.reset_cooldowns()  # an event's cooldown acts within this arc only (see the fresh step below)
        if request.max_steps <= 0:
            return ArcResult(
                t=request.t0,
                y=np.array(request.y0, dtype=float),
                fired=None,
                y_eval=np.empty((n, 0)),
                status=Status.BUDGET_EXHAUSTED,
                message=f"step budget exhausted at t = {request.t0:.6g}",
            )
        t_start, nsteps, hit, rows = ta.time, 0, None, []
        fresh = self._fresh_guards(request)
        outcome = _SUCCESS_CODE
        if fresh:  # heyoka looks for no root of an event that is zero where a step starts: one step alone
            result, _ = ta.step(fp(request.t_end) - t_start)
            outcome = int(result)
            nsteps = 1
            own = -outcome - 1
            at_start = None
            if ta.time == t_start and own in fresh:
                # ... unless the guard's rate there points into its surface by a rounding error (a tangential start:
                # an exit from sliding, carried in extended precision, has u_eq one ulp inside its limit): heyoka then
                # reports the start itself, at once and again at every step from there. Its report set the event's
                # cooldown (symbolic.START_COOLDOWN), so the step is taken once more, past the start, and the guard's
                # own values on it decide, as for exact (docs/model.md): a crossing after it left its surface, or,
                # on its wrong side at the step's end with none, the phase ends at once as heyoka said.
                at_start = (ta.dtime, np.array(ta.state, copy=True), outcome)
                result, _ = ta.step(fp(request.t_end) - t_start)
                outcome = int(result)
                nsteps = 2
            for te in request.t_eval[int(np.searchsorted(request.t_eval, float(t_start), side="right")) :]:
                if fp(float(te)) > ta.time:
                    break
                rows.append(np.array(ta.update_d_output(fp(float(te))), copy=True))
            for q in fresh:
                root = symbolic.first_crossing(ta, fp, request.guards[q], t_start, ta.time)
                if root is not None and (hit is None or root < hit[0]):
                    hit = (root, q, np.array(ta.update_d_output(root), copy=True))
            if at_start is not None and hit is None:
                guard = request.guards[own]
                if not guard.expected_sign * float(guard.value(float(ta.time), np.asarray(ta.state).astype(float))) > 0:
                    ta.dtime, ta.state[:], outcome = at_start  # back to heyoka's report at the start
                    rows = []
        if hit is None and outcome in (_SUCCESS_CODE, _TIME_LIMIT_CODE) and ta.time < fp(request.t_end):
            if nsteps >= request.max_steps:
                outcome = _STEP_LIMIT_CODE
            else:
                result, _, _, taken, _, _ = ta.propagate_until(
                    fp(request.t_end),
                    max_steps=int(request.max_steps) - nsteps,
                    callback=_step_rows(fp, request.t_eval, rows, request.t_end),
                )
                outcome = int(result)
                nsteps += int(taken)
        if hit is not None:
            hi, lo, y_fp, fired, status, message = hit[0], fp(0.0), hit[2], hit[1], Status.SUCCESS, ""
        else:
            (hi, lo), y_fp = ta.dtime, ta.state
            fired, status, message = None, Status.SUCCESS, ""
            if outcome == _STEP_LIMIT_CODE:
                status, message = Status.BUDGET_EXHAUSTED, f"step budget exhausted at t = {float(hi):.6g}"
            elif outcome == _NONFINITE_CODE:
                status, message = Status.INTEGRATOR_FAILURE, f"non-finite state at t = {float(hi):.6g}"
            elif outcome not in (_SUCCESS_CODE, _TIME_LIMIT_CODE):
                event = -outcome - 1
                if 0 <= event < len(request.guards):
                    fired = event
                else:
                    status, message = Status.INTEGRATOR_FAILURE, f"unexpected heyoka outcome {_OUTCOME(outcome)!r}"
        t_stop = float(hi)
        t_lo = float((hi - fp(t_stop)) + lo)
        if fired is None and status.ok:
            t_stop, t_lo = request.t_end, 0.0
        n_eval = int(np.searchsorted(request.t_eval, t_stop, side="right")) if status.ok else 0
        rows = rows[:n_eval]
        rows += [y_fp] * (n_eval - len(rows))  # no step was taken
        y_eval = np.array([np.asarray(r[:n]).astype(float) for r in rows]).T if rows else np.empty((n, 0))
        y_out = np.asarray(y_fp[:n]).astype(float)
        if fired is not None and status.ok:
            self._carry = (problem, t_stop, t_lo, y_out, (hi, lo), np.array(y_fp, copy=True))
        extra = {"taylor_coefficients": nsteps * int(ta.order)}
        if self._compiled_in_advance:
            extra["compile_seconds"], self._compiled_in_advance = self._compiled_in_advance, 0.0
        return ArcResult(
            t=t_stop,
            y=y_out,
            fired=fired,
            y_eval=y_eval,
            nfev=nsteps,
            njev=0,
            nsteps=nsteps,
            extra=extra,
            status=status,
            message=message,
            t_lo=t_lo,
        )

    def advance(self, request: ArcRequest) -> ArcResult:
        problem = request.problem
        if getattr(self, "_problem", None) is not problem:
            self.setup(problem)
        if self._symbolic:
            return self._advance_symbolic(request)
        c = self._model(len(request.sections))
        st, ta = c.st, c.ta
        carried = None if self.precision == "double" else self._continued(request)
        self._carry = None
        quiet = self._quiet_until(request)
        t0 = self._load(c, request, carried, sections=quiet is None)
        fp, n, logs = self._fp, self._n_states, c.logs
        if request.max_steps <= 0:
            return ArcResult(
                t=request.t0,
                y=np.array(request.y0, dtype=float),
                fired=None,
                y_eval=np.empty((n, 0)),
                status=Status.BUDGET_EXHAUSTED,
                message=f"step budget exhausted at t = {request.t0:.6g}",
            )
        outcome, fresh_hit, nsteps, first_rows = self._propagate(c, request, quiet)
        if outcome is None:  # the first steps, with the sections off, went past sections_from: again, with them
            t0 = self._load(c, request, carried)
            outcome, fresh_hit, redone, first_rows = self._propagate(c, request, None, nsteps)
            nsteps += redone
        if fresh_hit is not None:  # a fresh guard crossed inside the first step
            hi, lo, y_fp = fresh_hit[0], fp(0.0), fresh_hit[2]
        else:
            (hi, lo), y_fp = ta.dtime, c.state
        t_stop = float(hi)
        t_lo = float((hi - fp(t_stop)) + lo)
        fired, status, message = self._verdict(len(model.GUARD_SLOT) * st.n_blocks, outcome, fresh_hit, request, t_stop)
        if fresh_hit is None and outcome == _TIME_LIMIT_CODE:
            t_stop, t_lo = request.t_end, 0.0
        extra = {"taylor_coefficients": nsteps * c.order}
        if self._compiled_in_advance:  # a wider model compiled for more sections
            extra["compile_seconds"], self._compiled_in_advance = self._compiled_in_advance, 0.0
        n_eval = int(np.searchsorted(request.t_eval, t_stop, side="right")) if status.ok and request.t_eval.size else 0
        rows = first_rows[:n_eval]
        rows += [y_fp] * (n_eval - len(rows))  # no step was taken
        y_eval = np.array([np.asarray(r[:n]).astype(float) for r in rows]).T if rows else self._no_rows
        y_out = np.array(y_fp[:n], dtype=float)
        if self.precision != "double" and status.ok:
            self._keep(request, fired, t_stop, t_lo, y_out, (hi, lo), y_fp)
        return ArcResult(
            t=t_stop,
            y=y_out,
            fired=fired,
            y_eval=y_eval,
            section_hits=model.section_hits(ta, request, t0, hi, logs) if _any_hits(logs) else [],
            nfev=nsteps,
            njev=0,
            nsteps=nsteps,
            extra=extra,
            status=status,
            message=message,
            t_lo=t_lo,
        )

    def _propagate(self, c: _Compiled, request: ArcRequest, quiet: float | None, spent: int = 0):
        """Run the arc: a special first step if the phase starts on a guard, then heyoka's propagation.

        ``quiet``: the sections are off (see :meth:`_load`) up to this time, then on. If the first
        steps went past it (crossings after it were not looked for), the outcome is ``None``: the
        arc is to be run again with the sections on. ``spent``: steps this arc has already used.
        Returns heyoka's outcome as an integer (``int(taylor_outcome)``), the fresh guards'
        crossing (see :meth:`_first_step`), the steps taken and the states at the request's times
        up to where the arc stopped (and perhaps a few past it, in the last step).
        """
        fp, ta, nsteps, fresh_hit, rows = self._fp, c.ta, 0, None, []
        budget = int(request.max_steps) - spent
        fresh = self._fresh_guards(request) if self.fresh_steps > 0 else []
        outcome = _SUCCESS_CODE
        if fresh:
            outcome, fresh_hit, nsteps = self._first_step(c, request, fresh, rows)
        if quiet is not None and not (ta.time if fresh_hit is None else fresh_hit[0]) <= fp(quiet):
            return None, None, nsteps, rows
        if fresh_hit is not None or outcome != _SUCCESS_CODE:
            return outcome, fresh_hit, nsteps, rows
        if quiet is not None:  # the sections off up to there, then on
            if nsteps < budget:  # heyoka reads max_steps=0 as "no limit"
                result, _, _, taken, _, _ = ta.propagate_until(fp(quiet), max_steps=budget - nsteps)
                outcome = int(result)
                nsteps += int(taken)
            c.pars[:] = self._pars(c.st, request)
            if outcome != _TIME_LIMIT_CODE and outcome != _SUCCESS_CODE:  # an event, a failure, the budget
                return outcome, fresh_hit, nsteps, rows
        if nsteps >= budget:
            return _STEP_LIMIT_CODE, fresh_hit, nsteps, rows
        result, _, _, taken, _, _ = ta.propagate_until(
            fp(request.t_end), max_steps=budget - nsteps, callback=_step_rows(fp, request.t_eval, rows, request.t_end)
        )
        return int(result), fresh_hit, nsteps + int(taken), rows

    @staticmethod
    def _verdict(n_events: int, outcome: int, fresh_hit, request: ArcRequest, t_stop: float):
        """``(fired, status, message)`` from heyoka's outcome as an integer (``n_events``: the model's
        terminal events)."""
        if fresh_hit is not None:
            return fresh_hit[1], Status.SUCCESS, ""
        if outcome == _TIME_LIMIT_CODE:
            return None, Status.SUCCESS, ""
        if outcome == _STEP_LIMIT_CODE:
            return None, Status.BUDGET_EXHAUSTED, f"step budget exhausted at t = {t_stop:.6g}"
        if outcome == _NONFINITE_CODE:
            return None, Status.INTEGRATOR_FAILURE, f"non-finite state at t = {t_stop:.6g}"
        event = -outcome - 1
        if 0 <= event < n_events:
            fired = model.guard_index(request, event)
            if fired is None:
                return (
                    None,
                    Status.INTEGRATOR_FAILURE,
                    (f"event {event} of an inactive phase fired at t = {t_stop:.17g}"),
                )
            return fired, Status.SUCCESS, ""
        return None, Status.INTEGRATOR_FAILURE, f"unexpected heyoka outcome {_OUTCOME(outcome)!r}"

    def _fresh_guards(self, request: ArcRequest) -> list[int]:
        """Guards exactly zero at the start: the phase starts on its own surface.

        A velocity guard ``v_i - v0`` is zero exactly when ``v_i == v0``: read from the state.
        The friction family's other guards are evaluated by the problem's compiled guard
        function called directly (about 1 us, against 15 us through :meth:`Guard.value`).
        """
        y0, problem = request.y0, request.problem
        # per mode and guard tuple (the tuple is kept in the plan, so its id is not reused)
        plan = self._fresh_plan.get((request.mode, id(request.guards))) if not self._symbolic else None
        if plan is None or plan[0] is not request.guards:
            if not self._symbolic:
                plan = self._fresh_plan[(request.mode, id(request.guards))] = (
                    request.guards,
                    problem.mode_array(request.mode),
                    tuple((g.kind == "velocity", g.code, g.block - 1) for g in request.guards),
                    problem.law.guard_value,
                    problem.data.p,
                )
            else:
                return [
                    q for q, g in enumerate(request.guards) if g.expected_sign * float(g.value(request.t0, y0)) == 0.0
                ]
        _, mode_arr, kinds, law_value, p = plan
        v0, y = self._v0, None
        fresh = []
        for q, (velocity, code, i) in enumerate(kinds):
            if velocity:
                zero = float(y0[2 * i + 1]) == v0
            else:
                if y is None:  # one array type for the compiled call (warmed in setup)
                    y = self._state
                    y[:] = y0
                zero = float(law_value(p, mode_arr, code, i, float(request.t0), y)) == 0.0
            if zero:
                fresh.append(q)
        return fresh

    def _first_step(self, c: _Compiled, request: ArcRequest, fresh: list[int], dense_rows: list):
        """Taylor steps with the fresh guards' events off; their crossings found on the steps' polynomials.

        A guard that starts the arc on its own surface starts from a zero of its
        event function, often a double zero (value and slope both zero: a slip
        that starts at ``fs = fr``, where the block's acceleration is zero). heyoka
        then reports that zero itself as a root (the run stops at once, and the
        transitions cycle: an event storm at one instant), or does not look for
        roots of a function that is zero where a step starts and misses the next
        one if the step reaches it (quad precision takes long steps). So the
        fresh guards are off for the first step, and for up to
        :attr:`fresh_steps` steps while a guard is still exactly on its surface
        at a step's end (a step cut short by the arc's end); a guard that has
        left its surface goes back on and heyoka's own detection takes over.
        Returns heyoka's outcome as an integer, ``(t, guard index, state)`` of the earliest
        fresh crossing (if any) and the number of steps taken.
        """
        fp, st, ta, pars = self._fp, c.st, c.ta, c.pars
        pending, best, outcome, steps = list(fresh), None, _SUCCESS_CODE, 0
        # in double, a velocity guard's crossings are found on the step's Taylor coefficients in one pass
        polynomial = self.precision == "double" and any(request.guards[q].kind == "velocity" for q in fresh)
        while pending:
            offsets = [st.guard_par(request.guards[q]) + model.GUARD_ACTIVE for q in pending]
            for off in offsets:
                pars[off] = fp(0.0)
            t_start, start = ta.time, ta.dtime
            result, _ = ta.step(fp(request.t_end) - t_start, write_tc=polynomial)
            outcome = int(result)
            steps += 1
            t_end = ta.time
            first = int(np.searchsorted(request.t_eval, float(t_start), side="right")) if request.t_eval.size else 0
            for te in request.t_eval[first:]:
                if fp(float(te)) > t_end:
                    break
                dense_rows.append(np.array(ta.update_d_output(fp(float(te))), copy=True))
            on_surface = []
            for q in pending:
                guard = request.guards[q]
                if polynomial and guard.kind == "velocity":
                    root = self._velocity_crossing(c.tc, guard, start, t_start, t_end)
                else:
                    root = self._first_crossing(ta, guard, t_start, t_end)
                if root is _ON_SURFACE:
                    on_surface.append(q)
                elif root is not None and (best is None or root < best[0]):
                    best = (root, q, np.array(ta.update_d_output(root), copy=True))
            for off in offsets:
                pars[off] = fp(1.0)
            if best is not None or outcome != _SUCCESS_CODE:
                break  # a crossing, an event of another guard, or the arc's end: a guard on its surface is no event
            if on_surface and steps >= self.fresh_steps:  # on its surface for good: the transition decides
                q = on_surface[0]
                best = (t_end, q, np.array(ta.update_d_output(t_end), copy=True))
                break
            pending = on_surface
        return outcome, best, steps

    def _velocity_crossing(self, tc: np.ndarray, guard, start, t_start: float, t_end: float):
        """:meth:`_first_crossing` of a velocity guard in double, on the Taylor polynomial of the step.

        The same samples, decisions and Illinois refinement, compiled
        (:func:`nsbench.integrators._heyoka_crossing.velocity_crossing`) on the step's Taylor
        coefficients of ``v_i`` (what heyoka's dense output evaluates), instead of one
        ``update_d_output`` call and a state copy per evaluation. ``tc``: the integrator's Taylor
        coefficients (``ta.tc``); ``start``: heyoka's double-length time where the step started
        (``t - start`` is the polynomial's variable).
        """
        out = self._root
        found = crossing.velocity_crossing(
            tc[2 * guard.block - 1], start[0], start[1], t_start, t_end, float(guard.expected_sign), self._v0, out
        )
        if found == crossing.ROOT:
            return float(out[0])
        if found == crossing.NONE:
            return None
        return t_start if found == crossing.AT_START else _ON_SURFACE

    def _first_crossing(self, ta, guard, t_start, t_end):
        """First zero of ``expected_sign * guard`` in ``(t_start, t_end]`` after it turned positive."""
        fp = self._fp
        problem = guard.problem
        sign = guard.expected_sign

        def value(t):
            y = ta.update_d_output(t)
            if guard.kind == "velocity":  # in the integrator's own precision
                return fp(sign) * (y[2 * guard.block - 1] - fp(problem.v0))
            return fp(sign * float(guard.value(float(t), np.asarray(y[: problem.n_states]).astype(float))))

        lo, g_lo, positive, negative = t_start, fp(0.0), False, False
        for k in range(1, 33):
            t = t_start + (t_end - t_start) * fp(k) / fp(32)
            g = value(t)
            if g > 0:
                lo, g_lo, positive = t, g, True
            elif positive:
                return model.illinois(value, lo, g_lo, t, g)
            negative = negative or g < 0
        g_end = value(t_end)
        if positive or g_end > 0:
            return None
        negative = negative or g_end < 0
        # on its wrong side: at once; still exactly on its surface (a short step): undecided, step on
        return t_start if negative else _ON_SURFACE


class Heyoka(HeyokaIntegrator):
    """heyoka's Taylor method in double precision, guards as terminal events."""

    name = "heyoka"
    precision = "double"
    capabilities = _caps("double")


class HeyokaLongDouble(HeyokaIntegrator):
    """heyoka's Taylor method in extended (80-bit long double) precision."""

    name = "heyoka-ld"
    precision = "long double"
    capabilities = _caps("long double")


class HeyokaQuad(HeyokaIntegrator):
    """heyoka's Taylor method in quadruple (real128) precision."""

    name = "heyoka-q"
    precision = "quad"
    capabilities = _caps("quad")
    accuracy_levels = ({"tol": 1e-10}, {"tol": 1e-20}, {"tol": 1e-30})
