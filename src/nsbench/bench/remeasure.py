"""Regenerating the packaged cost table (``suites/costs.json``) from a finished run: a maintainer's tool.

``python -m nsbench.bench.remeasure OUT SECONDS [--merge SUITE]`` measures the
tasks of the run in ``OUT`` (:func:`nsbench.bench.estimate.measure`), times the
writing of its report and writes the table the plan line reads. It sits above
the report, which the estimator itself never imports.
"""

from __future__ import annotations

import time
from pathlib import Path

from nsbench.bench import estimate


def main(argv: list[str] | None = None) -> int:  # pragma: no cover - a maintainer's tool
    import sys

    args = list(sys.argv[1:] if argv is None else argv)
    merge = None
    if "--merge" in args:  # --merge SUITE: add this run's tasks to the packaged table, with SUITE's own fixed costs
        k = args.index("--merge")
        merge = args[k + 1] if k + 1 < len(args) else ""
        del args[k : k + 2]
    if len(args) != 2 or merge == "":
        print(
            "usage: python -m nsbench.bench.remeasure OUT SECONDS [--merge SUITE]\n  OUT: the folder of a finished "
            "'nsbench run --suite full --fresh --workers 2' on an idle machine; SECONDS: its wall time "
            "without the report\n  --merge SUITE: OUT is a run of SUITE; its tasks are added to the packaged table "
            "and its overhead and report time kept as SUITE's own",
            file=sys.stderr,
        )
        return 2
    from nsbench.bench.report import write_report
    from nsbench.bench.storage import load_results

    table = estimate.measure(args[0], float(args[1]))
    tic = time.perf_counter()
    write_report(args[0], load_results(args[0]))
    table.report = round(time.perf_counter() - tic, 1)
    if merge:
        packaged = estimate.CostTable.packaged()
        if packaged is None:
            print("no packaged cost table to merge into: measure the full suite first", file=sys.stderr)
            return 2
        table = packaged.merged(table, merge)
    path = Path(estimate.__file__).resolve().parents[1] / "suites" / estimate.COSTS_FILE
    path.write_text(table.to_json() + "\n")
    overhead, report, _ = table.fixed(merge)
    print(
        f"{path}: {len(table.run)} cases, {len(table.target)} locations, calibration {table.calibration:.4f} s, "
        f"overhead {overhead} s, report {report} s" + (f" (suite {merge!r})" if merge else "")
    )
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
