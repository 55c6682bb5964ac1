"""The bifurcations the paper names, located by continuation (:mod:`nsbench.periodic`).

For each stated bifurcation (``paper_values.csv``), every branch of periodic
orbits in a window around the stated value is traced (from the attractor reached
from rest at the window's start, then whatever the motion settles on where a
branch ends), and the located bifurcation nearest the stated value is reported
beside it: its value to about 1e-11, its kind, the paper's category it falls in,
and whether that category is the one the paper names. The window is the stated
value (or interval) widened by ``WINDOW`` of the paper's sweep range on each side.
"""

from __future__ import annotations

import time
from typing import Callable

import numpy as np
import pandas as pd

#: half-width of the window around a stated value, as a fraction of the sweep's range
WINDOW = 0.05
COLUMNS = [
    "case",
    "sweep",
    "paper_kind",
    "paper_value",
    "continued_value",
    "difference",
    "continued_kind",
    "continued_category",
    "same_category",
    "window",
    "branches",
    "located",
    "seconds",
    "detail",
]


def continue_claims(
    claims: pd.DataFrame,
    ranges: dict[tuple[int, str], tuple[float, float]],
    *,
    steps: int = 60,
    transient: float = 1000.0,
    cubic: bool = False,
    log: Callable[[str], None] = print,
) -> pd.DataFrame:
    """One row per stated bifurcation: the nearest located bifurcation of any kind in its window.

    ``ranges`` maps ``(case, sweep)`` to the paper sweep's range (for the window width).
    A claim whose window holds no periodic orbit, or no bifurcation, gets a row saying so.
    Cubic cases (3, 4) are continued only with ``cubic=True``: their transition matrices
    come from variational equations integrated in Python, minutes per window where the
    orbits are long; their rows say so otherwise.
    """
    from nsbench.periodic import trace
    from nsbench.problems import get_problem

    rows = []
    for c in claims.itertuples():
        lo_r, hi_r = ranges.get((c.case, c.sweep), (c.low, c.high))
        w = WINDOW * (hi_r - lo_r)
        start, stop = max(c.low - w, lo_r), min(c.high + w, hi_r)
        stated = 0.5 * (c.low + c.high)

        def problem_at(value, case=c.case, name=c.sweep):
            return get_problem("two-dof", case=case, **{name: float(value)})

        row = dict(
            case=c.case,
            sweep=c.sweep,
            paper_kind=c.kind,
            paper_value=f"{c.low:g}" if c.low == c.high else f"{c.low:g}-{c.high:g}",
            window=f"{start:.4g}..{stop:.4g}",
        )
        if not cubic and not problem_at(start).is_linear:
            row.update(
                located=0,
                branches=0,
                detail=f"not continued here (cubic springs, slow); run: nsbench continuation two-dof "
                f"--case {c.case} --sweep {c.sweep}={start:.4g}:{stop:.4g}",
            )
            rows.append(row)
            continue
        tic = time.perf_counter()
        try:
            result = trace(problem_at, c.sweep, start, stop, steps=steps, transient=transient)
        except Exception as exc:  # a failing continuation is a recorded row, never a lost report
            row.update(located=0, branches=0, detail=f"continuation failed: {type(exc).__name__}: {exc}")
            log(f"case {c.case} {c.sweep} ({row['paper_value']}): {row['detail']}")
            rows.append(row)
            continue
        row["seconds"] = round(time.perf_counter() - tic, 1)
        bifs = [b for b in result.bifurcations if b.category not in ("none", "unknown")]
        row.update(branches=len(result.branches), located=len(bifs))
        if bifs:
            values = np.array([b.value for b in bifs])
            outside = np.maximum(np.maximum(c.low - values, values - c.high), 0.0)
            b = bifs[int(np.lexsort((np.abs(values - stated), outside))[0])]
            row.update(
                continued_value=b.value,
                difference=0.0 if c.low <= b.value <= c.high else b.value - stated,
                continued_kind=b.kind,
                continued_category=b.category,
                same_category=b.category == c.kind,
                detail=b.detail,
            )
        else:
            why = "; ".join(sorted({g[1].split(":")[0] for g in result.gaps}))[:200]
            row["detail"] = "no bifurcation located in the window" + (
                f" (values without an orbit: {why})" if result.gaps else ""
            )
        log(
            f"case {c.case} {c.sweep} ({row['paper_value']}): "
            + (f"{row['continued_kind']} at {row['continued_value']:.10g}" if bifs else row["detail"])
            + f" [{row.get('seconds', 0):.0f} s]"
        )
        rows.append(row)
    frame = pd.DataFrame(rows)
    for col in COLUMNS:
        if col not in frame:
            frame[col] = np.nan
    return frame[COLUMNS]
