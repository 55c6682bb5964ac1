"""Checks on drawn figures: every legend lies clear of every axes' data area."""

from __future__ import annotations


def overlaps(fig) -> list[str]:
    """``'legend of <title> over <title>'`` for each legend (an axes' or the figure's) whose box meets
    an axes' box; empty when every legend lies beside the data."""
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    legends = [ax.get_legend() for ax in fig.axes if ax.get_legend() is not None] + list(fig.legends)
    found = []
    for legend in legends:
        box = legend.get_window_extent(renderer)
        for ax in fig.axes:
            if ax.get_visible() and box.overlaps(ax.get_window_extent(renderer)):
                found.append(
                    f"legend {[t.get_text() for t in legend.get_texts()][:3]} over axes "
                    f"{ax.get_title() or ax.get_ylabel()!r}"
                )
    return found
