"""Values given as text (the command line's, or a request's fields): parsed and checked once.

Every value a command line or an app's request is given is checked here before any work
starts: counts are whole numbers within a bound, reals finite and in range, and output paths
writable. Each check raises a :class:`~nsbench.errors.ConfigError` whose message names the option,
the bad value and what is allowed; ``nsbench.cli.main`` prints it as one line and exits with status 2.
"""

from __future__ import annotations

import errno
import math
import os
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

from nsbench.errors import ConfigError

if TYPE_CHECKING:  # pragma: no cover
    from nsbench.integrators.base import Integrator
    from nsbench.problems.base import HybridProblem


# Upper bounds of counts given on the command line: they keep a typo (1e12) from
# allocating terabytes or running for years. Raise them here if a run needs more.
#: Trajectory points of ``simulate --samples``.
MAX_SAMPLES = 10_000_000
#: Section points per value (``bifurcation --record``, ``paper --record``).
MAX_RECORD = 1_000_000
#: Worker processes (``--workers``).
MAX_WORKERS = 1024
#: Return-map iterations of ``lyapunov --iterations``.
MAX_ITERATIONS = 100_000_000
#: Ensemble members of ``lyapunov --members``.
MAX_MEMBERS = 100_000
#: Largest seed (numpy's seeds are 32-bit here).
MAX_SEED = 2**32 - 1
#: Longest time span (``--t-end``, ``--transient``, ``--window``), in the problem's time units: the
#: paper's problems have an event every 1 to 4 units, so a run this long meets the event budget
#: (10^6 events) long before its end; far beyond it time itself stops resolving events
#: (ulp(1e16) = 2). A typo (1e300) is refused here instead of running into a budget.
MAX_SPAN = 1e8
#: Longest per-task time limit in seconds (``--point-limit``, ``--member-limit``): about 30 years,
#: in effect no limit, and a value the operating system's timers can still hold.
MAX_TIME_LIMIT = 1e9
#: Smallest Lyapunov separation ``--d0``: the states are O(1) and rounded to about 1e-16 at every
#: step, so a separation below 1e-12 (four orders above that) measures the rounding, not the flow.
MIN_D0 = 1e-12


def parse_assignment(text: str, flag: str) -> tuple[str, str]:
    """Split ``NAME=VALUE``; raise a ``ConfigError`` naming ``flag`` otherwise."""
    name, sep, value = text.partition("=")
    if not sep or not name.strip() or not value.strip():
        raise ConfigError(f"{flag} expects NAME=VALUE, got {text!r}")
    return name.strip(), value.strip()


def parse_number(text: str, what: str) -> float:
    """A float (range checks are the consumer's), or a ``ConfigError`` naming ``what``."""
    try:
        return float(text)
    except ValueError:
        raise ConfigError(f"{what} = {text!r} is not a number") from None


def _shown(text: str) -> str:
    """``text`` as typed if it reads as a number, else quoted (so that '' and 'abc' show)."""
    try:
        float(text)
    except ValueError:
        return repr(text)
    return text.strip()


def parse_count(text: str, what: str, *, low: int = 1, high: int | None = None, bound: str | None = None) -> int:
    """A whole number in ``[low, high]``.

    Parameters
    ----------
    text
        The value as typed; ``1e3`` and ``1000.0`` are read as 1000.
    what
        The option, named in the message (e.g. ``--samples``).
    low, high
        Smallest and largest value allowed.
    bound
        Instead of ``high``: the name of one of this module's bounds (e.g.
        ``"MAX_SAMPLES"``), which the message names so that a user who needs
        more knows what to raise; with ``high``, the qualified name of the bound
        ``high`` is (``"nsbench.bifurcation.MAX_SWEEP_POINTS"``), named alike.

    Returns
    -------
    int
        The count.

    Raises
    ------
    ConfigError
        Not a number, ``nan``, ``inf``, not whole, or outside ``[low, high]``; the
        message names the option, the value and the range.
    """
    if high is None:
        if bound is None:
            raise TypeError("parse_count needs high or bound")
        high = int(globals()[bound])
    allowed = f"a whole number between {low} and {high}"
    shown = _shown(text)
    try:
        value = int(text.strip())
    except ValueError:
        try:
            real = float(text)
        except ValueError:
            raise ConfigError(f"{what} = {shown} is not a number; expected {allowed}") from None
        if not (math.isfinite(real) and real.is_integer()):
            raise ConfigError(f"{what} = {shown} must be {allowed}")
        value = int(real)
    if value < low:
        raise ConfigError(f"{what} = {shown} must be >= {low} ({allowed})")
    if value > high:
        where = f"; the bound is {bound if '.' in bound else f'{__name__}.{bound}'}" if bound else ""
        raise ConfigError(f"{what} = {shown} must be <= {high} ({allowed}{where})")
    return value


