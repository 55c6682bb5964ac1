"""The same sweep with several integrators: agreement per parameter value and the cost of each diagram.

Agreement is the symmetric Hausdorff distance between the section-point sets
(the block positions ``x1, ..., xn`` of the recorded points) of an integrator and of the reference (the
first integrator) at each parameter value; cost is the summed wall time and
right-hand-side evaluations of the whole diagram.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from nsbench.bifurcation.sweep import OK_STATUSES


def hausdorff(a: np.ndarray, b: np.ndarray) -> float:
    """Symmetric Hausdorff distance between two point sets (rows); NaN if either is empty."""
    a = a[~np.isnan(a).any(axis=1)]
    b = b[~np.isnan(b).any(axis=1)]
    if not len(a) or not len(b):
        return np.nan
    d = np.sqrt(((a[:, None, :] - b[None, :, :]) ** 2).sum(axis=2))
    return float(max(d.min(axis=1).max(), d.min(axis=0).max()))


def _coords(frame: pd.DataFrame) -> list[str]:
    """The position columns (``x1 .. xn``, :func:`~nsbench.bifurcation.storage.positions_of`) that hold
    values (peaks sections record them all)."""
    from nsbench.bifurcation.storage import positions_of

    return [c for c in positions_of(frame) if frame[c].notna().any()]


def agreement(frames: dict[str, pd.DataFrame]) -> pd.DataFrame:
    """Per value: Hausdorff distance of every integrator's points to the first integrator's."""
    names = list(frames)
    ref = frames[names[0]]
    cols = _coords(ref)
    rows = []
    for index, rpts in ref.groupby("index", sort=True):
        row = {"index": int(index), "value": float(rpts["value"].iloc[0])}
        for name in names[1:]:
            other = frames[name]
            opts = other[other["index"] == index]
            ok = rpts["status"].iloc[0] in OK_STATUSES and len(opts) and opts["status"].iloc[0] in OK_STATUSES
            row[name] = hausdorff(rpts[cols].to_numpy(float), opts[cols].to_numpy(float)) if ok else np.nan
        rows.append(row)
    return pd.DataFrame(rows)


def costs(frames: dict[str, pd.DataFrame], walls: dict[str, float] | None = None) -> pd.DataFrame:
    """Cost of each diagram: summed per-point wall time, evaluations, steps, failures."""
    rows = []
    for name, frame in frames.items():
        pts = frame.groupby("index").first()
        rows.append(
            dict(
                integrator=name,
                values=len(pts),
                failed=int((~pts["status"].isin(OK_STATUSES)).sum()),
                point_wall_time_s=float(pts["wall_time"].sum()),
                run_wall_time_s=(walls or {}).get(name, np.nan),
                nfev=int(pts["nfev"].sum()),
                nsteps=int(pts["nsteps"].sum()),
                n_events=int(pts["n_events"].sum()),
            )
        )
    return pd.DataFrame(rows)


def report(frames: dict[str, pd.DataFrame], walls: dict[str, float] | None = None) -> str:
    """Markdown: cost table and agreement summary (median, max and share of values below 1e-6)."""
    names = list(frames)
    agree = agreement(frames)
    lines = [
        f"# Sweep across integrators (reference: {names[0]})",
        "",
        "## Cost of each diagram",
        "",
        _table(costs(frames, walls)),
        "",
        "## Agreement with the reference",
        "",
        "Symmetric Hausdorff distance between the section-point sets (block positions), per parameter value.",
        "",
    ]
    rows = []
    for name in names[1:]:
        d = agree[name].to_numpy(float)
        good = d[~np.isnan(d)]
        rows.append(
            dict(
                integrator=name,
                compared=len(good),
                median=float(np.median(good)) if len(good) else np.nan,
                max=float(good.max()) if len(good) else np.nan,
                share_below_1e_6=float((good < 1e-6).mean()) if len(good) else np.nan,
            )
        )
    lines.append(_table(pd.DataFrame(rows)) if rows else "(one integrator only)")
    return "\n".join(lines) + "\n"


def _table(frame: pd.DataFrame) -> str:
    """A Markdown table of the sweep reports (:func:`nsbench.render.markdown`, numbers to 4 digits)."""
    from nsbench.render import markdown, four_digits

    return markdown(frame, fmt=four_digits)
