"""Report figures (matplotlib, imported on first use), saved as PNG, SVG and PDF.

Per problem: work-precision diagrams (max switching-time error against warm wall
time, with min-max whiskers over the timed runs, against the integrator's own
time, and against ``nfev``), and the
switching-time error along the trajectory of
each integrator's tightest successful configuration. A problem without a
reference gets a cost-only figure instead.
"""

from __future__ import annotations

import math
import re
from contextlib import contextmanager
from contextvars import ContextVar
from dataclasses import dataclass
from pathlib import Path
from typing import Iterator, Sequence

import numpy as np
import pandas as pd

from nsbench.bench.labels import configuration
from nsbench.bench.tables import problem_groups
from nsbench.plotting import pyplot
from nsbench.status import ReferenceStatus, Status, TargetOutcome

#: Errors below this are drawn at it (log axes cannot show 0).
ERROR_FLOOR = 1e-16
_MARKERS = "osD^v<>pPX*hd"
_TIME_LABEL = "warm median wall time (whiskers: fastest to slowest timed run)"
#: Cost axes of the work-precision figures: (column, file tag, axis label, caption words).
COST_AXES = {
    "wall_time": ("time", "warm wall time (s)", _TIME_LABEL),
    "integrator_time": (
        "inttime",
        "integrator time (s)",
        "the time spent inside the integrator's own code (median over the timed runs; "
        "nsbench's event handling left out)",
    ),
    "nfev": (
        "nfev",
        "model evaluations (nfev)",
        "nfev (right-hand-side evaluations; for moreau-jean the one-step problems it solves; methods that "
        "count none, nfev 0, are not drawn)",
    ),
    "nsteps": (
        "nsteps",
        "steps or segments (nsteps)",
        "the integrator's steps (segments for the collocation methods, Taylor steps for heyoka)",
    ),
}


#: The formats a report's figures can be written in. PNG always: the HTML page embeds it.
REPORT_FORMATS = ("png", "svg", "pdf")
#: The formats of the figures saved now (:func:`saving_as`); PNG alone by default, since each further
#: format is a full draw of every figure (SVG for the web, PDF for LaTeX papers: ``--formats``).
_FORMATS: ContextVar[tuple[str, ...]] = ContextVar("nsbench_figure_formats", default=("png",))


def check_formats(formats: Sequence[str], what: str = "--formats") -> tuple[str, ...]:
    """``formats`` as a tuple of :data:`REPORT_FORMATS`, PNG first and always; anything else a ``ConfigError``."""
    from nsbench.errors import ConfigError

    bad = [f for f in formats if f not in REPORT_FORMATS]
    if bad or not formats:
        raise ConfigError(
            f"{what}: {', '.join(map(repr, bad)) or 'no format'} not allowed; choose from {', '.join(REPORT_FORMATS)} "
            "(comma-separated; png is always written)"
        )
    return ("png", *[f for f in REPORT_FORMATS[1:] if f in formats])


def parse_formats(text: str | Sequence[str], what: str = "--formats") -> tuple[str, ...]:
    """``"png, SVG"`` (the ``--formats`` text) or a sequence of names, as :func:`check_formats` keeps them."""
    names = text.split(",") if isinstance(text, str) else text
    return check_formats(tuple(f.strip().lower() for f in names if f.strip()), what)


@contextmanager
def saving_as(formats: Sequence[str]) -> Iterator[tuple[str, ...]]:
    """Save the figures made inside this block in ``formats`` (see :func:`check_formats`)."""
    token = _FORMATS.set(check_formats(formats))
    try:
        yield _FORMATS.get()
    finally:
        _FORMATS.reset(token)


@dataclass(frozen=True)
class Figure:
    """One saved figure: a stable ``name`` (file stem), title, caption and file paths."""

    name: str
    title: str
    caption: str
    png: Path
    #: The SVG file, when SVG was asked for (:func:`saving_as`), else ``None``.
    svg: Path | None = None
    #: Every file written, PNG first.
    files: tuple[Path, ...] = ()


def slug(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9.=-]+", "_", text).strip("_")


