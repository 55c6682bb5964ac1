"""Figures of a sweep: the bifurcation diagram, the locus of sticking phase, portraits and time series.

matplotlib is imported here on first use. Every figure is written as PNG
(compact, for reports), SVG and PDF unless fewer formats are asked for.
"""

from __future__ import annotations

from pathlib import Path
from typing import Sequence

import numpy as np
import pandas as pd

# the writing of figures is shared with continuation and simulate; the commands name these here too
from nsbench.plotting import FORMATS, pyplot, save
from nsbench.plotting import preload as preload

BLUE, RED = "tab:blue", "tab:red"


def diagram(
    frame: pd.DataFrame,
    base: str | Path,
    title: str = "",
    candidates: pd.DataFrame | None = None,
    formats: Sequence[str] = FORMATS,
    variables: Sequence[str] | None = None,
) -> list[Path]:
    """Bifurcation diagram: section-point coordinates against the swept parameter.

    ``variables`` default to the block positions ``x1 .. xn`` (one panel each; the first of each
    pair of state variables of other problems, every one if they do not come in pairs).

    Failed or incomplete values are marked along the bottom; candidate
    bifurcation points (if given) as faint vertical lines.
    """
    plt = pyplot()
    from nsbench.bifurcation.storage import positions_of, state_columns

    if variables is None:
        variables = positions_of(frame)
    variables = [v for v in variables if v in frame and frame[v].notna().any()] or state_columns(frame)[:1]
    fig, axes = plt.subplots(len(variables), 1, figsize=(7.0, 2.4 * len(variables) + 0.6), sharex=True, squeeze=False)
    name = frame["param"].iloc[0] if len(frame) else "parameter"
    from nsbench.bifurcation.sweep import OK_STATUSES

    good = frame["status"].isin(OK_STATUSES)
    ok = frame[good]
    bad = frame[~good].groupby("index").first()
    x = ok["value"].to_numpy(dtype=float)
    for ax, var in zip(axes[:, 0], variables):
        y = ok[var].to_numpy(dtype=float)
        if len(bad):
            lo = float(np.nanmin(y)) if np.isfinite(y).any() else 0.0
            ax.plot(bad["value"], np.full(len(bad), lo), "x", color=RED, ms=3, label="failed/incomplete")
            ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)  # beside the data
        if candidates is not None and len(candidates):  # one artist for all the lines: cheaper to draw
            ax.vlines(
                candidates["value"], 0, 1, transform=ax.get_xaxis_transform(), color="tab:orange", lw=0.5, alpha=0.5
            )
        ax.set_xlim(*_limits(np.r_[x, bad["value"].to_numpy(dtype=float)]))
        ax.set_ylim(*_limits(y))
        ax.set_ylabel(var)
    axes[-1, 0].set_xlabel(name)
    if title:
        fig.suptitle(title, fontsize=9)
    fig.tight_layout()
    for ax, var in zip(axes[:, 0], variables):  # the axes have their final size in pixels now
        _point_image(ax, x, ok[var].to_numpy(dtype=float))
    return save(fig, base, formats)


def _limits(values: np.ndarray) -> tuple[float, float]:
    """Axis limits around the finite ``values`` with matplotlib's default 5 % margins (a band of a
    tenth of the value around a single value)."""
    finite = values[np.isfinite(values)]
    if not finite.size:
        return 0.0, 1.0
    lo, hi = float(finite.min()), float(finite.max())
    span = hi - lo
    if not span > 1e-12 * max(1.0, abs(lo)):
        span = 0.1 * max(abs(lo), 1.0)
        lo, hi = lo - 0.5 * span, hi + 0.5 * span
    return lo - 0.05 * span, hi + 0.05 * span


def _point_image(ax, x: np.ndarray, y: np.ndarray) -> None:
    """The points as one image of the axes' own pixels: a pixel holding points is black (more opaque the
    more it holds). The points are binned once here, so every format embeds that image instead of
    drawing a hundred thousand markers again for each format (and twice for its tight box)."""
    box = ax.get_window_extent()
    width, height = max(1, int(round(box.width))), max(1, int(round(box.height)))
    (x0, x1), (y0, y1) = ax.get_xlim(), ax.get_ylim()
    keep = np.isfinite(x) & np.isfinite(y)
    counts, _, _ = np.histogram2d(y[keep], x[keep], bins=(height, width), range=((y0, y1), (x0, x1)))
    rgba = np.zeros((height, width, 4))
    rgba[..., 3] = 1.0 - 0.15**counts  # one point: 0.85 opaque; two or more: nearly black
    ax.imshow(
        rgba,
        extent=(x0, x1, y0, y1),
        origin="lower",
        aspect="auto",
        interpolation="nearest",
        zorder=1.5,
        rasterized=True,
    )


