"""One bifurcation sweep: its specification and the computation of one parameter value.

Each point integrates from rest (the standard initial condition) through the
transient, then records ``record`` section points: ``peaks`` (local maxima of
``x1``), ``strobe`` (states at ``t = 2 pi k / Omega``), ``stick`` (stick events)
or ``mapping`` (slip events: where the locus of sticking phase leaves a
sliding region). Every integrator runs through the engine
(:func:`nsbench.engine.run`: the defaults and the missed-crossing check of
``nsbench.simulate``), which stops at the last point wanted; an integrator with a
compiled kernel runs the whole point in compiled code. A value whose run fails
(a crossing stepped over among them) is a failure row, with no points.
The columns follow the problem: its state names, and event counts per block.
"""

from __future__ import annotations

import math
import time
from dataclasses import asdict, dataclass, field
from typing import TYPE_CHECKING, Any, Sequence

import numpy as np

if TYPE_CHECKING:
    import pandas as pd

from nsbench.bifurcation.request import parse_sweep  # noqa: F401 - the grammar of a sweep, its request parses it
from nsbench.errors import ConfigError, NsbenchError
from nsbench.problems.base import problem_traits
from nsbench.status import Status

SECTIONS = ("peaks", "strobe", "stick", "mapping")
#: A section of the states at every event of one kind of the problem: ``event:KIND`` (``stick`` is
#: ``event:stick``, ``mapping`` is ``event:slip``): what a problem with neither a position nor a force
#: (a thermostat, a relay) can be swept on.
EVENT_SECTION = "event:"
#: statuses of a value whose points are usable: ``rest`` is a motion that came to rest
#: (pure sliding damped out) before ``record`` points: its final state is its one point
OK_STATUSES = (Status.SUCCESS, Status.REST)
REST_SPEED = 1e-9
EVENT_COUNTS = (("stick", "sticks"), ("slip", "slips"), ("reverse", "reverses"))


def section_event_kind(section: str) -> str | None:
    """The event kind whose states a section records (``stick``, ``slip`` for ``mapping``, ``KIND`` for
    ``event:KIND``), or ``None`` for ``peaks`` and ``strobe``."""
    if section.startswith(EVENT_SECTION):
        return section[len(EVENT_SECTION) :]
    return {"stick": "stick", "mapping": "slip"}.get(section)


def check_section_name(section: object) -> None:
    """``ConfigError`` unless ``section`` is one of :data:`SECTIONS` or ``event:KIND``."""
    allowed = f"one of {', '.join(SECTIONS)}, or event:KIND (the states at the problem's KIND events)"
    if not isinstance(section, str):
        raise ConfigError(f"section {section!r} is not allowed; choose {allowed}")
    if section in SECTIONS or (section.startswith(EVENT_SECTION) and section[len(EVENT_SECTION) :].strip()):
        return
    raise ConfigError(f"section {section!r} is not allowed; choose {allowed}")


def section_refusal(problem, section: str) -> str:
    """Why ``section`` records nothing on ``problem`` (``''`` when it applies): peaks need a position whose
    rate is a state (:func:`nsbench.sections.peaks`), strobe a harmonic force, an event section events
    of its kind."""
    from nsbench.sections import peaks

    kind = section_event_kind(section)
    if kind is not None:
        if kind in problem.event_kinds:
            return ""
        return f"section {section} records {kind} events; {problem.name} has none (its event kinds: {', '.join(problem.event_kinds)})"
    if section == "strobe":
        return (
            ""
            if problem.is_forced and problem.forcing_frequency > 0
            else f"section strobe needs a harmonic force (F > 0, Omega > 0); {problem.name} has none"
        )
    try:
        peaks(problem)
    except ConfigError as exc:
        return str(exc)
    return ""


def refuse_section(problem, section: str, what: str = "") -> None:
    """``ConfigError`` (prefixed by ``what``, such as ``--section: ``) when ``section`` records nothing on
    ``problem`` (:func:`section_refusal`), naming the sections it can record."""
    refusal = section_refusal(problem, section)
    if refusal:
        others = [s for s in usable_sections(problem) if s != section]
        use = f"use section {' or '.join(others)}" if others else f"no section of a sweep applies to {problem.name}"
        raise ConfigError(f"{what}{refusal}; {use}")


