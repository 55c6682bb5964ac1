"""What a sweep or a continuation asks for: a :class:`SweepRequest` (``nsbench bifurcation``) or a
:class:`ContinuationRequest` (``nsbench continuation``), every value parsed and checked once.

A request is built once, by the command line (:mod:`nsbench.cli.bifurcation`,
:mod:`nsbench.cli.continuation`, which map their arguments onto the fields) or from Python, and
checked at its construction: a bad value is a :class:`~nsbench.errors.ConfigError` naming the
option, the value and what is allowed, before any worker starts, problem is built or value
computed. :func:`nsbench.bifurcation.sweep_command.run_sweeps` and
:func:`nsbench.bifurcation.continuation_command.run_continuation` run them. Nothing heavy is
imported here: the sweep's worker processes start right after, and the command line reads the
defaults when it builds its parser.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

from nsbench.errors import ConfigError
from nsbench.inputs import MIN_D0, check_output_file, options_given, parse_count, parse_number, parse_real
from nsbench.plotting import FORMATS

#: Default hard limit of the whole continuation in its worker, in seconds (``--time-limit``).
TIME_LIMIT = 3600.0
#: Most continuation steps over the range (``--steps``).
MAX_STEPS = 100_000


def parse_sweep(text: str) -> tuple[str, float, float, int]:
    """``NAME=START:STOP:COUNT`` as ``(name, start, stop, count)``.

    START and STOP must be finite, different numbers, COUNT a whole number from 1 to
    1 000 000 (``1e3`` reads as 1000); anything else is a ``ConfigError``
    naming the bad part and what is allowed.
    """
    from nsbench.bifurcation import MAX_SWEEP_POINTS as max_count

    name, sep, rng = text.partition("=")
    parts = [p.strip() for p in rng.split(":")]
    if not sep or not name.strip() or len(parts) != 3:
        raise ConfigError(f"--sweep expects NAME=START:STOP:COUNT, got {text!r}")
    try:
        start, stop = float(parts[0]), float(parts[1])
    except ValueError:
        raise ConfigError(f"--sweep {text!r}: START and STOP must be numbers") from None
    if not (math.isfinite(start) and math.isfinite(stop)):
        raise ConfigError(f"--sweep {text!r}: START and STOP must be finite")
    if start == stop:
        raise ConfigError(
            f"--sweep {text!r}: START and STOP are equal; a sweep needs a range of values "
            "(for one value, use nsbench simulate)"
        )
    allowed = f"a whole number between 1 and {max_count}"
    try:
        count = float(parts[2])
    except ValueError:
        raise ConfigError(f"--sweep {text!r}: COUNT = {parts[2]!r} is not a number; expected {allowed}") from None
    if not (math.isfinite(count) and count.is_integer() and 1 <= count <= max_count):
        raise ConfigError(f"--sweep {text!r}: COUNT = {parts[2]} must be {allowed} (split a longer sweep into several)")
    return name.strip(), start, stop, int(count)


@dataclass(frozen=True)
class SweepRequest:
    """One bifurcation sweep as asked: one parameter swept, for one or several integrators.

    Each value may be given as the command line's text (``record="100"``, ``sweep="v0=0.1:0.2:6"``,
    ``options=["tol=1e-10"]``, ``formats="png,svg"``) or as a Python value (``record=100``,
    ``options={"tol": 1e-10}``, ``formats=("png",)``); the construction parses and checks each
    once, in the order of the command's checks, and keeps the parsed value. A message names the
    command's option (``--record = 0 must be >= 1 ...``). What needs the problem (the integrators'
    options and fixed steps, ``pair``, ``portraits``, ``section``, ``out``) is checked by
    :func:`nsbench.bifurcation.sweep_command.run_sweeps` before the first value is computed.

    Attributes
    ----------
    problem, case, params
        Registered problem, its preset, and fixed parameter overrides (``--param``, ``--n``).
    sweep
        ``(name, start, stop, count)``: the swept parameter and its grid (given as ``NAME=START:STOP:COUNT``).
    integrators
        Registered integrators, one sweep each (a comparison when several); ``(None,)``: the
        problem's default (``exact`` for a linear problem, ``henon-rk4`` otherwise).
    options, h
        Integrator options (each applied to the integrators that have it); ``h``, the step of
        fixed-step integrators, is folded into ``options`` (``h`` is then ``None``).
    section, transient, record, window
        Recorded points (default: ``strobe`` if forced, else ``peaks``), time integrated before
        recording, points per value, longest recording time (default ``40 * record + 400``).
    workers, dask
        Local processes (default: all cores), or the address of a Dask scheduler.
    out, fresh
        Results folder (default ``bifurcation/<problem>[-n<N>][-case<C>]-<NAME>``); discard what is stored there.
    refine, portraits, pair
        Refine candidate bifurcation points by bisection; values to draw the locus of sticking
        phase and phase portraits at; the two blocks they show (``None``: blocks 1 and 2).
    formats, point_limit, setup_limit, progress
        Figure formats; hard limits (seconds) of one value and of an integrator's set-up; a progress bar.
    """

    problem: str
    sweep: tuple[str, float, float, int]
    case: int = 1
    params: dict[str, Any] = field(default_factory=dict)
    integrators: tuple[str | None, ...] = ()
    options: dict[str, Any] = field(default_factory=dict)
    h: float | None = None
    section: str | None = None
    transient: float = 1500.0
    record: int = 100
    window: float | None = None
    workers: int | None = None
    dask: str | None = None
    out: str | None = None
    fresh: bool = False
    refine: bool = False
    portraits: tuple[float, ...] = ()
    pair: tuple[int, int] | None = None
    formats: tuple[str, ...] = FORMATS
    point_limit: float = 600.0
    setup_limit: float = 1800.0
    progress: bool = True
    #: ``pair`` as given (the messages about it quote it so).
    pair_text: str | None = field(default=None, init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        keep = _keeper(self)
        if self.workers is not None:  # the command's first check
            keep("workers", parse_count(str(self.workers), "--workers", low=1, bound="MAX_WORKERS"))
        keep("sweep", parse_sweep(_sweep_text(self.sweep)))
        check_swept_name(self.sweep[0])
        keep("case", _case(self.case))
        keep("record", parse_count(str(self.record), "--record", low=1, bound="MAX_RECORD"))
        keep("transient", parse_real(str(self.transient), "--transient", low=0.0, bound="MAX_SPAN"))
        if self.window is not None:
            keep("window", parse_real(str(self.window), "--window", low=0.0, low_open=True, bound="MAX_SPAN"))
        keep("options", options_given(self.options))
        if self.h is not None:
            h = parse_real(str(self.h), "--h", low=0.0, low_open=True)
            if "h" in self.options:
                raise ConfigError("--h and --option h=... are both given; give it once")
            keep("options", {**self.options, "h": h})
            keep("h", None)
        limits = ("point_limit", "--point-limit"), ("setup_limit", "--setup-limit")
        for name, flag in limits:
            keep(name, parse_real(str(getattr(self, name)), flag, low=0.0, low_open=True, bound="MAX_TIME_LIMIT"))
        keep("portraits", tuple(parse_real(str(value), "--portrait") for value in self.portraits))
        if self.pair is not None:
            text = self.pair if isinstance(self.pair, str) else ",".join(str(b) for b in self.pair)
            keep("pair_text", text)
            keep("pair", parse_pair(text))
        names = list(self.integrators)
        twice = sorted({n for n in names if names.count(n) > 1 and n is not None})
        if twice:  # the same sweep twice, and a comparison of a method with itself
            raise ConfigError(f"--integrator {twice[0]} is given twice; give each integrator once")
        keep("formats", _formats(self.formats))
        keep("params", dict(self.params))
        keep("integrators", tuple(names) or (None,))


def _keeper(request: Any):
    """A setter of a frozen request's fields, for its ``__post_init__`` (which keeps each parsed value)."""

    def keep(name: str, value: Any) -> None:
        object.__setattr__(request, name, value)

    return keep


