"""Qualitative changes along a sweep and candidate bifurcation points, found from the data alone.

Per parameter value: the period of the recorded section points (smallest
``p`` such that point ``k + p`` repeats point ``k``), the number of distinct
points, whether each block still sticks, pure sliding, and the stick events
per block per cycle. Where these change between neighbouring values a
candidate bifurcation point is listed, classified as ``sliding`` (a block
gains or loses its sticking phase), ``period`` (the period changes: a
fixed-point bifurcation of the section map) or ``event-pattern`` (same period
and sticking, a different number of sticking phases per cycle: a
border-collision of the locus of sticking phase). :func:`refine` narrows a
candidate by bisection, computing new points. Nothing here knows any expected
value.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import pandas as pd

from nsbench.bifurcation.storage import n_blocks_of
from nsbench.bifurcation.sweep import OK_STATUSES, SweepSpec, compute_point


def _features(points: pd.DataFrame, section: str) -> np.ndarray:
    """What must repeat for a point to repeat: the peaked position, the whole state on the
    stroboscopic section, the positions (and the block) at stick or slip events."""
    blocks = range(1, n_blocks_of(points) + 1)
    cols = ["x1"] if section == "peaks" else [c for b in blocks for c in (f"x{b}", f"v{b}")]
    if section in ("stick", "mapping"):
        cols = [f"x{b}" for b in blocks]
    feats = points[cols].to_numpy(dtype=float)
    if section in ("stick", "mapping"):
        feats = np.column_stack([feats, 10.0 * points["event_block"].to_numpy(dtype=float)])
    return feats[:, ~np.all(np.isnan(feats), axis=0)]


def period_of(feats: np.ndarray, tol: float) -> int:
    """Smallest ``p <= len / 2`` with ``|feats[k + p] - feats[k]| <= tol`` for all ``k``; 0 if none."""
    n = len(feats)
    for p in range(1, n // 2 + 1):
        if np.all(np.abs(feats[p:] - feats[:-p]) <= tol):
            return p
    return 0


def distinct_count(feats: np.ndarray, tol: float) -> int:
    """Number of clusters of points farther than ``tol`` apart (greedy, in order)."""
    reps: list[np.ndarray] = []
    for f in feats:
        if not any(np.all(np.abs(f - r) <= tol) for r in reps):
            reps.append(f)
    return len(reps)


def classify(frame: pd.DataFrame, tol: float = 1e-6) -> pd.DataFrame:
    """One row per parameter value with its qualitative features.

    Columns: ``index, value, status, n_points, period, n_distinct``, then per block
    ``B``: ``sticksB, sticksB_per_cycle, blockB_sticks``, and ``pure_sliding``.
    ``period`` 0 means no period up to half the recorded points (aperiodic or long).
    """
    blocks = range(1, n_blocks_of(frame) + 1)
    rows = []
    for index, pts in frame.groupby("index", sort=True):
        first = pts.iloc[0]
        ok = first["status"] in OK_STATUSES
        section = first["section"]
        feats = _features(pts, section) if ok else np.empty((0, 1))
        scale = max(1.0, float(np.nanmax(np.abs(feats)))) if feats.size else 1.0
        period = (1 if len(feats) == 1 else period_of(feats, tol * scale)) if ok else -1
        n = int(first["n_points"])
        cycles = n / period if period > 0 else np.nan
        row = dict(index=int(index), value=float(first["value"]), status=first["status"], n_points=n,
                   period=period, n_distinct=distinct_count(feats, tol * scale) if ok else -1)
        sticks = {b: int(first[f"sticks{b}"]) for b in blocks}
        row.update({f"sticks{b}": sticks[b] for b in blocks})
        row.update({f"sticks{b}_per_cycle": float(round(sticks[b] / cycles)) if period > 0 else np.nan
                    for b in blocks})
        row.update({f"block{b}_sticks": sticks[b] > 0 for b in blocks})
        row["pure_sliding"] = not any(sticks.values())
        rows.append(row)
    return pd.DataFrame(rows)


def _blocks(features: pd.Series | pd.DataFrame) -> list[int]:
    keys = features.index if isinstance(features, pd.Series) else features.columns
    return sorted(int(k[5:-7]) for k in keys if k.startswith("block") and k.endswith("_sticks"))


def _changes(a: pd.Series, b: pd.Series) -> list[tuple[str, str]]:
    out = []
    blocks = _blocks(a)
    for blk in blocks:
        if a[f"block{blk}_sticks"] != b[f"block{blk}_sticks"]:
            what = "stops" if a[f"block{blk}_sticks"] else "starts"
            out.append(("sliding", f"block {blk} {what} sticking"))
    if a["pure_sliding"] != b["pure_sliding"]:
        out.append(("sliding", "pure sliding " + ("begins" if b["pure_sliding"] else "ends")))
    if a["period"] != b["period"]:
        out.append(("period", f"period {_p(a['period'])} -> {_p(b['period'])}"))
    elif a["period"] > 0 and any(a[f"sticks{k}_per_cycle"] != b[f"sticks{k}_per_cycle"] for k in blocks):
        def per_cycle(row: pd.Series) -> str:
            return "(" + ", ".join(f"{row[f'sticks{k}_per_cycle']:g}" for k in blocks) + ")"

        out.append(("event-pattern", f"sticking phases per cycle {per_cycle(a)} -> {per_cycle(b)}"))
    return out


def _p(p: int) -> str:
    return "none" if p == 0 else ("failed" if p < 0 else str(p))


def candidates(features: pd.DataFrame) -> pd.DataFrame:
    """Candidate bifurcation points: where features change between neighbouring values.

    Columns: ``kind, description, left, right, value`` (midpoint), ``width``.
    """
    rows = []
    feats = features.sort_values("value").reset_index(drop=True)
    for j in range(len(feats) - 1):
        a, b = feats.iloc[j], feats.iloc[j + 1]
        if a["status"] not in OK_STATUSES or b["status"] not in OK_STATUSES:
            continue
        for kind, text in _changes(a, b):
            rows.append(dict(kind=kind, description=text, left=a["value"], right=b["value"],
                             value=0.5 * (a["value"] + b["value"]), width=b["value"] - a["value"]))
    return pd.DataFrame(rows, columns=["kind", "description", "left", "right", "value", "width"])


@dataclass(frozen=True)
class Refined:
    kind: str
    description: str
    left: float
    right: float
    evaluations: int

    @property
    def value(self) -> float:
        return 0.5 * (self.left + self.right)


def _signature(spec: SweepSpec, value: float, integ, tol: float) -> pd.Series:
    one = replace(spec, start=value, stop=value, count=1)
    return classify(compute_point(one, 0, integ), tol).iloc[0]


def refine(spec: SweepSpec, left: float, right: float, kind: str, xtol: float | None = None,
           tol: float = 1e-6, max_iter: int = 40, before=None) -> Refined:
    """Narrow a candidate between ``left`` and ``right`` by bisection on the same change ``kind``.

    The midpoint's features are computed with the sweep's settings; the half
    whose ends still differ in ``kind`` is kept, until the bracket is below
    ``xtol`` (default 1e-4 of the sweep range). ``before(value)``, if given, is
    called before each value is computed (a supervised worker announces it
    there, under its limit).
    """
    from nsbench.integrators import get_integrator

    before = before or (lambda value: None)
    integ = get_integrator(spec.integrator, **spec.options)
    xtol = xtol if xtol is not None else 1e-4 * abs(spec.stop - spec.start)
    before(left)
    a = _signature(spec, left, integ, tol)
    before(right)
    b = _signature(spec, right, integ, tol)
    desc = ", ".join(t for k, t in _changes(a, b) if k == kind)
    n = 2
    for _ in range(max_iter):
        if right - left <= xtol:
            break
        mid = 0.5 * (left + right)
        before(mid)
        m = _signature(spec, mid, integ, tol)
        n += 1
        if m["status"] not in OK_STATUSES:
            break
        if any(k == kind for k, _ in _changes(a, m)):
            right, b = mid, m
        elif any(k == kind for k, _ in _changes(m, b)):
            left, a = mid, m
        else:
            break
    return Refined(kind, desc, float(left), float(right), n)


__all__ = ["classify", "candidates", "refine", "Refined", "period_of", "distinct_count"]
