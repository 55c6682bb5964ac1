"""How an integrator's cost grows with the size of a problem: the scaling study of a suite.

A suite whose problems differ only in the number of blocks ``n`` (for example the
packaged ``chain-scaling``: ``params = {n = [2, 4, ..., 64]}``) is a *family*. For
each family, integrator and ``n`` this module finds the cheapest configuration
that reaches a switching-time error target (:data:`SCALING_TARGET`, the
fixed-target rule of :mod:`nsbench.bench.tables`: success, the reference's event
sequence, every switching time within the target), fits the growth exponent
``b`` of ``cost ~ n**b`` on log-log axes over the ``n`` it reaches, and records
where the integrator stops being usable and why.
"""

from __future__ import annotations

import json
import math
from typing import Any

import numpy as np
import pandas as pd

from nsbench.bench.tables import reached_mask
from nsbench.status import Status

#: the switching-time error the scaling study asks every integrator to reach
SCALING_TARGET = 1e-8
#: set-up times below this at every n are not fitted (seconds)
NEGLIGIBLE_SETUP = 0.01
#: costs whose growth is fitted, with their labels
COSTS = {
    "wall_time": "wall time (s, warm median)",
    "integrator_time": "integrator time (s)",
    "nfev": "right-hand side evaluations",
}


def _family_and_n(config_json: str) -> tuple[str, int | None]:
    """The family key of a problem config (everything but ``n``) and its ``n``; ``('', None)`` for none.

    Rows without a problem config (cost-only rows ingested from pytest-benchmark,
    such as a timed sweep) belong to no family.
    """
    if not config_json or config_json in ("<NA>", "nan", "None"):
        return "", None
    config = json.loads(config_json)
    params = dict(config.get("params") or {})
    n = params.pop("n", None)
    key = json.dumps({**config, "params": params}, sort_keys=True)
    return key, (int(n) if n is not None else None)


def _family_label(key: str) -> str:
    if not key:
        return ""
    from nsbench.bench.keys import problem_label

    return problem_label(json.loads(key))


def with_family(frame: pd.DataFrame) -> pd.DataFrame:
    """``frame`` with ``family`` (label of the problem without ``n``) and ``n`` (NA when absent)."""
    if frame.empty or "problem_config" not in frame:
        return frame.assign(family=pd.Series(dtype="string"), n=pd.Series(dtype="Int64"))
    keys = [_family_and_n(str(c)) for c in frame["problem_config"]]
    return frame.assign(family=[_family_label(k) for k, _ in keys], n=pd.array([n for _, n in keys], dtype="Int64"))


def scaling_families(frame: pd.DataFrame) -> list[str]:
    """Families of ``frame`` run at two or more ``n``: the ones a scaling study applies to."""
    framed = with_family(frame)
    if framed.empty:
        return []
    counts = framed.dropna(subset=["n"]).groupby("family")["n"].nunique()
    return sorted(counts[counts >= 2].index)


def _why_not(rows: pd.DataFrame, target: float) -> str:
    """Why no configuration of one (integrator, n) reaches ``target``: the statuses, in short."""
    reasons = []
    for status, group in rows.groupby("status", sort=True):
        if status == Status.SUCCESS:
            wrong = int((~group["sequence_ok"].fillna(False).astype(bool)).sum())
            if wrong:
                reasons.append(f"wrong event sequence x{wrong}")
            short = len(group) - wrong
            if short:
                best = group["switch_err_max"].min()
                reasons.append(f"error {best:.1e} > {target:g}" if pd.notna(best) else f"no error x{short}")
        else:
            reasons.append(f"{status} x{len(group)}")
    return ", ".join(reasons)