def usable_sections(problem) -> tuple[str, ...]:
    """The sections a sweep of ``problem`` can record: of peaks, strobe, stick, mapping, and an
    ``event:KIND`` per event kind of the problem, those :func:`section_refusal` lets through."""
    named = [s for s in SECTIONS if not section_refusal(problem, s)]
    covered = {section_event_kind(s) for s in named}
    return (*named, *(EVENT_SECTION + k for k in problem.event_kinds if k not in covered))


def counter_columns(n_blocks: int) -> tuple[str, ...]:
    """``n_events``, then stick, slip and reverse counts per block, then ``nfev, nsteps``."""
    per_block = tuple(f"{name}{b}" for _, name in EVENT_COUNTS for b in range(1, n_blocks + 1))
    return ("n_events", *per_block, "nfev", "nsteps")


#: The text columns of a sweep table; ``index``, ``k``, ``n_points``, ``event_block`` and the
#: counters are integers, every other column a float (:func:`column_kinds`).
TEXT_COLUMNS = ("param", "section", "status", "message")


def column_kinds(columns: tuple[str, ...]) -> dict[str, str]:
    """``'text'``, ``'int'`` or ``'float'`` for each column of a sweep table (what a store keeps)."""
    ints = {"index", "k", "n_points", "event_block", "n_events", "nfev", "nsteps"}
    counts = tuple(name for _, name in EVENT_COUNTS)
    return {
        c: "text"
        if c in TEXT_COLUMNS
        else "int"
        if c in ints or (c.startswith(counts) and c.rstrip("0123456789") in counts)
        else "float"
        for c in columns
    }


def sweep_columns(state_names: tuple[str, ...]) -> tuple[str, ...]:
    """The tidy columns of a sweep of a problem with these state names."""
    n_blocks = len(state_names) // 2
    return (
        "param",
        "value",
        "index",
        "section",
        "k",
        "t",
        *state_names,
        "event_block",
        "status",
        "message",
        "n_points",
        *counter_columns(n_blocks),
        "wall_time",
    )