#: Method families and their colour maps: members of a family share a hue, told apart by shade and
#: marker. A family is what the integrator's capabilities say, never its name: reference-grade
#: integrators, else its event location (``Capabilities.event_location``), labelled here.
#: Each family's hue: matplotlib's qualitative ``tab10`` colours, made to be told apart (the sequential
#: maps used before gave collocation's Oranges and time-stepping's YlOrBr, ofapi and moreau-jean, one hue).
FAMILIES = (
    ("reference", "tab:gray"),
    ("dense output", "tab:blue"),
    ("solver root finding", "tab:green"),
    ("Taylor", "tab:red"),
    ("collocation", "tab:orange"),
    ("Henon", "tab:purple"),
    ("time-stepping", "tab:brown"),
    ("switch-model", "tab:pink"),
    ("smoothing", "tab:cyan"),
)
#: How far a family's lightest member is mixed towards white (its first member is the family's colour).
_LIGHTEST = 0.4
_EVENT_FAMILIES = {
    "dense-output-root": "dense output",
    "solver-rootfinding": "solver root finding",
    "taylor-root": "Taylor",
    "collocation-newton": "collocation",
    "henon": "Henon",
}
#: Colours of integrators in no family above (a plug-in's own event location, or one not registered
#: here): each its own, none of the families' hues.
_OTHER_COLOURS = (
    "tab:olive",
    "gold",
    "magenta",
    "black",
    "lime",
    "maroon",
    "darkkhaki",
    "slateblue",
    "navy",
    "darkseagreen",
)


def family(name: str) -> str:
    """The method family of an integrator, from its capabilities (``'other'`` if it is not registered here).

    ``'reference'`` for reference-grade integrators; a whole-system method's
    family (``'time-stepping'``, ``'switch-model'``, ``'smoothing'``); otherwise the event
    location of its capabilities (``'dense output'`` for ``dense-output-root``,
    ...), so a plug-in joins the family of the methods that locate events as it
    does, or forms its own.
    """
    from nsbench.integrators import integrator_class

    try:
        caps = integrator_class(name).capabilities
    except Exception:  # not registered here (results from elsewhere): a family of its own
        return "other"
    if caps.reference_grade:
        return "reference"
    if caps.family != "event-driven":  # the whole-system families (time-stepping, switch model, smoothing)
        return caps.family
    return _EVENT_FAMILIES.get(caps.event_location, caps.event_location)


def _styles(names: list[str]) -> dict[str, dict]:
    """Colour by family (its hue, a lighter shade per further member) and a distinct marker per member.

    An integrator outside the known families (a plug-in that locates events its
    own way, or one not registered here) gets a colour of its own, none of the
    families' hues, and a marker of its own.
    """
    from matplotlib.colors import to_rgb

    maps = dict(FAMILIES)
    members: dict[str, list[str]] = {}
    for n in sorted(names):
        members.setdefault(family(n), []).append(n)
    styles: dict[str, dict] = {}
    others = 0
    # each family's markers start at its own place in the list: two maps whose darkest shades coincide
    # (Greens and BuGn) still give their first members different markers
    start = {fam: k for k, (fam, _) in enumerate(FAMILIES)}
    for fam, group in members.items():
        for i, n in enumerate(group):
            if fam in maps:
                light = _LIGHTEST * i / max(len(group) - 1, 1)  # 0 for the first member
                base = np.array(to_rgb(maps[fam]))
                marker = _MARKERS[(i + start[fam]) % len(_MARKERS)]
                styles[n] = {"color": tuple(base + (1.0 - base) * light), "marker": marker}
            else:  # markers from the end of the list: unlike the families' first members
                styles[n] = {
                    "color": _OTHER_COLOURS[others % len(_OTHER_COLOURS)],
                    "marker": _MARKERS[-1 - others % len(_MARKERS)],
                }
                others += 1
    return styles


def _legend_outside(ax) -> None:
    """The legend right of the axes, never over the data."""
    if ax.lines:
        ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.02, 1.0), frameon=False)


def _methods(group: pd.DataFrame) -> tuple[pd.DataFrame, list[str]]:
    """Rows of the methods under test (references are what they are measured against), and the left-out names."""
    from nsbench.bench.summary import split_references

    methods, refs = split_references(group)
    return methods, sorted(refs["integrator"].unique())


