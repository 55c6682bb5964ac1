"""Figures of single runs (matplotlib is imported here, on first use, never by ``import nsbench``)."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, cast

if TYPE_CHECKING:  # pragma: no cover
    from nsbench.problems.oscillator import FrictionOscillator
    from nsbench.results import SimulationResult

BLOCK_COLOURS = ("tab:blue", "tab:red")


def _pyplot():
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    return plt


def plot_simulation(result: "SimulationResult", path: str | Path):
    """Time series of every state and the phase plane of each block, events marked.

    Returns the matplotlib figure (also saved to ``path``).
    """
    plt = _pyplot()
    traj, events = result.trajectory, result.events
    problem = cast("FrictionOscillator", result.problem)  # the blocks' time series and phase planes
    nb = problem.n_blocks
    fig, axes = plt.subplots(
        2, nb + 1, figsize=(4.2 * (nb + 1), 6.5), squeeze=False, gridspec_kw={"width_ratios": [2.0] + [1.0] * nb}
    )
    units = "dimensional" if problem.dimensional else "dimensionless"
    for row, q in enumerate(("x", "v")):
        ax = axes[row, 0]
        for i in range(1, nb + 1):
            col = f"{q}{i}"
            ax.plot(traj["t"], traj[col], color=BLOCK_COLOURS[i - 1], lw=0.9, label=col)
            ev = events[events["block"] == i]
            stick = ev[ev["kind"] == "stick"]
            ax.plot(stick["t"], stick[col], "o", ms=2.5, color=BLOCK_COLOURS[i - 1], alpha=0.7)
        ax.set_ylabel(q + " (" + units + ")")
        ax.legend(loc="lower left", bbox_to_anchor=(0.0, 1.0), ncol=nb, fontsize=8, frameon=False)  # above the data
    axes[1, 0].set_xlabel("t")
    for i in range(1, nb + 1):
        ax = axes[0, i]
        ax.plot(traj[f"x{i}"], traj[f"v{i}"], color=BLOCK_COLOURS[i - 1], lw=0.7)
        ax.axhline(problem.v0, color="grey", lw=0.6, ls="--")
        ax.set_xlabel(f"x{i}")
        ax.set_ylabel(f"v{i}")
        ax.set_title(f"phase plane, block {i}", fontsize=9)
        ax = axes[1, i]
        for kind, marker in (("stick", "o"), ("slip", "^"), ("reverse", "x")):
            ev = events[(events["block"] == i) & (events["kind"] == kind)]
            ax.plot(ev["t"], ev[f"x{i}"], marker, ms=3, ls="none", label=kind)
        ax.set_xlabel("t")
        ax.set_ylabel(f"x{i} at events")
        ax.legend(loc="lower left", bbox_to_anchor=(0.0, 1.0), ncol=3, fontsize=7, frameon=False)  # above the data
    name = result.integrator["name"]
    fig.suptitle(f"{problem!r} with {name}: {len(events)} events, status {result.status.value}", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110, bbox_inches="tight")
    plt.close(fig)
    return fig