def _sweep_text(sweep: Any) -> str:
    """``sweep`` as ``NAME=START:STOP:COUNT`` (a parsed tuple written back, so that it is checked alike)."""
    if isinstance(sweep, str):
        return sweep
    name, start, stop, count = sweep
    return f"{name}={start!r}:{stop!r}:{count}"


def _range_text(sweep: Any) -> str:
    """``sweep`` as ``NAME=START:STOP`` (a parsed tuple written back, so that it is checked alike)."""
    if isinstance(sweep, str):
        return sweep
    name, start, stop = sweep
    return f"{name}={start!r}:{stop!r}"


def _case(case: Any) -> int:
    text = str(case)
    try:
        whole = float(text).is_integer()
    except ValueError:
        whole = False
    if not whole:
        raise ConfigError(f"--case = {text!r} must be a case number such as 1, 2, 3 or 4")
    return int(parse_number(text, "--case"))


def _formats(formats: Any, *, empty: bool = True) -> tuple[str, ...]:
    """``--formats`` as text (``"png, svg"``) or as names, each one of the figure formats; none at all
    only where ``empty`` allows it."""
    given = formats.split(",") if isinstance(formats, str) else formats
    chosen = tuple(f.strip() for f in given if f.strip())
    bad = [f for f in chosen if f not in FORMATS]
    if bad or not (chosen or empty):
        what = f"{', '.join(bad)} not allowed" if bad else "none given"
        raise ConfigError(f"--formats: {what}; choose from {', '.join(FORMATS)}")
    return chosen