_SUPERSCRIPT = str.maketrans("-0123456789", "\u207b\u2070\u00b9\u00b2\u00b3\u2074\u2075\u2076\u2077\u2078\u2079")


def plain_log_label(value: float, pos: int | None = None) -> str:
    """A log axis' tick label as plain text: ``10⁻⁶`` with Unicode superscripts, ``1``, ``10``, ``100``,
    ``1000`` as numbers, any other value as ``%g``. matplotlib's default labels are mathtext (``$10^{-6}$``),
    whose parsing took about a quarter of a report's time; these are drawn as they are."""
    if not (value > 0.0 and math.isfinite(value)):
        return ""
    exponent = math.log10(value)
    n = round(exponent)
    if abs(exponent - n) > 1e-9:
        return f"{value:g}"
    return f"{10**n:g}" if 0 <= n <= 3 else "10" + str(n).translate(_SUPERSCRIPT)


def _plain_minor_label(value: float, pos: int | None = None) -> str:
    """A minor tick's label on a log axis narrower than a decade: ``2×10⁻⁶`` (plain text, as above)."""
    if not (value > 0.0 and math.isfinite(value)):
        return ""
    mantissa, exponent = f"{value:.1e}".split("e")
    n = int(exponent)
    return f"{float(mantissa) * 10**n:g}" if 0 <= n <= 3 else f"{float(mantissa):g}×10" + str(n).translate(_SUPERSCRIPT)


#: A log axis spanning this many decades or more has no minor ticks (:func:`_plain_log_ticks`).
MINOR_TICK_DECADES = 3


def _plain_log_ticks(fig) -> None:
    """Every log axis of ``fig`` labelled in plain text (:func:`plain_log_label`); a base-2 axis (the chain's
    ``n``) by its numbers. Minor ticks are labelled only on an axis that spans less than a decade, where
    the major ticks may be too few to read it by, and drawn only on one that spans less than
    :data:`MINOR_TICK_DECADES` decades: on the error axes of 10 to 16 decades they were 8 a decade, each a
    matplotlib object made anew on every draw, 40 % of a report's drawing time (measured on the default
    report's 25 figures: 9.8 s with them, 6.0 s without), and too dense to read by."""
    from matplotlib.ticker import FuncFormatter, NullFormatter, NullLocator

    for ax in fig.axes:
        for axis in (ax.xaxis, ax.yaxis):
            if axis.get_scale() != "log":
                continue
            base = getattr(axis.get_transform(), "base", 10.0)
            major = plain_log_label if base == 10.0 else (lambda v, pos=None: f"{v:g}")
            axis.set_major_formatter(FuncFormatter(major))
            lo, hi = sorted(abs(v) for v in axis.get_view_interval())
            narrow = lo > 0.0 and hi / lo < base
            axis.set_minor_formatter(FuncFormatter(_plain_minor_label) if narrow else NullFormatter())
            if not (lo > 0.0 and hi / lo < base**MINOR_TICK_DECADES):
                axis.set_minor_locator(NullLocator())


def _save(fig, out: Path, name: str, title: str, caption: str, formats: Sequence[str] | None = None) -> Figure:
    """Write ``fig`` as ``out/name.<format>`` in ``formats`` (default: those of :func:`saving_as`)."""
    out.mkdir(parents=True, exist_ok=True)
    _plain_log_ticks(fig)
    wanted = _FORMATS.get() if formats is None else check_formats(formats)
    files = []
    for fmt in wanted:
        path = out / f"{name}.{fmt}"
        fig.savefig(path, bbox_inches="tight", **({"dpi": 110} if fmt == "png" else {}))
        files.append(path)
    for fmt in REPORT_FORMATS:  # a format not asked for this time: its file of an earlier report is out of date
        if fmt not in wanted:
            (out / f"{name}.{fmt}").unlink(missing_ok=True)
    pyplot().close(fig)
    svg = out / f"{name}.svg" if "svg" in wanted else None
    return Figure(name, title, caption, files[0], svg, tuple(files))


