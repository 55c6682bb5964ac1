"""Does ``nsbench compare`` raise false alarms, and does it catch a real slowdown? Measured, not asserted.

Runs one suite ``--runs`` times (identical code, each run a separate ``run_suite``
with its own worker processes, minutes apart), then:

- compares every run with the one before (``--runs - 1`` comparisons of identical
  code) and counts the flagged cases: there should be none;
- compares the planted integrators of every run (``planted-dop853``,
  ``planted-rk4``: ``benchmarks/_planted.py``) with their twice-the-work twins of
  the next run (``planted-dop853-2x``: every arc computed twice;
  ``planted-rk4-2x``: half the step), matched by problem and level, and counts
  the cases whose time is flagged ``slower``: every one should be.

The suite is the default suite's integrators and levels on 2-DOF case 2 (the
reference-grade ones and the slowest methods left out, so that a run takes a few
minutes on 2 cores), plus the planted four. ``--burn N`` starts N CPU-bound
processes for the whole measurement (a CI machine with other jobs); the load
average of every run is printed either way. Finished runs are kept under
``--out`` and reused by a rerun (delete the folder to start over).

    python benchmarks/compare_false_alarms.py --out /tmp/false-alarms --runs 21
"""

from __future__ import annotations

import argparse
import json
import multiprocessing
import os
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))  # _planted, importable by the workers too

import _planted  # noqa: E402
import pandas as pd  # noqa: E402

from nsbench import registry  # noqa: E402
from nsbench.bench import Suite, load_results, run_suite  # noqa: E402
from nsbench.bench.compare import compare_frames  # noqa: E402

LEFT_OUT = ["exact-mp", "reference", "scipy-radau", "scipy-bdf", "ida", "heyoka-q"]


def suite() -> Suite:
    import tomllib
    from importlib import resources

    data = tomllib.loads(resources.files("nsbench.suites").joinpath("default.toml").read_text())
    data.update(name="false-alarms", problems=[{"name": "two-dof", "case": 2}], bifurcation_targets=[])
    data["integrators"]["exclude"] = LEFT_OUT
    return Suite.from_dict(data)


def _burn() -> None:  # pragma: no cover - a busy loop
    x = 0
    while True:
        x = (x * 1103515245 + 12345) % 2147483648


def planted_pairs(a: pd.DataFrame, b: pd.DataFrame) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Run A's planted rows and run B's twice-the-work rows, the latter under the former's case ids."""
    left = a[a["integrator"].isin(list(_planted.PAIRS))]
    twins = {cls.name: name for name, cls in _planted.PAIRS.items()}
    right = b[b["integrator"].isin(list(twins))].copy()
    ids = {(r.problem_label, r.integrator, int(r.level)): r.case_id for r in left.itertuples()}
    right["case_id"] = [ids.get((r.problem_label, twins[r.integrator], int(r.level)), "") for r in right.itertuples()]
    return left, right[right["case_id"] != ""]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", required=True, help="folder for the runs and the summary")
    parser.add_argument("--runs", type=int, default=21, help="runs of the suite (comparisons: runs - 1)")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--burn", type=int, default=0, help="CPU-bound processes to start beside the runs")
    parser.add_argument("--factor", type=float, default=1.5)
    parser.add_argument("--confidence", type=float, default=0.99)
    args = parser.parse_args()
    for cls in _planted.ALL:
        registry.register("integrators", cls.name, cls)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    burners = [multiprocessing.Process(target=_burn, daemon=True) for _ in range(args.burn)]
    for p in burners:
        p.start()
    runs, loads = [], {}
    try:
        for i in range(args.runs):
            folder = out / f"run{i:02d}"
            if not (folder / "results.parquet").exists():
                tic = time.perf_counter()
                summary = run_suite(suite(), folder, workers=args.workers, progress=False, resume=False)
                print(
                    f"run {i}: {len(summary.results)} cases in {time.perf_counter() - tic:.0f} s, "
                    f"load average {os.getloadavg()[0]:.1f}",
                    flush=True,
                )
            runs.append(load_results(folder))
            prov = json.loads((folder / "provenance.json").read_text())
            loads[i] = prov.get("timing", {}).get("load", {})
    finally:
        for p in burners:
            p.terminate()
    rows = []
    for i in range(1, len(runs)):
        same = compare_frames(runs[i - 1], runs[i], args.factor, args.confidence)
        left, right = planted_pairs(runs[i - 1], runs[i])
        planted = compare_frames(left, right, args.factor, args.confidence)
        rows.append(
            {
                "comparison": f"run{i - 1:02d} -> run{i:02d}",
                "load_a": loads[i - 1].get("median"),
                "load_b": loads[i].get("median"),
                "identical_cases": len(same),
                "identical_flagged": int(same["flagged"].sum()),
                "identical_flags": "; ".join(
                    f"{r.integrator} {r.options} {r.flags} (x{r.time_ratio:.2f}, cpu x{r.cpu_ratio:.2f})"
                    for r in same[same["flagged"]].itertuples()
                ),
                "identical_load_verdicts": int((same["time_verdict"] == "load").sum()),
                "planted_cases": len(planted),
                "planted_slower": int((planted["time_verdict"] == "slower").sum()),
                "planted_missed": "; ".join(
                    f"{r.integrator} {r.options} {r.time_verdict} (x{r.time_ratio:.2f}, cpu x{r.cpu_ratio:.2f})"
                    for r in planted[planted["time_verdict"] != "slower"].itertuples()
                ),
                "planted_wall_ratio_median": float(planted["time_ratio"].median()),
                "planted_cpu_ratio_median": float(planted["cpu_ratio"].median()),
            }
        )
    table = pd.DataFrame(rows)
    table.to_csv(out / "summary.csv", index=False)
    with pd.option_context("display.width", 250, "display.max_colwidth", 80):
        print(table.drop(columns=["identical_flags", "planted_missed"]).to_string(index=False))
    for r in table.itertuples():
        if r.identical_flags or r.planted_missed:
            print(f"{r.comparison}: flagged {r.identical_flags or '-'}; planted missed {r.planted_missed or '-'}")
    print(
        f"identical code: {int(table['identical_flagged'].sum())} flagged in {len(table)} comparisons of "
        f"{int(table['identical_cases'].sum())} cases; planted 2x: {int(table['planted_slower'].sum())} of "
        f"{int(table['planted_cases'].sum())} flagged slower"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