def check_swept_name(name: str) -> None:
    """Refuse a swept name that is not a parameter of the problem's state-preserving kind."""
    if name == "n":
        raise ConfigError("the number of blocks n cannot be swept (it changes the state); give --n")
    if name in ("case", "dimensional"):  # get_problem's own arguments, not parameters
        raise ConfigError(
            f"--sweep {name}=...: {name} is not a parameter and cannot be swept; give --case for the preset "
            "and sweep one of its parameters (v0, F, Omega, ...)"
        )


def parse_pair(text: str) -> tuple[int, int]:
    """``A,B``: two different block numbers (the locus of sticking phase shows their positions)."""
    parts = [t.strip() for t in text.split(",")]
    if len(parts) != 2 or not all(p.isdigit() for p in parts):
        raise ConfigError(f"--pair expects two block numbers A,B (e.g. 1,2), got {text!r}")
    if parts[0] == parts[1] or int(parts[0]) == int(parts[1]):
        raise ConfigError(f"--pair {text}: the locus needs two different blocks A,B (e.g. 1,2)")
    return int(parts[0]), int(parts[1])


def parse_range(text: str) -> tuple[str, float, float]:
    """``NAME=START:STOP`` as ``(name, start, stop)`` with two different finite numbers."""
    name, sep, rng = text.partition("=")
    parts = [p.strip() for p in rng.split(":")]
    if not sep or not name.strip() or len(parts) != 2:
        raise ConfigError(f"--sweep expects NAME=START:STOP, got {text!r}")
    start = parse_number(parts[0], f"--sweep {text!r}: START")
    stop = parse_number(parts[1], f"--sweep {text!r}: STOP")
    if not (math.isfinite(start) and math.isfinite(stop)) or start == stop:
        raise ConfigError(f"--sweep {text!r}: START and STOP must be two different finite numbers")
    return name.strip(), start, stop


@dataclass(frozen=True)
class ContinuationRequest:
    """Periodic orbits followed in one parameter over a range, and their bifurcations located.

    Each value may be given as the command line's text (``steps="200"``, ``sweep="v0=0.2:0.28"``,
    ``formats="png,svg"``) or as a Python value (``steps=200``, ``formats=("png",)``); the
    construction parses and checks each once, in the order of the command's checks, and keeps the
    parsed value. A message names the command's option. What needs the problem (``section``,
    ``diagram``, ``out``, the integrator) is checked by
    :func:`nsbench.bifurcation.continuation_command.run_continuation` before the flow runs.

    Attributes
    ----------
    problem, case, params
        Registered problem, its preset (a number, or a name such as relay-feedback's), fixed
        parameter overrides (``--param``, ``--n``).
    sweep
        ``(name, start, stop)``: the continued parameter and its range (given as ``NAME=START:STOP``).
    steps
        Continuation steps over the range at the largest step size (halved where needed).
    section, integrator, transient, origin
        Section points drawn and stored (default: by the problem, :func:`nsbench.bifurcation.sweep.orbit_section`);
        the flow's integrator (default: ``exact`` for a linear problem, ``heyoka`` otherwise);
        time integrated from rest before the first orbit is sought; a value to find the first
        orbit at, and continue it from to ``start``.
    doubling
        Follow period-doubled branches.
    diagram, out, formats
        A sweep folder (``nsbench bifurcation``) drawn beneath the branches; the results folder
        (default ``continuation/<problem>-case<C>-<NAME>``); the figure's formats.
    time_limit, setup_limit, progress
        Hard limits (seconds) of the whole continuation and of the flow's set-up; a progress bar.
    """

    problem: str
    sweep: tuple[str, float, float]
    case: int | str = 1
    params: dict[str, Any] = field(default_factory=dict)
    steps: int = 200
    section: str | None = None
    integrator: str | None = None
    transient: float = 1500.0
    origin: float | None = None
    doubling: bool = True
    diagram: str | None = None
    out: str | None = None
    formats: tuple[str, ...] = FORMATS
    time_limit: float = TIME_LIMIT
    setup_limit: float = 1800.0
    progress: bool = True

    def __post_init__(self) -> None:
        keep = _keeper(self)
        keep("sweep", parse_range(_range_text(self.sweep)))
        for name, flag in (("time_limit", "--time-limit"), ("setup_limit", "--setup-limit")):
            keep(name, parse_real(str(getattr(self, name)), flag, low=0.0, low_open=True, bound="MAX_TIME_LIMIT"))
        keep("steps", parse_count(str(self.steps), "--steps", low=1, high=MAX_STEPS))
        keep("transient", parse_real(str(self.transient), "--transient", low=0.0, bound="MAX_SPAN"))
        keep("case", _case_or_name(self.case))
        if self.origin is not None:
            keep("origin", parse_real(str(self.origin), "--origin"))
        name = self.sweep[0]
        if name in self.params:
            raise ConfigError(f"parameter {name} is both continued (--sweep) and fixed (--param)")
        if name == "n":
            raise ConfigError("the number of blocks n cannot be continued (it changes the state)")
        keep("params", dict(self.params))
        keep("formats", _formats(self.formats, empty=False))  # the branches' figure is what it is run for