def _whiskers(ax, rows: pd.DataFrame, x: np.ndarray, y: np.ndarray, color) -> None:
    """Horizontal min-max whiskers around the median times ``x`` (where the range is known)."""
    low = rows["wall_time_min"].to_numpy(dtype=float)
    high = rows["wall_time_max"].to_numpy(dtype=float)
    known = np.isfinite(low) & np.isfinite(high)
    if known.any():
        xerr = np.vstack([np.maximum(x - low, 0.0), np.maximum(high - x, 0.0)])[:, known]
        ax.errorbar(x[known], y[known], xerr=xerr, fmt="none", ecolor=color, elinewidth=1.0, capsize=2.5, alpha=0.8)


def work_precision(group: pd.DataFrame, label: str, cost: str, styles: dict, out: Path) -> Figure:
    """Max switching-time error against ``cost`` (``'wall_time'`` or ``'nfev'``), one line per integrator.

    The line joins the successful runs with the reference's event sequence;
    a successful run with a wrong sequence is a hollow marker off the line, a
    run within the reference's certified error is drawn at that error with a
    downward triangle (an upper bound: its error is not measurable), and a run
    that did not succeed (time limit, failure) is not drawn: the error of its
    partial prefix is no point of the curve. References are left out.
    """
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(6.4, 4.6))
    methods, left_out = _methods(group)
    dropped = int((methods["status"] != Status.SUCCESS).sum())
    for name, rows in methods.groupby("integrator", sort=True):
        counted = pd.to_numeric(rows[cost], errors="coerce") > 0  # a 0 nfev is no count (siconos): no point at 0
        rows = rows[rows["switch_err_max"].notna() & counted & (rows["status"] == Status.SUCCESS)]
        rows = rows.sort_values("level")
        if rows.empty:
            continue
        x = rows[cost].astype(float).to_numpy()
        y = np.maximum(rows["switch_err_max"].to_numpy(dtype=float), ERROR_FLOOR)
        good = rows["sequence_ok"].fillna(False).to_numpy(dtype=bool)
        st = styles[name]
        if cost == "wall_time":
            _whiskers(ax, rows[good], x[good], y[good], st["color"])
        ax.plot(x[good], y[good], "-", marker=st["marker"], color=st["color"], lw=1.0, ms=6, label=name)
        bound = good & (
            rows["at_ref_accuracy"].fillna(False).to_numpy(dtype=bool)
            if "at_ref_accuracy" in rows
            else np.zeros(len(rows), bool)
        )
        if bound.any():
            ax.plot(x[bound], y[bound], "v", color=st["color"], ms=9, ls="none", mfc="white")
        if (~good).any():
            ax.plot(x[~good], y[~good], st["marker"], mfc="none", color=st["color"], ms=6, ls="none")
    ax.set_xscale("log")
    ax.set_yscale("log")
    kind, xlabel, words = COST_AXES[cost]
    ax.set_xlabel(xlabel)
    ax.set_ylabel("max switching-time error")
    ax.set_title(f"{label}: error vs {xlabel.split(' (')[0]}")
    ax.grid(True, which="major", alpha=0.3)
    _legend_outside(ax)
    caption = (
        f"Work-precision on {label}: max switching-time error over the matched prefix against "
        f"{words}; "
        f"one point per configuration, lines through the runs with the reference's event sequence. "
        f"Hollow markers: a wrong event sequence (never counted as reaching a target). White "
        f"triangles: within the reference's certified error, drawn at that error (an upper bound)."
    )
    if dropped:
        caption += f" {dropped} run(s) that did not succeed (time limit, failure) are not drawn."
    if left_out:
        caption += f" References not drawn: {', '.join(left_out)}."
    return _save(fig, out, f"wp_{kind}_{slug(label)}", f"{label}: error vs {xlabel.split(' (')[0]}", caption)