def parse_real(
    text: str,
    what: str,
    *,
    low: float | None = None,
    low_open: bool = False,
    high: float | None = None,
    high_open: bool = False,
    bound: str | None = None,
) -> float:
    """A finite number, optionally bounded below and above.

    Parameters
    ----------
    text
        The value as typed.
    what
        The option, named in the message (e.g. ``--transient``).
    low, high
        Bounds (``None``: unbounded on that side).
    low_open, high_open
        Whether the bound itself is excluded (``> low`` instead of ``>= low``).
    bound
        Instead of ``high``: the name of one of this module's bounds (e.g.
        ``"MAX_SPAN"``), which the message names.

    Returns
    -------
    float
        The value.

    Raises
    ------
    ConfigError
        Not a number, ``nan``, ``inf``, or out of range.
    """
    if bound is not None:
        high = float(globals()[bound])
    parts = []
    if low is not None:
        parts.append(f"{'>' if low_open else '>='} {low:g}")
    if high is not None:
        parts.append(f"{'<' if high_open else '<='} {high:g}")
    allowed = "a finite number" + (" " + " and ".join(parts) if parts else "")
    if bound is not None:
        allowed += f" (the bound is {__name__}.{bound})"
    shown = _shown(text)
    try:
        value = float(text)
    except ValueError:
        raise ConfigError(f"{what} = {shown} is not a number; expected {allowed}") from None
    ok = math.isfinite(value)
    if ok and low is not None:
        ok = value > low if low_open else value >= low
    if ok and high is not None:
        ok = value < high if high_open else value <= high
    if not ok:
        raise ConfigError(f"{what} = {shown} must be {allowed}")
    return value


def _first_existing(path: Path) -> Path:
    """``path`` or its nearest ancestor that exists (``.`` at worst)."""
    for candidate in (path, *path.parents):
        if os.path.lexists(candidate):
            return candidate
    return Path(".")


def _writable(folder: Path) -> bool:
    return os.access(folder, os.W_OK | os.X_OK)


def _refuse_dangling_link(target: Path, head: str) -> None:
    """A symbolic link that leads nowhere (broken, or a loop) looks missing but cannot be written."""
    for candidate in (target, *target.parents):
        if os.path.islink(candidate) and not os.path.exists(candidate):
            what = "a loop" if _is_loop(candidate) else "broken"
            raise ConfigError(f"{head}: {candidate} is a symbolic link that leads nowhere ({what})")


def _is_loop(link: Path) -> bool:
    try:
        os.stat(link)
    except OSError as exc:
        return exc.errno == errno.ELOOP
    return False


def check_fixed_step(
    integrator: "Integrator", problem: "HybridProblem", span: float, what: str, max_steps: int, given: bool = False
) -> None:
    """Refuse a fixed step that cannot run ``problem`` over ``span``.

    A fixed-step integrator takes ``span / h`` steps: beyond ``max_steps`` the run
    could only stop at its budget (and beyond about ``2**63`` the count is not even
    a machine integer), so ``--t-end 1e300`` or ``h = 1e-300`` is refused here,
    naming both, instead of running to a failure. A forced problem also needs two
    steps per forcing period at least (``w h < pi``): with fewer the steps alias
    the force (``h = 1e300``, or ``Omega = 1e300``) and the run "succeeds" with
    nothing to do with the problem. A step the user ``given`` must also be shorter
    than the run (a default step may exceed a short span: the run is then one step).
    """
    caps = type(integrator).capabilities
    name = caps.step_option
    if caps.adaptive or name is None:
        return
    step = integrator.settings.get(name)
    if step is None:
        return
    step = float(step)
    label = f"{type(integrator).name}'s {name} = {step:g}"
    if span > 0 and not span / step <= max_steps:
        raise ConfigError(
            f"{what} with {label} needs {span / step:.3g} steps, more than the step budget of "
            f"{max_steps}: raise {name} or shorten the span"
        )
    if given and span > 0 and step > span:
        raise ConfigError(f"{label} is longer than the whole run ({what}): give {name} < {span:g}")
    w = float(problem.forcing_frequency)
    if problem.is_forced and not w * step < math.pi:
        raise ConfigError(
            f"{label} takes fewer than two steps per forcing period (2 pi / w = {2 * math.pi / w:.3g}): "
            f"the force is not resolved; lower {name} below {math.pi / w:.3g}"
        )


