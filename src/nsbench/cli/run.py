"""``nsbench run``: the main job, a small benchmark report written to ``reports/latest``."""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
import pandas as pd

from nsbench.errors import UnsupportedProblemError

# (problem, case) pairs of the default job; linear ones have the exact reference.
DEFAULT_PROBLEMS = (("one-dof", 1), ("two-dof", 1), ("two-dof", 2))


def add_parser(sub) -> None:
    p = sub.add_parser("run", help="run the default benchmark and write a report (the main job)")
    p.add_argument("--out", default="reports/latest", help="output directory (default reports/latest)")
    p.add_argument("--t-end", type=float, default=300.0, help="time span (default 300)")
    p.set_defaults(handler=main)


def _compare(ref: pd.DataFrame, ev: pd.DataFrame) -> tuple[bool, float]:
    same = len(ref) == len(ev) and (ref["kind"].to_numpy() == ev["kind"].to_numpy()).all() \
        and (ref["block"].to_numpy() == ev["block"].to_numpy()).all()
    err = float(np.max(np.abs(ref["t"].to_numpy() - ev["t"].to_numpy()))) if same and len(ev) else np.nan
    return bool(same), err


def main(args: argparse.Namespace) -> int:
    from nsbench.engine import simulate
    from nsbench.integrators import list_integrators
    from nsbench.problems import get_problem
    from nsbench.provenance import provenance

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    rows = []
    names = list_integrators()
    for pname, case in DEFAULT_PROBLEMS:
        problem = get_problem(pname, case=case)
        reference = simulate(problem, "exact", args.t_end).events
        for name in names:
            tic = time.perf_counter()
            try:
                res = simulate(problem, name, args.t_end)
            except UnsupportedProblemError as exc:
                rows.append(dict(problem=pname, case=case, integrator=name, status="unsupported",
                                 message=str(exc)))
                continue
            same, err = _compare(reference, res.events)
            rows.append(dict(problem=pname, case=case, integrator=name, status=res.status.value,
                             message=res.message, same_sequence=same,
                             max_event_time_error=err, wall_time=res.wall_time,
                             setup_time=res.setup_time, **res.counters.as_dict()))
            print(f"{pname} case {case:<2} {name:<14} {res.status.value:<8} "
                  f"events {len(res.events):>4}  max |dt| {err:9.2e}  "
                  f"{time.perf_counter() - tic:7.3f} s", flush=True)
    table = pd.DataFrame(rows)
    table.to_csv(out / "results.csv", index=False)
    prov = provenance()
    lines = ["# nsbench report", "", f"Time span `tau` in [0, {args.t_end:g}], integrators at their "
             "default options, event times compared with `exact`.", ""]
    cols = ["problem", "case", "integrator", "status", "same_sequence", "n_events",
            "max_event_time_error", "wall_time", "nfev"]
    lines.append(table[[c for c in cols if c in table]].to_markdown(index=False)
                 if _has_tabulate() else table[[c for c in cols if c in table]].to_string(index=False))
    lines += ["", "## Provenance", ""] + [f"- {k}: {v}" for k, v in prov.items()]
    (out / "report.md").write_text("\n".join(lines) + "\n")
    print(f"report -> {out / 'report.md'}")
    return 0


def _has_tabulate() -> bool:
    try:
        import tabulate  # noqa: F401
    except ImportError:
        return False
    return True
