"""The answer per family of methods: what each family costs and leaves, from the tidy results.

For each problem and each integrator (one per family in the ``families`` suite)
:func:`families_table` reads its ladder (the option the suite varies: ``h`` for
fixed-step and time-stepping methods, ``eta`` for the switch model, ``eps`` for
smoothing), the cheapest configuration that reaches each switching-time target,
the observed order along the ladder (:func:`nsbench.bench.metrics.observed_order`;
for ``eps``, which sharpens as it grows, against ``1/eps``) fitted separately across
switches (the switching-time error), on a smooth arc (``arc_err``, measured by
:func:`smooth_arc_error`) and over the whole trajectory (the state error), and the
stick creep at the ladder's ends.
:func:`families_answer` says it in sentences, for the report's opening.
"""

from __future__ import annotations

import json
import math
from typing import Any

import numpy as np
import pandas as pd

from nsbench.bench.metrics import observed_order
from nsbench.bench.tables import reached_mask
from nsbench.status import Status

#: The option each whole-system family's ladder varies, and whether it sharpens as it grows.
LADDERS = {"time-stepping": ("h", False), "switch-model": ("eta", False), "smoothing": ("eps", True)}
FAMILY_ORDER = ("event-driven", "time-stepping", "switch-model", "smoothing")

CAPTION = (
    "One row per problem and integrator, grouped by family and, within it, by ecosystem (the software the "
    "method comes from). `ladder`: the option the suite varies and its range; "
    "`reaches <target>`: the median wall time per run of the cheapest configuration whose switch "
    "sequence is the reference's with every switching-time error within the target (blank: none "
    "does); `order (switches)`, `order (states)`: the log-log slope of `switch_err_max` and "
    "`state_err_l2` along the ladder, over the configurations with the reference's switch sequence "
    "(against `1/eps` for smoothing); `order (smooth arcs)`: the slope of `arc_err`, the state error "
    "of a run started on the reference inside its longest slipping arc and stopped before the arc "
    "ends (no switch), over the successful configurations; `creep`: `stick_creep` (the drift velocity off the belt "
    "per unit of stick time while the reference sticks under an in-cone load, `abs(R) <= fs` by the reference's "
    "state and the run's, in the run's matched prefix) at the loosest and the tightest configuration; `located`: the largest error of the switch times the "
    "method locates itself (`located_err_max`), at the tightest configuration, where it reports them; "
    "`sequence ok`: configurations with "
    "the reference's switch sequence, of all run."
)


def family_of(row: pd.Series) -> str:
    """A row's family: its ``family`` column, or the registered integrator's (older results), else 'other'."""
    fam = row.get("family")
    if isinstance(fam, str) and fam:
        return fam
    from nsbench.integrators import integrator_class

    try:
        return integrator_class(str(row["integrator"])).capabilities.family
    except Exception:  # an integrator not installed here
        return "other"


def ecosystem_of(name: str) -> str:
    """The software an integrator comes from (``Integrator.ecosystem``), or 'other' where it is not installed."""
    from nsbench.integrators import integrator_class

    try:
        return str(getattr(integrator_class(name), "ecosystem", "nsbench"))
    except Exception:  # an integrator not registered here
        return "other"


def has_whole_system(frame: pd.DataFrame) -> bool:
    """Whether the results hold any whole-system method (the families report applies)."""
    return bool(len(frame)) and any(family_of(r) in LADDERS for _, r in frame.iterrows())


def _ladder(rows: pd.DataFrame, family: str) -> tuple[str, list[float], bool]:
    """The option that varies along the rows (the family's ladder, else the step option) and its values."""
    options = [json.loads(o) if isinstance(o, str) and o else {} for o in rows["options"]]
    name, sharpens = LADDERS.get(family, ("", False))
    if not name or not any(name in o for o in options):
        # the method's own step option (lugre, of the smoothing family, varies rtol, not eps): a step or a
        # tolerance, which tightens as it shrinks, so it is fitted as it is, never as 1/value
        name = str(rows["step_option"].iloc[0]) if "step_option" in rows else ""
        sharpens = False
    values = [float(o.get(name, math.nan)) if isinstance(o.get(name), (int, float)) else math.nan for o in options]
    return name, values, sharpens