def event_error_along(group: pd.DataFrame, label: str, styles: dict, out: Path) -> Figure:
    """|t - t_ref| against t_ref for each integrator's tightest successful configuration.

    One panel per method family (small multiples sharing both axes), so that at
    most a family's few members share a panel instead of every integrator
    overlapping in one.
    """
    plt = pyplot()
    methods, _ = _methods(group)
    curves: dict[str, list] = {}
    band = (np.empty(0), np.empty(0))  # the reference's certified error along the longest matched prefix
    for name, rows in methods.groupby("integrator", sort=True):
        ok = rows[(rows["status"] == Status.SUCCESS) & rows["event_t"].map(len).gt(0)]
        if ok.empty:
            continue
        best = ok.sort_values("level").iloc[-1]
        cert = np.asarray(best["event_cert"] if "event_cert" in best else [], dtype=float)
        if cert.size > band[0].size:
            band = (np.asarray(best["event_t"], dtype=float)[: cert.size], np.maximum(cert, ERROR_FLOOR))
        t = np.asarray(best["event_t"], dtype=float)
        err = np.maximum(np.abs(np.asarray(best["event_err"], dtype=float)), ERROR_FLOOR)
        curves.setdefault(family(name), []).append((name, best.get("options"), t, err))
    order = [f for f, _ in FAMILIES if f in curves] + sorted(f for f in curves if f not in dict(FAMILIES))
    cols = min(3, max(len(order), 1))
    nrows = max(1, math.ceil(len(order) / cols))
    fig, axes = plt.subplots(nrows, cols, figsize=(4.2 * cols, 2.9 * nrows), sharex=True, sharey=True, squeeze=False)
    for ax in axes.flat[len(order) :]:
        ax.set_visible(False)
    for ax, fam in zip(axes.flat, order):
        if band[0].size:
            ax.fill_between(
                band[0], ERROR_FLOOR, band[1], color="0.85", step="mid", lw=0, label="reference's certified error"
            )
        for name, options, t, err in curves[fam]:
            st = styles[name]
            named = configuration(name, options)  # by its options, not by a level's index
            ax.plot(t, err, "-", color=st["color"], lw=0.8, marker=st["marker"], ms=2.5, label=named)
        ax.set_yscale("log")
        ax.set_title(fam, fontsize=9)
        ax.grid(True, alpha=0.3)
    # one legend for every panel, right of them: a legend inside a small panel covers its curves
    entries: dict[str, object] = {}
    for ax in axes.flat[: len(order)]:
        for handle, name in zip(*ax.get_legend_handles_labels()):
            entries.setdefault(name, handle)
    if entries:
        fig.legend(
            list(entries.values()),
            list(entries),
            loc="upper left",
            bbox_to_anchor=(1.0, 0.95),
            fontsize=7,
            frameon=False,
        )
    for ax in axes[-1]:
        ax.set_xlabel("reference switching time")
    for ax in axes[:, 0]:
        ax.set_ylabel("|switching-time error|")
    fig.suptitle(f"{label}: switching-time error along the trajectory")
    caption = (
        f"Switching-time error of every event of the matched prefix on {label}, for the tightest "
        f"successful configuration of each integrator, one panel per method family (the line stops "
        f"where its event sequence departs from the reference)."
    )
    if band[0].size:
        caption += (
            " Grey: the reference's certified error at each event; a difference inside it is not a measured error."
        )
    return _save(fig, out, f"event_err_{slug(label)}", f"{label}: error along the trajectory", caption)


def cost_only(group: pd.DataFrame, label: str, styles: dict, out: Path) -> Figure:
    """Wall time per configuration, for a problem that has no reference."""
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(6.4, 4.4))
    for name, rows in group.groupby("integrator", sort=True):
        rows = rows[rows["wall_time"].notna()].sort_values("level")
        if rows.empty:
            continue
        st = styles[name]
        # rows ingested from pytest-benchmark may have no accuracy level: plot them in order
        levels = (
            rows["level"].astype(float).to_numpy() if rows["level"].notna().all() else np.arange(len(rows), dtype=float)
        )
        times = rows["wall_time"].to_numpy(dtype=float)
        low, high = rows["wall_time_min"].to_numpy(dtype=float), rows["wall_time_max"].to_numpy(dtype=float)
        known = np.isfinite(low) & np.isfinite(high)
        if known.any():
            ax.errorbar(
                levels[known],
                times[known],
                yerr=np.vstack([times - low, high - times])[:, known],
                fmt="none",
                ecolor=st["color"],
                elinewidth=1.0,
                capsize=2.5,
                alpha=0.8,
            )
        ax.plot(levels, times, "-", marker=st["marker"], color=st["color"], label=name)
    ax.set_yscale("log")
    ax.set_xlabel("configuration (loose to tight)")
    ax.set_ylabel("warm wall time (s)")
    ax.set_title(f"{label}: cost only (no reference available)")
    ax.grid(True, alpha=0.3)
    _legend_outside(ax)
    reason = str(group["reference_status"].iloc[0])
    caption = (
        f"Cost of each configuration on {label} (median warm wall time; whiskers: fastest to "
        f"slowest timed run); accuracy is not measured: {reason}."
    )
    return _save(fig, out, f"cost_{slug(label)}", f"{label}: cost only", caption)