@dataclass(frozen=True)
class SweepSpec:
    """Everything that defines a sweep (and its stored results).

    Attributes
    ----------
    problem, case, params
        Registered problem, preset and fixed parameter overrides (dimensionless).
    name, start, stop, count
        The swept parameter and its grid ``linspace(start, stop, count)``.
    integrator, options
        Registered integrator and its options.
    section
        ``peaks``, ``strobe``, ``stick`` or ``mapping``.
    transient, record
        Time integrated before recording, and section points recorded per value.
    window
        Longest time after the transient spent collecting the points.
    """

    problem: str
    case: int
    name: str
    start: float
    stop: float
    count: int
    integrator: str = "exact"
    options: dict[str, Any] = field(default_factory=dict)
    section: str = "peaks"
    transient: float = 1500.0
    record: int = 100
    window: float | None = None
    params: dict[str, float] = field(default_factory=dict)

    def __post_init__(self) -> None:
        import numbers

        from nsbench.bifurcation import MAX_SWEEP_POINTS

        count = self.count
        if isinstance(count, bool) or not isinstance(count, numbers.Integral) or not 1 <= count <= MAX_SWEEP_POINTS:
            raise ConfigError(f"count = {count!r} must be a whole number from 1 to {MAX_SWEEP_POINTS}")
        for key in ("start", "stop"):
            value = getattr(self, key)
            if isinstance(value, bool) or not isinstance(value, numbers.Real) or not math.isfinite(value):
                raise ConfigError(f"{key} = {value!r} must be a finite number")
        if self.start == self.stop and count > 1:
            raise ConfigError(
                f"start = stop = {self.start!r}: {count} values of a sweep would all be the same; "
                "give a range, or count = 1"
            )
        check_section_name(self.section)
        if not (math.isfinite(self.transient) and self.transient >= 0):
            raise ConfigError(f"transient = {self.transient!r} must be a finite number >= 0")
        if int(self.record) != self.record or self.record < 1:
            raise ConfigError(f"record = {self.record!r} must be a positive integer")
        if self.window is not None and not (math.isfinite(self.window) and self.window > 0):
            raise ConfigError(f"window = {self.window!r} must be a finite number > 0")
        if self.name in self.params:
            raise ConfigError(f"parameter {self.name} is both swept and fixed")

    @property
    def values(self) -> np.ndarray:
        return np.linspace(self.start, self.stop, self.count)

    @property
    def record_window(self) -> float:
        return self.window if self.window is not None else 40.0 * self.record + 400.0

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> "SweepSpec":
        return cls(**d)

    def problem_at(self, value: float):
        """The problem at one parameter value (raises ``ConfigError`` on a bad value)."""
        from nsbench.problems import get_problem

        overrides: dict[str, Any] = {**self.params, self.name: float(value)}
        return get_problem(self.problem, case=self.case, **overrides)

    @property
    def state_names(self) -> tuple[str, ...]:
        """State names of the swept problem (the same at every value)."""
        return self.problem_at(self.start).state_names

    @property
    def columns(self) -> tuple[str, ...]:
        return sweep_columns(self.state_names)

    def check(self) -> None:
        """Fail early: build the problem at both ends and the integrator, check the section, then the
        integrator on the problem."""
        self.check_section()
        self.check_integrator()

    def check_integrator(self, setup: bool = True) -> None:
        """The refusals of the integrator on the problem: a whole-system method, a peaks section it cannot
        record and (``setup``) what its set-up refuses (exact on cubic springs, a step too long for
        the problem's fastest rate). The set-up may evaluate the problem's compiled field, so a
        command with several sweeps checks every one with ``setup=False`` first: each refusal
        that needs no compiled code comes before any that does."""
        from nsbench.integrators import get_integrator
        from nsbench.integrators.base import require_event_driven

        problem = self.problem_at(self.start)
        integ = get_integrator(self.integrator, **self.options)
        if setup:
            check_in_caller(integ, problem)
        else:
            require_event_driven(integ, "a sweep")
        refusal = integ.sections_refusal(problem) if type(integ).__module__.startswith("nsbench.") else ""
        if self.section == "peaks" and refusal:
            raise ConfigError(f"section peaks: {refusal}; use another integrator, or another section")

    def check_section(self) -> None:
        """The refusals of the section at both ends of the sweep (strobe needs a harmonic force; a section
        that records nothing on the problem names those that do). They read what the problem
        declares (its forcing, event kinds and ``position_rates``) and run nothing; a plug-in
        problem that declares no ``position_rates`` has a peaks section confirmed on its field."""
        ends = [self.problem_at(v) for v in (self.start, self.stop)]
        if self.section == "strobe":
            # the forcing period must exist everywhere; F may be 0 at one end of an F sweep
            for v, problem in zip((self.start, self.stop), ends):
                if problem.forcing_frequency <= 0:
                    raise ConfigError(
                        f"section strobe needs Omega > 0; at {self.name} = {v:g} Omega = {problem.forcing_frequency:g}"
                    )
            if not any(p.is_forced for p in ends):
                raise ConfigError(
                    "section strobe needs a harmonic force (F > 0) in the sweep; use peaks, stick or mapping"
                )
        if self.section != "strobe":  # strobe was checked at both ends above
            refuse_section(ends[0], self.section)


def check_in_caller(integ, problem, use: str = "a sweep") -> None:
    """The refusals of ``integ`` on ``problem`` that the calling process may run before its workers start.

    A whole-system method (``use`` names what needs an event-driven integrator); then a built-in
    integrator's :meth:`~nsbench.integrators.base.Integrator.check_problem` (compiling or
    loading compiled code is the workers' set-up); for a plug-in only the capabilities (a cubic
    problem refused): its own setup runs only in supervised workers, under their limit, since one
    that hangs or ends its process must not take the command with it.
    """
    from nsbench.integrators.base import require_event_driven
    from nsbench.integrators.base import Integrator

    require_event_driven(integ, use)  # a whole-system method would fail every value in the workers
    if type(integ).__module__.startswith("nsbench."):
        integ.check_problem(problem)
    else:
        Integrator.setup(integ, problem)


def default_section(*problems) -> str:
    """``strobe`` if any of ``problems`` (e.g. both ends of a sweep) is forced, ``peaks`` otherwise (a problem
    without a position, such as a thermostat, is then refused by :meth:`SweepSpec.check`, which names the
    ``event:KIND`` sections it has: which event kind is worth recording is the user's choice)."""
    forced = any(p.is_forced for p in problems)
    return "strobe" if forced and all(p.forcing_frequency > 0 for p in problems) else "peaks"