def families_table(frame: pd.DataFrame, targets: tuple[float, ...]) -> pd.DataFrame:
    """One row per (problem, integrator): family, ladder, cost to reach each target, observed orders, creep."""
    out: list[dict[str, Any]] = []
    if not len(frame):
        return pd.DataFrame()
    frame = frame.assign(_family=[family_of(r) for _, r in frame.iterrows()])
    for (problem, name), rows in frame.groupby(["problem_label", "integrator"], sort=True):
        family = str(rows["_family"].iloc[0])
        if (rows["reference"] == name).all() or (rows["status"] == Status.UNSUPPORTED).all():
            continue
        option, values, sharpens = _ladder(rows, family)
        steps = [1.0 / v if sharpens and v else v for v in values]
        good = (rows["status"] == Status.SUCCESS) & rows["sequence_ok"].fillna(False).astype(bool)
        row: dict[str, Any] = {
            "problem": problem,
            "family": family,
            "ecosystem": ecosystem_of(str(name)),
            "integrator": name,
            "ladder": _range(option, values),
        }
        for target in targets:
            ok = rows[reached_mask(rows, target)]
            row[f"reaches {target:g}"] = float(ok["wall_time"].min()) if len(ok) else math.nan
        sel = good.to_numpy()
        row["order (switches)"] = observed_order(
            [s for s, k in zip(steps, sel) if k], rows["switch_err_max"].to_numpy(dtype=float)[sel]
        )
        row["order (states)"] = observed_order(
            [s for s, k in zip(steps, sel) if k], rows["state_err_l2"].to_numpy(dtype=float)[sel]
        )
        ran = (rows["status"] == Status.SUCCESS).to_numpy()
        arc = rows["arc_err"].to_numpy(dtype=float) if "arc_err" in rows else np.full(len(rows), math.nan)
        row["order (smooth arcs)"] = observed_order([s for s, k in zip(steps, ran) if k], arc[ran])
        creep = rows.assign(_v=values).sort_values("_v", ascending=sharpens)["stick_creep"].to_numpy(dtype=float)
        row["creep (loosest)"] = float(creep[0]) if len(creep) else math.nan
        row["creep (tightest)"] = float(creep[-1]) if len(creep) else math.nan
        if "located_err_max" in rows and rows["located_err_max"].notna().any():
            located = rows.assign(_v=values).sort_values("_v", ascending=sharpens)["located_err_max"]
            row["located (tightest)"] = float(located.to_numpy(dtype=float)[-1])
        row["sequence ok"] = f"{int(sel.sum())} of {len(rows)}"
        out.append(row)
    table = pd.DataFrame(out)
    if len(table):
        rank = {f: i for i, f in enumerate(FAMILY_ORDER)}
        table = table.sort_values(
            ["problem", "family", "ecosystem"],
            key=lambda col: col.map(rank).fillna(9) if col.name == "family" else col,
            kind="stable",
        ).reset_index(drop=True)
    return table


def _range(option: str, values: list[float]) -> str:
    finite = sorted(v for v in values if math.isfinite(v))
    if not option or not finite:
        return "defaults"
    return f"{option} {finite[-1]:g} .. {finite[0]:g}" if len(finite) > 1 else f"{option} {finite[0]:g}"


def families_answer(table: pd.DataFrame, targets: tuple[float, ...]) -> list[str]:
    """The answer per family in sentences: cost to the targets, creep, observed order."""
    lines: list[str] = []
    if not len(table):
        return lines
    for problem, rows in table.groupby("problem", sort=False):
        driven = rows[rows["family"] == "event-driven"]
        if len(driven) > 1:
            # A suite of many event-driven methods (the default) is ranked in the report's tables; a
            # sentence per method (tolerance ladders with no order to fit) would bury the other families.
            lines.append(_event_driven_line(str(problem), driven, targets))
            rows = rows[rows["family"] != "event-driven"]
        for _, r in rows.iterrows():
            reached = [f"{t:g} in {r[f'reaches {t:g}']:.3g} s" for t in targets if math.isfinite(r[f"reaches {t:g}"])]
            missed = [f"{t:g}" for t in targets if not math.isfinite(r[f"reaches {t:g}"])]
            cost = ("reaches " + ", ".join(reached)) if reached else "reaches no target"
            if reached and missed:
                cost += f" (not {', '.join(missed)})"
            order = r["order (switches)"]
            order_text = (
                f"switching-time error of order {order:.2f} along {r['ladder']}"
                if math.isfinite(order)
                else f"no order measurable along {r['ladder']} (fewer than two configurations with the switch sequence)"
            )
            arc = r.get("order (smooth arcs)", math.nan)
            if math.isfinite(arc):
                order_text += f", order {arc:.2f} on a smooth arc"
            creep = ""
            if math.isfinite(r["creep (tightest)"]):
                span = f"{r['creep (tightest)']:.2g}"
                if math.isfinite(r["creep (loosest)"]):  # the loosest configuration may have no creep to read
                    span = f"{r['creep (loosest)']:.2g} to {span}"
                creep = f"; creep {span} (drift velocity) while the reference sticks under an in-cone load"
            located = r.get("located (tightest)", math.nan)
            if isinstance(located, float) and math.isfinite(located):
                creep += f"; its own switch times within {located:.2g} at the tightest configuration"
            lines.append(
                f"{problem}, {r['family']} ({r['integrator']}): {cost}; {order_text}{creep}; "
                f"switch sequence right in {r['sequence ok']} configurations."
            )
    return lines