#: Cost axes of the runtime-distribution figure: (fixed-target column, axis label).
ECDF_COSTS = {
    "wall_time": "warm wall time to reach the target (s)",
    "nfev": "model evaluations to reach the target (nfev)",
}


def runtime_distribution(long: pd.DataFrame, styles: dict, out: Path) -> Figure | None:
    """COCO-style runtime distributions: per method, the fraction of (problem, target) pairs solved within a cost.

    ``long`` is the fixed-target table (:func:`nsbench.bench.tables.fixed_target`)
    of the methods under test. The pairs are every (problem, target) that has a
    reference and can be graded; a method solves a pair at the cost of its
    cheapest configuration reaching the target (the fixed-target rule), and
    does not solve it otherwise (not reached, refused, failed). One panel per
    cost (wall time, ``nfev``); each curve rises in steps to the share of pairs
    the method solves. ``None`` when no pair can be graded.
    """
    # a boolean mask even when empty (an empty object Series would select columns)
    graded = long[long["outcome"].map(lambda o: TargetOutcome(o).graded).astype(bool)]
    pairs = graded[["problem_label", "target"]].drop_duplicates()
    if pairs.empty:
        return None
    n_pairs = len(pairs)
    plt = pyplot()
    fig, axes = plt.subplots(1, len(ECDF_COSTS), figsize=(11.5, 4.4), sharey=True)
    for ax, (cost, label) in zip(axes, ECDF_COSTS.items()):
        for name, rows in graded.groupby("integrator", sort=True):
            hit = pd.to_numeric(rows.loc[rows["outcome"] == TargetOutcome.REACHED, cost], errors="coerce")
            x = np.sort(hit[hit > 0].to_numpy(dtype=float))
            if x.size == 0:
                continue
            y = np.arange(1, x.size + 1) / n_pairs
            st = styles[name]
            ax.step(
                np.concatenate([x[:1], x]),
                np.concatenate([[0.0], y]),
                where="post",
                color=st["color"],
                lw=1.3,
                label=name,
            )
            ax.plot(x[-1], y[-1], st["marker"], color=st["color"], ms=5)  # where the curve ends
        ax.set_xscale("log")
        ax.set_xlabel(label)
        ax.set_ylim(0.0, 1.02)
        ax.grid(True, which="major", alpha=0.3)
    axes[0].set_ylabel(f"fraction of the {n_pairs} (problem, target) pairs solved")
    handles, labels = axes[0].get_legend_handles_labels()
    if handles:
        fig.legend(handles, labels, loc="upper left", bbox_to_anchor=(1.0, 0.92), fontsize=7, frameon=False)
    fig.suptitle("Runtime distributions over every problem and target")
    fig.tight_layout()
    n_problems, n_targets = pairs["problem_label"].nunique(), pairs["target"].nunique()
    caption = (
        f"Runtime distributions (COCO style): for each method under test, the fraction of the {n_pairs} "
        f"(problem, target) pairs ({n_problems} problems, {n_targets} switching-time error targets, those "
        "that have a reference and can be graded) that it solves within a given cost, by warm wall time "
        "(left) and by nfev (right). A pair is solved at the cost of the method's cheapest configuration "
        "that reaches the target with the reference's event sequence (the fixed-target rule); a curve "
        "ends (marker) at the share of pairs the method solves at all. Higher and further left is better. "
        "nfev counts right-hand-side evaluations, and for moreau-jean the one-step problems it solves (a "
        "stick/slip status solved and tested, one per step where the status holds, more at a switch); "
        "methods that count none (nfev 0, siconos) have no curve on the right."
    )
    return _save(fig, out, "runtime_distribution", "Runtime distributions", caption)


