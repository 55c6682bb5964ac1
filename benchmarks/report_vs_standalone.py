"""Do a report's timings match standalone runs? Re-times chosen cases of a results folder.

Each case is run alone, in a fresh process, the way a user would time it by
hand: ``nsbench.simulate`` with the row's problem, integrator, options and
span, one untimed run first (setup and first use), then ``--repeats`` warm
runs. This is done in ``--passes`` passes over all the chosen cases, so that a
case's runs are spread over minutes like the report's (a shared machine's
speed drifts); the median ``wall_time`` over all of them is compared with the
report's median as a ratio. Used for the measurement in docs/bench.md ("Timing
isolation"); not collected by pytest.

    python benchmarks/report_vs_standalone.py reports/latest \
        --problem one-dof/1 --integrator cvode-bdf --integrator cvode-adams --integrator scipy-radau
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys

import pandas as pd

_CHILD = r"""
import json, sys
import nsbench
spec = json.loads(sys.argv[1])
problem = nsbench.get_problem(spec["problem"]["name"], case=spec["problem"].get("case"),
                              dimensional=spec["problem"].get("dimensional", False),
                              **spec["problem"].get("params", {}))
opts = {k: v for k, v in spec["options"].items() if v is not None}
nsbench.simulate(problem, spec["integrator"], spec["t_end"], t0=spec["t0"], options=opts)  # untimed
times = [nsbench.simulate(problem, spec["integrator"], spec["t_end"], t0=spec["t0"], options=opts).wall_time
         for _ in range(spec["repeats"])]
print(json.dumps(times))
"""


def standalone_times(row: pd.Series, repeats: int) -> list[float]:
    """Warm ``wall_time`` of ``repeats`` standalone runs of a result row's case (fresh process)."""
    config = json.loads(row["integrator_config"])
    spec = {
        "problem": json.loads(row["problem_config"]),
        "integrator": config["name"],
        "options": config.get("options", {}),
        "t0": float(row["t0"]),
        "t_end": float(row["t_end"]),
        "repeats": repeats,
    }
    out = subprocess.run([sys.executable, "-c", _CHILD, json.dumps(spec)], capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("results", help="a results folder (holds results.parquet)")
    parser.add_argument("--problem", action="append", required=True, help="problem label, e.g. one-dof/1")
    parser.add_argument("--integrator", action="append", required=True)
    parser.add_argument("--repeats", type=int, default=3, help="warm runs per pass")
    parser.add_argument("--passes", type=int, default=3)
    args = parser.parse_args(argv)
    frame = pd.read_parquet(f"{args.results}/results.parquet")
    rows = frame[
        frame["problem_label"].isin(args.problem)
        & frame["integrator"].isin(args.integrator)
        & (frame["status"] == "success")
    ]
    print("| problem | integrator | options | report median (spread) | standalone median (spread) | ratio |")
    print("|---|---|---|---|---|---|")
    times: dict[int, list[float]] = {i: [] for i in rows.index}
    for _ in range(args.passes):
        for i, row in rows.iterrows():
            times[i] += standalone_times(row, args.repeats)
    ratios = []
    for i, row in rows.iterrows():
        med = statistics.median(times[i])
        spread = (max(times[i]) - min(times[i])) / 2 / med
        ratios.append(row["wall_time"] / med)
        options = {k: v for k, v in json.loads(row["options"]).items() if v is not None}
        print(
            f"| {row['problem_label']} | {row['integrator']} | {options} | {row['wall_time']:.4g} s "
            f"(±{100 * row['wall_spread'] / 2:.0f}%) | {med:.4g} s (±{100 * spread:.0f}%) | "
            f"{ratios[-1]:.2f} |",
            flush=True,
        )
    print(f"\nratios report / standalone: {min(ratios):.2f} .. {max(ratios):.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