def orbit_section(*problems) -> str:
    """The section drawn along a continuation's periodic orbits by default: ``strobe`` if forced,
    ``peaks`` where the problem has a position (:func:`nsbench.sections.peak_variables`), else
    ``event:KIND`` for the problem's first event kind (the relay's ``cross``: the states where the orbit
    crosses its switching surface). Unlike a sweep, which refuses a problem without a position and lets
    the user pick the event kind, a continuation only draws these points beside its branches."""
    section = default_section(*problems)
    if section == "peaks" and section_refusal(problems[0], "peaks") and problems[0].event_kinds:
        return EVENT_SECTION + problems[0].event_kinds[0]
    return section


def strobe_times(problem, transient: float, record: int) -> np.ndarray:
    """The first ``record`` stroboscopic times ``2 pi k / Omega >= transient``."""
    period = 2.0 * math.pi / problem.forcing_frequency
    k0 = math.ceil(transient / period - 1e-12)
    return period * np.arange(k0, k0 + record)


#: The rows of one or more parameter values as columns (name -> array or list), before they
#: become a table: a worker sends this, and the caller makes one table per chunk (a pandas
#: table per value cost more than many values' integration).
Columns = dict[str, Any]


def _columns(
    spec: SweepSpec,
    names: tuple[str, ...],
    index: int,
    value: float,
    t,
    y,
    blocks,
    status: str,
    message: str,
    counters: dict[str, int],
    wall: float,
) -> Columns:
    n = len(t)
    rows = max(n, 1)
    states = np.full((rows, len(names)), np.nan)
    if n:
        states[:n] = y
    data: Columns = {
        "param": [spec.name] * rows,
        "value": np.full(rows, float(value)),
        "index": np.full(rows, int(index), np.int64),
        "section": [spec.section] * rows,
        "k": np.arange(n, dtype=np.int64) if n else np.array([-1], np.int64),
        "t": np.asarray(t, dtype=float) if n else np.array([np.nan]),
    }
    for j, col in enumerate(names):
        data[col] = states[:, j].copy()
    data["event_block"] = np.asarray(blocks, dtype=np.int64) if n else np.array([0], np.int64)
    data["status"] = [status] * rows
    data["message"] = [message] * rows
    data["n_points"] = np.full(rows, n, np.int64)
    for col in counter_columns(len(names) // 2):
        data[col] = np.full(rows, int(counters.get(col, 0)), np.int64)
    data["wall_time"] = np.full(rows, wall)
    return data


def join_columns(parts: "list[Columns | pd.DataFrame]") -> Columns:
    """The columns of several values (from :func:`point_columns`, or tables) as one set of columns."""
    if not parts:
        raise ValueError("no rows to join")
    cols = [p if isinstance(p, dict) else {c: p[c].to_numpy() for c in p.columns} for p in parts]
    data: Columns = {}
    for c in cols[0]:
        if isinstance(cols[0][c], list):
            data[c] = [v for part in cols for v in part[c]]
        else:
            data[c] = np.concatenate([np.asarray(part[c]) for part in cols])
    return data


def rows_frame(parts: "list[Columns | pd.DataFrame]") -> pd.DataFrame:
    """One table of the rows of several values (columns from :func:`point_columns`, or tables)."""
    import pandas as pd

    if parts and not any(isinstance(p, dict) for p in parts):
        return pd.concat(parts, ignore_index=True)
    return pd.DataFrame(join_columns(parts))


def first_index(part: "Columns | pd.DataFrame") -> int:
    """The value index of rows from :func:`point_columns` or :func:`compute_point`."""
    return int(part["index"][0]) if isinstance(part, dict) else int(part["index"].iloc[0])


def failure_rows(spec: SweepSpec, index: int, status: str, message: str, wall: float = math.nan) -> pd.DataFrame:
    """The one row of a value that gave no points: its ``status`` (``failure``, ``time limit``,
    ``crashed``) and the reason."""
    import pandas as pd

    return pd.DataFrame(failure_columns(spec, index, status, message, wall))


def failure_columns(spec: SweepSpec, index: int, status: str, message: str, wall: float = math.nan) -> Columns:
    """:func:`failure_rows` as columns."""
    return _columns(spec, spec.state_names, index, float(spec.values[index]), [], None, [], status, message, {}, wall)


def compute_point(spec: SweepSpec, index: int, integrator=None) -> pd.DataFrame:
    """Rows of one parameter value. Failures become a row with their status and reason."""
    import pandas as pd

    return pd.DataFrame(point_columns(spec, index, integrator))


def point_columns(spec: SweepSpec, index: int, integrator=None, problem=None) -> Columns:
    """:func:`compute_point` as columns (what a sweep's worker sends); ``problem``: the problem
    at this value if the caller has built it."""
    from nsbench.integrators import get_integrator

    value = float(spec.values[index])
    tic = time.perf_counter()
    try:
        problem = spec.problem_at(value) if problem is None else problem
        names = problem.state_names
        integ = integrator if integrator is not None else get_integrator(spec.integrator, **spec.options)
        t, y, blocks, status, message, counters = _point(spec, problem, integ)
    except (NsbenchError, ArithmeticError, ValueError, RuntimeError) as exc:
        return failure_columns(
            spec, index, Status.ERROR.value, f"{type(exc).__name__}: {exc}", time.perf_counter() - tic
        )
    return _columns(spec, names, index, value, t, y, blocks, status, message, counters, time.perf_counter() - tic)


def _finish(spec, n_found, status, t_last, rest=False) -> tuple[str, str]:
    if status != Status.SUCCESS:
        return status, f"stopped at t = {t_last:.6g}"
    if n_found < spec.record and rest:
        return Status.REST.value, (
            f"at rest (sliding equilibrium) by t = {t_last:.6g} after {n_found} "
            f"{spec.section} points; the final state is recorded"
        )
    if n_found < spec.record:
        return Status.INCOMPLETE.value, (
            f"{n_found} of {spec.record} {spec.section} points by t = {t_last:.6g} "
            f"(window {spec.record_window:g} after the transient)"
        )
    return Status.SUCCESS.value, ""


def at_rest(problem, mode, t: float, y: np.ndarray) -> bool:
    """Whether the state ``y`` at ``t`` is at rest: an equilibrium of its mode's vector field, every rate
    at most :data:`REST_SPEED` in size.

    A friction oscillator keeps the rule its sweeps have always used: every block's velocity (its odd
    state variables) within :data:`REST_SPEED` of zero, pure sliding damped out (the accelerations decay
    with the velocities there; the rule is kept so that a stored sweep is computed again the same)."""
    if problem_traits(problem).belt_blocks:
        return float(np.max(np.abs(y[1::2]))) <= REST_SPEED
    rate = np.asarray(problem.rhs(tuple(int(m) for m in mode), t, np.asarray(y, float)), float)
    return bool(np.isfinite(rate).all()) and float(np.max(np.abs(rate), initial=0.0)) <= REST_SPEED


def _point(spec: SweepSpec, problem, integ):
    """One value through the engine (:func:`nsbench.engine.run`, with its defaults and its missed-crossing
    check): the recorded points, status and counters of the recording window."""
    from nsbench.engine import run

    integ.setup(problem)
    t_end, kwargs = _run_arguments(spec, problem)
    return _read_point(spec, problem, run(problem, integ, t_end, **kwargs), kwargs)


def _run_arguments(spec: SweepSpec, problem) -> tuple[float, dict[str, Any]]:
    """The span and the arguments of :func:`nsbench.engine.run` of one value: the sections or stops of the
    sweep's section, the transient, the sweep's budgets."""
    from nsbench.sections import peaks

    t_end = spec.transient + spec.record_window
    kwargs: dict[str, Any] = {}
    if spec.section == "peaks":
        kwargs = dict(sections=[peaks(problem)], hit_from=spec.transient, hit_stop=spec.record)
    elif spec.section == "strobe":
        times = strobe_times(problem, spec.transient, spec.record)
        t_end = float(times[-1])
        kwargs = dict(t_eval=times)
    else:
        kwargs = dict(stop_kind=section_event_kind(spec.section), stop_count=spec.record)
    kwargs.update(record_from=spec.transient, max_steps=50_000_000, max_events=5_000_000)
    return t_end, kwargs


def points_columns(spec: SweepSpec, indices: Sequence[int], integ) -> list[Columns]:
    """:func:`point_columns` of several values with the set-up-able ``integ``, run together through
    :func:`nsbench.engine.run_batch` (heyoka's batch mode where it takes them; else one by one): the same
    rows, each value's ``wall_time`` its share of the batch's. A value whose problem cannot be built, or a
    batch that raises, is run alone (its error row is its own)."""
    from nsbench.engine import Each, run_batch

    tic = time.perf_counter()
    problems = []
    for i in indices:
        try:
            problems.append(spec.problem_at(float(spec.values[i])))
        except (NsbenchError, ArithmeticError, ValueError, RuntimeError):
            return [point_columns(spec, i, integ) for i in indices]
    if len(indices) < 2:
        return [point_columns(spec, i, integ, p) for i, p in zip(indices, problems)]
    args = [_run_arguments(spec, p) for p in problems]
    keys = sorted(set().union(*(a[1] for a in args)))
    per = {k: Each([a[1][k] for a in args]) for k in keys}
    try:
        integ.setup(problems[0])
        raws = run_batch(problems, integ, Each([a[0] for a in args]), **per)
        read = [_read_point(spec, p, raw, a[1]) for p, raw, a in zip(problems, raws, args)]
    except (NsbenchError, ArithmeticError, ValueError, RuntimeError):
        return [point_columns(spec, i, integ, p) for i, p in zip(indices, problems)]
    wall = (time.perf_counter() - tic) / len(indices)
    return [
        _columns(spec, p.state_names, i, float(spec.values[i]), t, y, blocks, status, message, counters, wall)
        for i, p, (t, y, blocks, status, message, counters) in zip(indices, problems, read)
    ]


def _read_point(spec: SweepSpec, problem, raw, kwargs: dict[str, Any]):
    """The recorded points, status and counters of one value's run ``raw`` (a :class:`~nsbench.engine.RunRecord`)."""
    events = raw.events
    kinds, blocks_ev = events.kind, events.block
    counters: dict[str, int] = {
        "n_events": raw.n_events_total,
        "nfev": raw.counters.nfev,
        "nsteps": raw.counters.nsteps,
    }
    for kind, name in EVENT_COUNTS:  # by the problem's own codes: none for a problem without such events
        code = problem.event_kinds.index(kind) if kind in problem.event_kinds else -1
        for b in range(1, len(problem.state_names) // 2 + 1):  # the table's counter columns (sweep_columns)
            counters[f"{name}{b}"] = int(np.count_nonzero((kinds == code) & (blocks_ev == b))) if code >= 0 else 0
    if not raw.status.ok:
        # a value whose run failed (a crossing stepped over, a storm, a budget) is a failure, not a result:
        # no point of it is recorded, whatever it found before it stopped
        message = f"stopped at t = {raw.t:.6g}" + (f": {raw.message}" if raw.message else "")
        return np.empty(0), np.empty((0, problem.n_states)), np.empty(0, np.int64), raw.status.value, message, counters
    if spec.section == "peaks":
        t, y, blocks = raw.hits.t, raw.hits.y, np.ones(len(raw.hits), np.int64)
    elif spec.section == "strobe":
        t, y = raw.dense.t, raw.dense.y
        blocks = np.zeros(len(raw.dense), np.int64)
    else:
        want = problem.event_kinds.index(kwargs["stop_kind"])
        pick = np.flatnonzero(kinds == want)[: spec.record]
        t, y, blocks = events.t[pick], events.y[pick], blocks_ev[pick]
    moved = sum(counters[f"{name}{b}"] for _, name in EVENT_COUNTS for b in range(1, len(problem.state_names) // 2 + 1))
    rest = len(t) < spec.record and moved == 0 and at_rest(problem, raw.mode, raw.t, raw.y)
    status, message = _finish(spec, len(t), raw.status.value, raw.t, rest)
    if status == Status.REST:
        return np.array([raw.t]), raw.y[None, :], np.zeros(1, np.int64), status, message, counters
    return np.asarray(t), np.asarray(y), np.asarray(blocks), status, message, counters