#: A report with at least this many per-problem figures draws them in :data:`FIGURE_PROCESSES` processes
#: (:func:`start_report_figures`): below it, starting the processes (about a second each, importing
#: matplotlib and pandas) costs more than drawing in one.
PARALLEL_FIGURES = 12
#: Processes that draw a large report's figures (at most the machine's cores).
FIGURE_PROCESSES = 2


def _figure_jobs(frame: pd.DataFrame, out: Path) -> list[tuple]:
    """The per-problem figures of a report as ``(function name, args)``, in report order."""
    styles = _styles(sorted(frame["integrator"].unique()))
    jobs: list[tuple] = []
    for label, group in problem_groups(frame):
        wall = pd.to_numeric(group.get("wall_time"), errors="coerce")
        if not ((group["status"] == Status.SUCCESS) & wall.notna()).any():
            continue  # nothing of this problem was timed (a partial run): no figure of empty axes
        if (group["reference_status"] == ReferenceStatus.OK).any():
            for cost in COST_AXES:
                if (
                    cost not in ("integrator_time", "nsteps")
                    or pd.to_numeric(group.get(cost), errors="coerce").notna().any()
                ):
                    jobs.append(("work_precision", (group, label, cost, styles, out)))
            jobs.append(("event_error_along", (group, label, styles, out)))
        else:
            jobs.append(("cost_only", (group, label, styles, out)))
    return jobs


def _draw(job: tuple, formats: tuple[str, ...]) -> Figure:
    """Draw one figure job of :func:`_figure_jobs` in ``formats`` (in this process or a drawing one)."""
    name, args = job
    with saving_as(formats):
        return globals()[name](*args)


def _spawnable() -> bool:
    """Whether a ``spawn`` process can start here: it re-runs the main module, which must be a file (not a
    script read from standard input)."""
    import os
    import sys

    path = getattr(sys.modules.get("__main__"), "__file__", None)
    return path is None or os.path.isfile(path)


def start_report_figures(frame: pd.DataFrame, out: str | Path, processes: int | None = None):
    """Start drawing every per-problem figure of a report; returns the function that waits for them.

    With :data:`PARALLEL_FIGURES` figures or more and more than one core, the figures are drawn in a pool
    of ``processes`` (default :data:`FIGURE_PROCESSES`, at most the cores) started with ``spawn`` (a clean
    interpreter: nothing of this process's state, threads or compiled code is inherited), while this
    process goes on with the report's tables; matplotlib draws one figure at a time per process, and the
    figures are 60 % of a report's time (measured: 25 figures of the default report, 9.7 s of 15.6). The
    returned function gives the figures in report order; if the pool fails it draws what is missing here.
    """
    import os

    out = Path(out)
    jobs = _figure_jobs(frame, out)
    formats = _FORMATS.get()
    n = min(FIGURE_PROCESSES if processes is None else int(processes), os.cpu_count() or 1)
    if n < 1 or len(jobs) < PARALLEL_FIGURES or not _spawnable():
        figures = [_draw(job, formats) for job in jobs]
        return lambda: figures
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    pool = ProcessPoolExecutor(max_workers=n, mp_context=multiprocessing.get_context("spawn"))
    futures = [pool.submit(_draw, job, formats) for job in jobs]

    def collect() -> list[Figure]:
        figures = []
        try:
            for job, future in zip(jobs, futures):
                try:
                    figures.append(future.result())
                except Exception:  # noqa: BLE001 - a pool that broke (a process killed): this figure drawn here
                    figures.append(_draw(job, formats))
        finally:
            pool.shutdown(wait=True, cancel_futures=True)
        return figures

    return collect


def report_figures(frame: pd.DataFrame, out: str | Path, processes: int | None = None) -> list[Figure]:
    """Every per-problem figure of a report, in report order, saved under ``out`` (:func:`start_report_figures`)."""
    return start_report_figures(frame, out, processes)()


def scaling_report_figures(
    frame: pd.DataFrame, table: pd.DataFrame, summary: pd.DataFrame, out: str | Path
) -> list[Figure]:
    """The scaling figures of every family of the report (none when no family varies ``n``)."""
    styles = _styles(sorted(frame["integrator"].unique()))
    figures: list[Figure] = []
    for family in sorted(table["family"].unique()):
        figures += scaling_figures(table, summary, family, styles, Path(out))
    return figures


