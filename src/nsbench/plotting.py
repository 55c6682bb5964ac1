"""Writing figures, and the figures of single runs (matplotlib is imported here on first use, never by
``import nsbench``).

:func:`pyplot`, :func:`preload` and :func:`save` are shared by every command that draws (sweeps,
continuation, simulate): figures are written as PNG (compact, for reports), SVG and PDF unless fewer
formats are asked for.
"""

from __future__ import annotations

import threading
from pathlib import Path
from typing import TYPE_CHECKING, Any, Sequence, cast

if TYPE_CHECKING:  # pragma: no cover
    from nsbench.problems.oscillator import FrictionOscillator
    from nsbench.results import SimulationResult

BLOCK_COLOURS = ("tab:blue", "tab:red")
FORMATS = ("png", "svg", "pdf")


#: The thread of :func:`preload`, if one was started: drawing waits for it (matplotlib is not thread-safe).
_PRELOAD: Any = None


def pyplot():
    """matplotlib's pyplot on the Agg backend (after :func:`preload`'s thread, if one runs)."""
    if _PRELOAD is not None and _PRELOAD.ident != threading.get_ident():
        _PRELOAD.join()
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    return plt


def preload(formats: Sequence[str] = FORMATS) -> None:
    """Import matplotlib and the writers of ``formats``, and draw a small figure in each, in a
    background thread: a command that draws after a long computation then pays the imports and
    the first use of the fonts and writers while its workers compute, not afterwards (about half a
    second, of which the first drawing is a fifth). Figures drawn later wait for the thread."""
    global _PRELOAD

    def load() -> None:
        try:
            pyplot()
            import importlib
            import io

            from matplotlib.figure import Figure

            small = Figure(figsize=(2.0, 1.5))  # not pyplot's: nothing shared with the figures drawn later
            ax = small.add_subplot()
            ax.set_xlabel("v0")
            small.suptitle("warm-up", fontsize=9)
            for fmt in formats:
                if fmt in ("svg", "pdf"):
                    importlib.import_module(f"matplotlib.backends.backend_{fmt}")
                small.savefig(io.BytesIO(), format=fmt, bbox_inches="tight")
        except Exception:  # nothing lost: the figure drawn later meets the same problem and reports it
            pass

    if _PRELOAD is None:
        _PRELOAD = threading.Thread(target=load, name="nsbench-import-matplotlib", daemon=True)
        _PRELOAD.start()


def save(fig, base: str | Path, formats: Sequence[str] = FORMATS, dpi: int = 100) -> list[Path]:
    """Write ``fig`` as ``base.<fmt>`` for every format; close it; return the paths.

    The saved area is the figure's tight bounding box, so a legend placed beside the
    axes (where it covers no data) is kept whole. It is found once, on one drawing
    without output: asked for as ``"tight"``, every format would draw the figure
    twice, once for the box (a third of a second for a diagram in three formats).
    """
    plt = pyplot()
    base = Path(base)
    base.parent.mkdir(parents=True, exist_ok=True)
    from matplotlib.layout_engine import PlaceHolderLayoutEngine

    fig.draw_without_rendering()  # the ticks and texts where they will be drawn
    box = fig.get_tightbbox(fig.canvas.get_renderer()).padded(plt.rcParams["savefig.pad_inches"])
    if isinstance(fig.get_layout_engine(), PlaceHolderLayoutEngine):
        # what tight_layout() leaves: it does nothing, but with any engine savefig draws once more first
        fig.set_layout_engine(None)
    out = []
    for fmt in formats:
        path = base.parent / f"{base.name}.{fmt}"  # not with_suffix: names may hold dots
        fig.savefig(path, dpi=dpi, metadata={"Date": None} if fmt in ("svg", "pdf") else None, bbox_inches=box)
        out.append(path)
    plt.close(fig)
    return out


def plot_simulation(result: "SimulationResult", path: str | Path):
    """Time series of every state and the phase plane of each block, events marked.

    Returns the matplotlib figure (also saved to ``path``).
    """
    plt = pyplot()
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