def check_output_file(path: str, flag: str) -> Path:
    """Fail early unless ``path`` can be written as a file (its folder exists and is writable).

    Parameters
    ----------
    path
        The output file as given.
    flag
        The option, named in the message (e.g. ``--events-out``).

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    ConfigError
        ``path`` is a folder, its folder is missing, is a file, or is read-only, or
        ``path`` exists and is read-only.
    """
    target = Path(path)
    head = f"cannot write {flag} {path}"
    if not str(path).strip():
        raise ConfigError(f"{flag} expects a file name, got {path!r}")
    _refuse_dangling_link(target, head)
    if target.is_dir():
        raise ConfigError(f"{head}: it is a folder; give a file name")
    folder = target.parent
    if not folder.is_dir():
        found = _first_existing(folder)
        if found.exists() and not found.is_dir():
            raise ConfigError(f"{head}: {found} is a file, not a folder")
        raise ConfigError(f"{head}: folder {folder} does not exist")
    if target.exists() and not os.access(target, os.W_OK):
        raise ConfigError(f"{head}: the file is read-only")
    if not target.exists() and not _writable(folder):
        raise ConfigError(f"{head}: folder {folder} is read-only")
    return target


def check_output_dir(path: str | os.PathLike, flag: str) -> Path:
    """Fail early unless ``path`` is a writable folder or can be created (with its parents).

    Parameters
    ----------
    path
        The output folder as given.
    flag
        The option, named in the message (e.g. ``--out``).

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    ConfigError
        ``path`` or one of its ancestors is a file, or the folder (or the
        nearest existing ancestor it would be created in) is read-only.
    """
    target = Path(path)
    head = f"cannot write {flag} {path}"
    if not str(path).strip():
        raise ConfigError(f"{flag} expects a folder, got {str(path)!r}")
    _refuse_dangling_link(target, head)
    if target.exists():
        if not target.is_dir():
            raise ConfigError(f"{head}: it is a file, not a folder")
        if not _writable(target):
            raise ConfigError(f"{head}: the folder is read-only")
        return target
    found = _first_existing(target.parent)
    if not found.is_dir():
        raise ConfigError(f"{head}: {found} is a file, not a folder")
    if not _writable(found):
        raise ConfigError(f"{head}: cannot create it, folder {found} is read-only")
    return target


def parse_value(text: str) -> Any:
    """An option value: int, float, bool, None or string, in that order."""
    low = text.lower()
    if low in ("true", "false"):
        return low == "true"
    if low in ("none", "null"):
        return None
    for kind in (int, float):
        try:
            return kind(text)
        except ValueError:
            pass
    return text


def parse_options(texts: list[str], flag: str = "--option") -> dict[str, Any]:
    """``NAME=VALUE`` integrator options (:func:`parse_value`), each name once and every number finite.

    A non-finite number is refused here, as ``--h inf`` is: no option of a built-in
    integrator means anything by ``inf`` or ``nan`` (an unbounded ``max_step`` is
    its default, ``None``). Ranges are the integrator's to check.
    """
    options: dict[str, Any] = {}
    for text in texts:
        key, value = parse_assignment(text, flag)
        if key in options:
            raise ConfigError(f"{flag} {key} is given twice ({key}={options[key]!r} and {text!r}); give it once")
        parsed = parse_value(value)
        try:
            finite = not isinstance(parsed, (int, float)) or math.isfinite(float(parsed))
        except OverflowError:  # an integer beyond any float
            finite = False
        if not finite:
            raise ConfigError(f"{flag} {key}={value}: an option value must be a finite number")
        options[key] = parsed
    return options


def options_given(options: Any) -> dict[str, Any]:
    """Integrator options as given to a request: ``--option NAME=VALUE`` texts parsed
    (:func:`parse_options`), or a mapping kept as it is once every number in it is checked finite."""
    if not isinstance(options, Mapping):
        return parse_options(list(options))
    for key, value in options.items():
        try:
            finite = isinstance(value, bool) or not isinstance(value, (int, float)) or math.isfinite(float(value))
        except OverflowError:  # an integer beyond any float
            finite = False
        if not finite:
            raise ConfigError(f"--option {key}={value}: an option value must be a finite number")
    return dict(options)


#: Figure formats refused although matplotlib lists them: pgf needs a LaTeX
#: installation, raw and rgba are not image files.
_UNSAFE_FIGURE_FORMATS = {"pgf", "raw", "rgba"}


def figure_formats() -> tuple[str, ...]:
    """File extensions a figure can be saved as (those matplotlib writes, minus pgf, raw and rgba)."""
    from matplotlib.backend_bases import FigureCanvasBase

    return tuple(sorted(set(FigureCanvasBase.get_supported_filetypes()) - _UNSAFE_FIGURE_FORMATS))


def check_figure_path(path: str, flag: str) -> Path:
    """Fail early unless ``path`` ends in a figure format (png, pdf, svg, ...) and can be written.

    Raises
    ------
    ConfigError
        Unknown or missing extension (the message lists the allowed ones), or
        see :func:`check_output_file`.
    """
    check_output_file(path, flag)
    suffix = Path(path).suffix.lower().lstrip(".")
    allowed = figure_formats()
    if suffix not in allowed:
        what = f"extension .{suffix} is not a figure format" if suffix else "the file name has no extension"
        raise ConfigError(f"{flag} {path}: {what}; use one of {', '.join(allowed)}")
    return Path(path)