def scaling_figures(table: pd.DataFrame, summary: pd.DataFrame, family: str, styles: dict, out: Path) -> list[Figure]:
    """The scaling study of one family: cost to reach the target against ``n``, events and set-up against ``n``.

    ``table`` and ``summary`` are :func:`nsbench.bench.scaling.scaling_table` and
    :func:`~nsbench.bench.scaling.scaling_summary`.
    """
    from nsbench.bench.scaling import COSTS, SCALING_TARGET

    plt = pyplot()
    rows = table[table["family"] == family]
    fits = summary[summary["family"] == family].set_index("integrator")
    fig, axes = plt.subplots(1, len(COSTS), figsize=(15, 4.8))
    for ax, (cost, label) in zip(axes, COSTS.items()):
        for name, group in rows[rows["reached"]].groupby("integrator", sort=True):
            group = group.sort_values("n")
            y = group[cost].to_numpy(dtype=float)
            if not np.isfinite(y).any() or not (y > 0).any():
                continue
            b = fits.loc[name, f"exponent_{cost}"] if name in fits.index else math.nan
            tag = f"{name} (b = {b:.2f})" if np.isfinite(b) else name
            ax.plot(group["n"].to_numpy(dtype=float), y, label=tag, linewidth=1.2, markersize=4, **styles.get(name, {}))
        ax.set_xscale("log", base=2)
        ax.set_yscale("log")
        ax.set_xlabel("number of blocks n")
        ax.set_ylabel(label)
        ax.grid(True, which="both", alpha=0.3)
    handles, labels = axes[0].get_legend_handles_labels()
    if handles:
        fig.legend(handles, labels, loc="upper center", bbox_to_anchor=(0.5, -0.02), ncol=4, fontsize=8, frameon=False)
    fig.suptitle(f"{family}: cost to reach a switching-time error of {SCALING_TARGET:g}")
    caption = (
        f"Cost of the cheapest configuration of each integrator that reaches a switching-time error of "
        f"{SCALING_TARGET:g} on {family}, against the number of blocks n (log-log); b in the legend is "
        "the fitted growth exponent of cost ~ n^b (per panel in the scaling table). An integrator's line "
        "ends where it stops reaching the target."
    )
    figs = [_save(fig, out, f"scaling_cost_{slug(family)}", f"{family}: cost against n", caption)]

    fig, (ax_e, ax_s) = plt.subplots(1, 2, figsize=(11, 4.5))
    ref = rows.dropna(subset=["events_per_time"]).groupby("n")["events_per_time"].first()
    ax_e.plot(ref.index.to_numpy(dtype=float), ref.to_numpy(dtype=float), "ko-")
    ax_e.set_xscale("log", base=2)
    ax_e.set_xlabel("number of blocks n")
    ax_e.set_ylabel("events per unit time (reference)")
    ax_e.grid(True, which="both", alpha=0.3)
    for name, group in rows.groupby("integrator", sort=True):
        group = group.sort_values("n")
        y = group["setup_time"].to_numpy(dtype=float)
        if np.isfinite(y).any() and (y > 0).any():
            ax_s.plot(
                group["n"].to_numpy(dtype=float), y, label=name, linewidth=1.2, markersize=4, **styles.get(name, {})
            )
    ax_s.set_xscale("log", base=2)
    ax_s.set_yscale("log")
    ax_s.set_xlabel("number of blocks n")
    ax_s.set_ylabel("setup time (s): compilation, tables")
    ax_s.grid(True, which="both", alpha=0.3)
    if ax_s.lines:
        ax_s.legend(fontsize=7, ncol=2, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    caption = (
        f"{family}: events per unit time of the reference against n, and each integrator's set-up time "
        "(compilation and tables, kept out of the timed runs; the largest over its configurations, the "
        "first of which compiles) against n. heyoka keeps compiled code in an on-disk cache "
        "(~/.cache/heyoka), so a second run on one machine shows loading, not compiling."
    )
    figs.append(
        _save(fig, out, f"scaling_events_setup_{slug(family)}", f"{family}: events and set-up against n", caption)
    )
    return figs