def _case_or_name(case: Any) -> int | str:
    """A case number, or a name (relay-feedback's published cases), which the problem checks."""
    text = str(case).strip()
    if text[:1].isalpha():
        return text
    try:
        number = parse_number(str(case), "--case")
        if not float(number).is_integer():
            raise ValueError(number)
        return int(number)
    except (ValueError, OverflowError):
        raise ConfigError(f"--case = {case!r} must be a case number such as 1, 2, 3 or 4, or a case name") from None


@dataclass(frozen=True)
class LyapunovRequest:
    """The largest Lyapunov exponent of a problem's mapping points (``nsbench lyapunov``), as asked.

    Each value may be given as the command line's text (``members="32"``, ``h="0.01"``) or as a
    Python value; the construction parses and checks each once, in the order of the command's
    checks, and keeps the parsed value. A message names the command's option. What needs the
    problem (the integrator and its fixed step against the transient) is checked by
    :func:`nsbench.bifurcation.lyapunov_command.run_lyapunov` before any member runs.

    Attributes
    ----------
    problem, case, params, dimensional
        Registered problem, its preset (``None``: the problem's default), parameter overrides
        (``--param``, ``--n``), dimensional units.
    integrator, h
        Registered integrator (``None``: ``exact`` for a linear problem, ``henon-rk4``
        otherwise); the step of a fixed-step integrator.
    transient, iterations, members, d0, seed
        Time each member runs before its first mapping point used; return-map iterations in all,
        split over the members; independent estimates (at least 4); the renormalised
        separation; the seed of the start perturbations.
    workers, member_limit, setup_limit
        Processes running members at once; hard limits (seconds) of one member's run and of a
        plug-in problem's factory.
    out
        A CSV of ``log(d/d0)`` per member and iteration (and ``OUT.worker-errors.log``).
    """

    problem: str
    case: int | str | None = None
    params: dict[str, Any] = field(default_factory=dict)
    dimensional: bool = False
    integrator: str | None = None
    h: float | None = None
    transient: float = 1000.0
    iterations: int = 10000
    members: int = 32
    d0: float = 1e-8
    seed: int = 0
    workers: int = 1
    member_limit: float = 1800.0
    setup_limit: float = 1800.0
    out: str | None = None

    def __post_init__(self) -> None:
        keep = _keeper(self)
        keep("transient", parse_real(str(self.transient), "--transient", low=0.0, bound="MAX_SPAN"))  # inf never ends
        keep("members", parse_count(str(self.members), "--members", low=4, bound="MAX_MEMBERS"))
        keep("iterations", parse_count(str(self.iterations), "--iterations", low=1, bound="MAX_ITERATIONS"))
        keep("d0", parse_real(str(self.d0), "--d0", low=MIN_D0, high=0.01, high_open=True))
        keep("seed", parse_count(str(self.seed), "--seed", low=0, bound="MAX_SEED"))
        keep("workers", parse_count(str(self.workers), "--workers", low=1, bound="MAX_WORKERS"))
        if self.h is not None:
            keep("h", parse_real(str(self.h), "--h", low=0.0, low_open=True))
        for name, flag in (("member_limit", "--member-limit"), ("setup_limit", "--setup-limit")):
            keep(name, parse_real(str(getattr(self, name)), flag, low=0.0, low_open=True, bound="MAX_TIME_LIMIT"))
        if self.out:
            check_output_file(self.out, "--out")
        keep("params", dict(self.params))

    @property
    def problem_arguments(self) -> dict[str, Any]:
        """The ``get_problem`` keyword arguments: the preset, the units and the overrides."""
        return {"case": self.case, "dimensional": self.dimensional, **self.params}

    @property
    def options(self) -> dict[str, Any]:
        """The integrator's options: the step, if given."""
        return {"h": self.h} if self.h is not None else {}