def _event_driven_line(problem: str, rows: pd.DataFrame, targets: tuple[float, ...]) -> str:
    """One sentence for a problem's event-driven methods: the cheapest of them to each target."""
    parts = []
    for t in targets:
        cost = rows[f"reaches {t:g}"].to_numpy(dtype=float)
        if np.isfinite(cost).any():
            k = int(np.nanargmin(cost))
            parts.append(f"{t:g} by {rows['integrator'].iloc[k]} in {cost[k]:.3g} s")
        else:
            parts.append(f"{t:g} by none")
    return (
        f"{problem}, event-driven ({len(rows)} methods, ranked with their ties in the answer above): the lowest "
        "median time to " + ", ".join(parts) + "."
    )


#: Where the smooth-arc run starts and stops inside its arc: away from both switches by a quarter of the arc.
ARC_MARGIN = 0.25


def smooth_arc_window(
    ref_times: np.ndarray, t_dense: np.ndarray, y_dense: np.ndarray, v_belt: float | None
) -> tuple[int, int] | None:
    """Dense indices ``(a, b)`` of the reference's longest smooth arc, its middle half.

    The arcs are the spans between consecutive reference events (and the span's ends); on a belt
    problem only arcs on which some block slips count (on an all-stuck arc every method of the friction
    family moves with the belt, so its error says nothing). ``a`` is the first dense point a quarter of
    the arc after its start, ``b`` the last a quarter before its end; ``None`` if no arc holds two.
    """
    if t_dense.size < 2:
        return None
    bounds = np.concatenate([[t_dense[0]], np.sort(np.asarray(ref_times, dtype=float)), [t_dense[-1]]])
    best, best_len = None, 0.0
    for ta, tb in zip(bounds[:-1], bounds[1:]):
        length = tb - ta
        inside = np.flatnonzero((t_dense >= ta + ARC_MARGIN * length) & (t_dense <= tb - ARC_MARGIN * length))
        if inside.size < 2 or length <= best_len:
            continue
        if v_belt is not None:
            mid = inside[inside.size // 2]
            if not np.any(np.abs(y_dense[1::2, mid] - v_belt) > 1e-6 * max(1.0, abs(v_belt))):
                continue
        best, best_len = (int(inside[0]), int(inside[-1])), length
    return best


def smooth_arc_error(
    problem, integ, ref_events: pd.DataFrame, t_dense: np.ndarray, y_dense: np.ndarray, v_belt: float | None
) -> float:
    """``arc_err``: the state error of ``integ`` over a smooth arc, started on the reference.

    The run starts at the reference's dense state at ``a`` and stops at ``b``
    (:func:`smooth_arc_window`) with no switch in between, so its error is the method's on smooth
    stepping alone, where the whole-trajectory error mixes in what every switch left. Max-norm of the
    state error at ``b``; NaN if there is no such arc, or the run fails or switches.
    """
    from nsbench.engine import simulate

    window = smooth_arc_window(ref_events["t"].to_numpy() if len(ref_events) else np.empty(0), t_dense, y_dense, v_belt)
    if window is None:
        return math.nan
    a, b = window
    run = simulate(problem, integ, float(t_dense[b]), t0=float(t_dense[a]), y0=np.array(y_dense[:, a]), check_points=0)
    if not run.ok or len(run.events):
        return math.nan
    return float(np.max(np.abs(np.asarray(run.y_final, dtype=float) - y_dense[:, b])))