def scaling_table(frame: pd.DataFrame, target: float = SCALING_TARGET) -> pd.DataFrame:
    """One row per (family, integrator, n): the cheapest configuration reaching ``target``.

    Columns: ``family, integrator, n, reached, options, wall_time, wall_spread,
    integrator_time, nfev, setup_time`` (the largest over the integrator's cases
    at that ``n``: the first one compiles, the others reuse the code; kept out of
    the timed runs),
    ``events_per_time`` (the reference's events per unit time) and ``why``
    (why nothing reached the target, when so).
    """
    framed = with_family(frame)
    out = []
    for family in scaling_families(frame):
        fam = framed[framed["family"] == family]
        for (name, n), rows in fam.groupby(["integrator", "n"], sort=True):
            if (rows["status"] == Status.UNSUPPORTED).all():
                continue
            span = float(rows["t_end"].iloc[0] - rows["t0"].iloc[0])
            n_ref = rows["n_ref"].dropna()
            row: dict[str, Any] = {
                "family": family,
                "integrator": name,
                "n": int(n),
                "reached": False,
                "options": "",
                "wall_time": math.nan,
                "wall_spread": math.nan,
                "integrator_time": math.nan,
                "nfev": math.nan,
                # the first configuration run in a worker compiles, the others reuse its code: the largest
                "setup_time": float(rows["setup_time"].max()) if rows["setup_time"].notna().any() else math.nan,
                "events_per_time": float(n_ref.iloc[0]) / span if len(n_ref) and span > 0 else math.nan,
                "why": "",
            }
            is_reference = (rows["reference"] == name).all()
            ok = rows[reached_mask(rows, target)] if not is_reference else rows[rows["status"] == Status.SUCCESS]
            if len(ok) and ok["wall_time"].notna().any():
                best = ok.loc[ok["wall_time"].idxmin()]
                row.update(
                    reached=True,
                    options=best["options"],
                    wall_time=float(best["wall_time"]),
                    wall_spread=float(best["wall_spread"]) if pd.notna(best["wall_spread"]) else math.nan,
                    integrator_time=float(best["integrator_time"]) if pd.notna(best["integrator_time"]) else math.nan,
                    nfev=float(best["nfev"]) if pd.notna(best["nfev"]) else math.nan,
                )
                if is_reference:
                    # the reference run compiled it before its cases ran: their set-up is a cache load
                    row.update(
                        why="the reference (its set-up, done by the reference run, is not shown)", setup_time=math.nan
                    )
            else:
                row["why"] = _why_not(rows, target)
            out.append(row)
    return pd.DataFrame(
        out,
        columns=[
            "family",
            "integrator",
            "n",
            "reached",
            "options",
            "wall_time",
            "wall_spread",
            "integrator_time",
            "nfev",
            "setup_time",
            "events_per_time",
            "why",
        ],
    )


def growth_exponent(n: np.ndarray, cost: np.ndarray) -> float:
    """Least-squares slope of ``log cost`` against ``log n`` (NaN with fewer than 3 usable points).

    Three points at least: with two the slope is a single ratio and says nothing
    about the trend. Costs of zero or less (a counter an integrator does not
    keep) are left out.
    """
    n, cost = np.asarray(n, float), np.asarray(cost, float)
    keep = np.isfinite(n) & np.isfinite(cost) & (n > 0) & (cost > 0)
    if keep.sum() < 3:
        return math.nan
    slope, _ = np.polyfit(np.log(n[keep]), np.log(cost[keep]), 1)
    return float(slope)


def scaling_summary(table: pd.DataFrame) -> pd.DataFrame:
    """Per (family, integrator): growth exponents, the largest ``n`` reaching the target, where it stops.

    Columns: ``family, integrator, exponent_wall_time, exponent_integrator_time,
    exponent_nfev, exponent_setup_time, largest_n_reached, n_reached, n_tried,
    first_n_not_reached, why``.
    """
    rows = []
    for (family, name), group in table.groupby(["family", "integrator"], sort=True):
        group = group.sort_values("n")
        hit = group[group["reached"]]
        miss = group[~group["reached"]]
        row: dict[str, Any] = {"family": family, "integrator": name}
        for cost in COSTS:
            row[f"exponent_{cost}"] = growth_exponent(hit["n"].to_numpy(), hit[cost].to_numpy())
        setup = group["setup_time"].to_numpy(dtype=float)
        # set-up under NEGLIGIBLE_SETUP is process noise (a worker's first import), not a trend
        row["exponent_setup_time"] = growth_exponent(
            group["n"].to_numpy(), np.where(setup >= NEGLIGIBLE_SETUP, setup, np.nan)
        )
        row.update(
            largest_n_reached=int(hit["n"].max()) if len(hit) else pd.NA,
            n_reached=len(hit),
            n_tried=len(group),
            first_n_not_reached=int(miss["n"].min()) if len(miss) else pd.NA,
            why=str(miss.iloc[0]["why"]) if len(miss) else "",
        )
        rows.append(row)
    out = pd.DataFrame(
        rows,
        columns=[
            "family",
            "integrator",
            *(f"exponent_{c}" for c in COSTS),
            "exponent_setup_time",
            "largest_n_reached",
            "n_reached",
            "n_tried",
            "first_n_not_reached",
            "why",
        ],
    )
    return out.sort_values(["family", "exponent_wall_time"], na_position="last", kind="stable").reset_index(drop=True)


SCALING_CAPTION = (
    "Scaling with the number of blocks n: for each integrator, the cheapest configuration reaching a "
    f"switching-time error of {SCALING_TARGET:g} at each n (success, the reference's event sequence, every "
    "switching time within the target); exponent_* is the least-squares slope b of cost ~ n^b on log-log "
    "axes over the n it reaches (NaN with fewer than 3 of them); setup (compilation) is fitted over the "
    "n where it exceeds 10 ms (3 of them at least). largest_n_reached is where it still reaches the target; first_n_not_reached and why say where "
    "and how it stops being usable (time limit, wrong event sequence, error above the target)."
)