def locus(
    run, base: str | Path, title: str = "", formats: Sequence[str] = FORMATS, phase_time: float | None = None
) -> list[Path]:
    """Locus of sticking phase over sliding regions I, II, III for the run's pair of blocks
    (the first blue, the second red; default blocks 1 and 2).

    For forced problems region II is drawn at ``phase_time`` (default: the
    first forcing period boundary in the window, the stroboscopic phase).
    With more than two blocks, the regions are slices at the other blocks'
    positions at that time.
    """
    from nsbench.bifurcation.locus import region_masks

    plt = pyplot()
    problem = run.problem
    traj = run.trajectory
    a, b = run.pair
    x1, x2 = traj[f"x{a}"].to_numpy(), traj[f"x{b}"].to_numpy()
    pad1 = max(0.3, 0.25 * np.ptp(x1))
    pad2 = max(0.3, 0.25 * np.ptp(x2))
    g1 = np.linspace(x1.min() - pad1, x1.max() + pad1, 300)
    g2 = np.linspace(x2.min() - pad2, x2.max() + pad2, 300)
    m1, m2 = np.meshgrid(g1, g2)
    t = run.t_start
    if problem.is_forced and problem.forcing_frequency > 0:
        period = 2 * np.pi / problem.forcing_frequency
        t = phase_time if phase_time is not None else np.ceil(run.t_start / period) * period
    at = int(np.argmin(np.abs(traj["t"].to_numpy() - t)))  # the other blocks where the trajectory is then
    others = {k: float(traj[f"x{k}"].iloc[at]) for k in range(1, problem.n_blocks + 1) if k not in (a, b)}
    r1, r2 = region_masks(problem, t, m1, m2, (a, b), others)
    fig, ax = plt.subplots(figsize=(5.6, 4.8))
    ax.contourf(m1, m2, r1.astype(float), levels=[0.5, 1.5], colors=[BLUE], alpha=0.10)
    ax.contourf(m1, m2, r2.astype(float), levels=[0.5, 1.5], colors=[RED], alpha=0.10)
    ax.contour(m1, m2, r1.astype(float), levels=[0.5], colors=[BLUE], linewidths=0.6)
    ax.contour(m1, m2, r2.astype(float), levels=[0.5], colors=[RED], linewidths=0.6)
    ax.plot(x1, x2, color="0.75", lw=0.4, label="trajectory")
    # block 1 wider and underneath: where both stick (slope-1 lines) both colours show
    for block, colour, lw in ((a, BLUE, 3.2), (b, RED, 1.3)):
        for j, seg in enumerate(run.sticking_segments(block)):
            ax.plot(seg[:, 0], seg[:, 1], color=colour, lw=lw, label=f"block {block} sticks" if j == 0 else None)
    mp = run.mapping_points
    if len(mp):
        ax.plot(mp[f"x{a}"], mp[f"x{b}"], "o", ms=3, color="k", label="mapping points")
    ax.text(0.02, 0.97, "I: blue band, II: red band, III: overlap", transform=ax.transAxes, fontsize=7, va="top")
    ax.set_xlabel(f"x{a}")
    ax.set_ylabel(f"x{b}")
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)  # beside the phase plane
    if title:
        ax.set_title(title, fontsize=9)
    fig.tight_layout()
    return save(fig, base, formats)


def portrait(run, base: str | Path, title: str = "", formats: Sequence[str] = FORMATS) -> list[Path]:
    """Time series of the pair's positions and their phase portraits ``(x_i, v_i)`` over the recording window."""
    plt = pyplot()
    traj = run.trajectory
    blocks = run.pair if run.problem.n_blocks >= 2 else (1,)  # the locus's pair of a longer chain
    nb = len(blocks)
    fig, axes = plt.subplots(1, 1 + nb, figsize=(4.0 * (1 + nb), 3.2), gridspec_kw={"width_ratios": [1.6] + [1.0] * nb})
    ax = axes[0]
    for j, (i, colour) in enumerate(zip(blocks, (BLUE, RED)), start=1):
        ax.plot(traj["t"], traj[f"x{i}"], color=colour, lw=0.7, label=f"x{i}")
        ax_p = axes[j]
        ax_p.plot(traj[f"x{i}"], traj[f"v{i}"], color=colour, lw=0.6)
        ax_p.axhline(run.problem.v0, color="0.5", lw=0.5, ls="--")
        ax_p.set_xlabel(f"x{i}")
        ax_p.set_ylabel(f"v{i}")
    ax.set_xlabel("t")
    ax.legend(fontsize=7, loc="lower left", bbox_to_anchor=(0.0, 1.01), ncol=len(blocks), frameon=False)  # above
    if title:
        fig.suptitle(title, fontsize=9)
    fig.tight_layout()
    return save(fig, base, formats)
