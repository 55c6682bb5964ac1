"""``nsbench ingest FILE.json --out DIR``: a pytest-benchmark JSON file into the tidy schema."""

from __future__ import annotations

import argparse


def add_parser(sub) -> None:
    p = sub.add_parser("ingest", help="load a pytest-benchmark JSON file as results (then 'nsbench report')")
    p.add_argument("file", metavar="FILE.json", help="written by pytest --benchmark-json=FILE.json")
    p.add_argument("--out", default=None, metavar="DIR", help="output directory (default: FILE without .json)")
    p.add_argument("--report", action="store_true", help="also write the report")
    p.set_defaults(handler=main)


def main(args: argparse.Namespace) -> int:
    from pathlib import Path

    from nsbench.bench.ingest import ingest

    out = args.out or str(Path(args.file).with_suffix(""))
    frame = ingest(args.file, out)
    print(f"{len(frame)} benchmarks -> {Path(out) / 'results.parquet'} (and results.csv)")
    if args.report:
        from nsbench.bench.report import write_report

        print(f"report -> {write_report(out, frame).html}")
    return 0
