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

from nsbench.bifurcation.storage import n_blocks_of, positions_of, state_columns
from nsbench.bifurcation.sweep import OK_STATUSES, SweepSpec, compute_point


def _features(points: pd.DataFrame, section: str) -> np.ndarray:
    """What must repeat for a point to repeat: the peaked position, the whole state on the
    stroboscopic section, the positions (and the block) at stick or slip events."""
    cols, block_feature = _feature_columns(points, section)
    feats = points[cols].to_numpy(dtype=float)
    if block_feature:
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

    The values are classified together, with array operations over all the
    values that recorded the same number of points (a sweep's usual case): the
    same periods and counts as :func:`period_of` and :func:`distinct_count` give
    value by value, without a Python loop per value.
    """
    if frame.empty:
        return pd.DataFrame([])
    blocks = range(1, n_blocks_of(frame) + 1)
    order = np.argsort(frame["index"].to_numpy(), kind="stable")  # a value's rows keep their order
    rows = frame.take(order)
    idx = rows["index"].to_numpy()
    starts = np.flatnonzero(np.r_[True, idx[1:] != idx[:-1]])
    counts = np.diff(np.r_[starts, len(idx)])
    first = rows.iloc[starts]
    status = first["status"].to_numpy(dtype=object)
    ok = np.isin(status, [str(s) for s in OK_STATUSES])
    period = np.full(len(starts), -1, dtype=np.int64)
    distinct = np.full(len(starts), -1, dtype=np.int64)
    sections = first["section"].to_numpy(dtype=object)
    for section in np.unique(sections[ok]):
        columns, block_feature = _feature_columns(rows, section)
        values = rows[columns].to_numpy(dtype=float)
        if block_feature:
            values = np.column_stack([values, 10.0 * rows["event_block"].to_numpy(dtype=float)])
        for m in np.unique(counts[ok & (sections == section)]):
            members = np.flatnonzero(ok & (sections == section) & (counts == m))
            for part in np.array_split(members, max(1, len(members) * int(m) ** 2 // 2_000_000)):
                feats = values[starts[part][:, None] + np.arange(m)]  # (values, points, features)
                period[part], distinct[part] = _period_and_distinct(feats, tol)
    n = first["n_points"].to_numpy(dtype=np.int64)
    out = pd.DataFrame(
        {
            "index": idx[starts].astype(np.int64),
            "value": first["value"].to_numpy(dtype=float),
            "status": first["status"].to_numpy(),
            "n_points": n,
            "period": period,
            "n_distinct": distinct,
        }
    )
    sticks = {b: first[f"sticks{b}"].to_numpy(dtype=np.int64) for b in blocks}
    with np.errstate(divide="ignore", invalid="ignore"):
        cycles = n / period
        for b in blocks:
            out[f"sticks{b}"] = sticks[b]
        for b in blocks:
            out[f"sticks{b}_per_cycle"] = np.where(period > 0, np.round(sticks[b] / cycles), np.nan)
    for b in blocks:
        out[f"block{b}_sticks"] = sticks[b] > 0
    out["pure_sliding"] = ~np.any([sticks[b] > 0 for b in blocks], axis=0) if len(blocks) else True
    return out


def _feature_columns(points: pd.DataFrame, section: str) -> tuple[list[str], bool]:
    """The columns of :func:`_features`, and whether ``10 * event_block`` joins them."""
    states = state_columns(points)
    if section in ("stick", "mapping") or section.startswith("event:"):  # at events: the positions of the blocks
        return positions_of(points)[: n_blocks_of(points)] or states[:1], True
    # peaks: the first position (x1: a section of v1); strobe: the whole state
    return (states[:1] if section == "peaks" else states), False


def _period_and_distinct(feats: np.ndarray, tol: float) -> tuple[np.ndarray, np.ndarray]:
    """:func:`period_of` and :func:`distinct_count` of each ``feats[i]`` (points by features), all at once.

    As there, a feature that is NaN at every point of a value is left out of its
    comparisons, and the tolerance is ``tol`` times the largest feature (at least 1).
    """
    n_values, m, _ = feats.shape
    unused = np.all(np.isnan(feats), axis=1)[:, None, :]  # (values, 1, features)
    scale = np.maximum(1.0, np.max(np.abs(np.nan_to_num(feats, nan=0.0)), axis=(1, 2)))
    limit = (tol * scale)[:, None, None]
    period = np.zeros(n_values, dtype=np.int64) if m > 1 else np.ones(n_values, dtype=np.int64)
    for p in range(1, m // 2 + 1):
        same = np.all((np.abs(feats[:, p:] - feats[:, :-p]) <= limit) | unused, axis=(1, 2))
        period[(period == 0) & same] = p
    # close[i, j, k]: points j and k of value i within the tolerance; greedy representatives in order
    close = np.all((np.abs(feats[:, :, None, :] - feats[:, None, :, :]) <= limit[..., None]) | unused[:, None], axis=3)
    rep = np.zeros((n_values, m), dtype=bool)
    for j in range(m):
        rep[:, j] = ~np.any(close[:, j, :j] & rep[:, :j], axis=1)
    return period, rep.sum(axis=1)


def _blocks(features: pd.Series | pd.DataFrame) -> list[int]:
    keys = features.index if isinstance(features, pd.Series) else features.columns
    return sorted(int(k[5:-7]) for k in keys if k.startswith("block") and k.endswith("_sticks"))


def _changes(a: pd.Series, b: pd.Series, friction: bool = True) -> list[tuple[str, str]]:
    out = []
    blocks = _blocks(a)
    for blk in blocks:
        if a[f"block{blk}_sticks"] != b[f"block{blk}_sticks"]:
            what = "stops" if a[f"block{blk}_sticks"] else "starts"
            body = f"block {blk}" if friction else ("the motion" if len(blocks) == 1 else f"body {blk}")
            out.append(("sliding", f"{body} {what} sticking"))
    if a["pure_sliding"] != b["pure_sliding"]:
        what = "pure sliding" if friction else "motion without sticking"
        out.append(("sliding", f"{what} " + ("begins" if b["pure_sliding"] else "ends")))
    if a["period"] != b["period"]:
        out.append(("period", f"period {_p(a['period'])} -> {_p(b['period'])}"))
    elif a["period"] > 0 and any(a[f"sticks{k}_per_cycle"] != b[f"sticks{k}_per_cycle"] for k in blocks):

        def per_cycle(row: pd.Series) -> str:
            return "(" + ", ".join(f"{row[f'sticks{k}_per_cycle']:g}" for k in blocks) + ")"

        out.append(("event-pattern", f"sticking phases per cycle {per_cycle(a)} -> {per_cycle(b)}"))
    return out


def _p(p: int) -> str:
    return "none" if p == 0 else ("failed" if p < 0 else str(p))


def candidates(features: pd.DataFrame, blocks: bool = True) -> pd.DataFrame:
    """Candidate bifurcation points: where features change between neighbouring values.

    Columns: ``kind, description, left, right, value`` (midpoint), ``width``. ``blocks``
    is whether the swept problem has blocks on a belt (its ``traits.belt_blocks``): the
    descriptions speak of blocks and pure sliding for the friction oscillators, of the motion's
    sticking phases for the others (an impact oscillator's mass sticking to its stop).
    """
    rows = []
    feats = features.sort_values("value").reset_index(drop=True)
    for j in _differing_pairs(feats):
        a, b = feats.iloc[j], feats.iloc[j + 1]
        if a["status"] not in OK_STATUSES or b["status"] not in OK_STATUSES:
            continue
        for kind, text in _changes(a, b, blocks):
            rows.append(
                dict(
                    kind=kind,
                    description=text,
                    left=a["value"],
                    right=b["value"],
                    value=0.5 * (a["value"] + b["value"]),
                    width=b["value"] - a["value"],
                )
            )
    return pd.DataFrame(rows, columns=["kind", "description", "left", "right", "value", "width"])


def _differing_pairs(feats: pd.DataFrame) -> np.ndarray:
    """Positions ``j`` where row ``j + 1`` differs from row ``j`` in something :func:`_changes` looks at
    (the others have no change: only these are compared one by one)."""
    if len(feats) < 2:
        return np.zeros(0, dtype=np.int64)
    blocks = _blocks(feats)
    columns = [f"block{b}_sticks" for b in blocks] + ["pure_sliding", "period"]
    plain = feats[columns].to_numpy(dtype=float)
    differ = np.any(plain[1:] != plain[:-1], axis=1)
    if blocks:
        per_cycle = feats[[f"sticks{b}_per_cycle" for b in blocks]].to_numpy(dtype=float)
        differ |= (feats["period"].to_numpy()[:-1] > 0) & np.any(per_cycle[1:] != per_cycle[:-1], axis=1)
    return np.flatnonzero(differ)


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


def refine(
    spec: SweepSpec,
    left: float,
    right: float,
    kind: str,
    xtol: float | None = None,
    tol: float = 1e-6,
    max_iter: int = 40,
    before=None,
) -> Refined:
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
