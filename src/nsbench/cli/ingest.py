"""``nsbench ingest FILE.json --out DIR``: a pytest-benchmark JSON file into the tidy schema."""

from __future__ import annotations

import argparse
import sys

from nsbench.errors import ConfigError


def add_parser(sub) -> None:
    p = sub.add_parser("ingest", help="load a pytest-benchmark JSON file as results (then 'nsbench report')")
    p.add_argument("file", metavar="FILE.json", help="written by pytest --benchmark-json=FILE.json")
    p.add_argument("--out", default=None, metavar="DIR", help="output directory (default: FILE without .json)")
    p.add_argument("--report", action="store_true", help="also write the report")
    p.set_defaults(handler=main)


def main(args: argparse.Namespace) -> int:
    from pathlib import Path

    from nsbench.bench.ingest import ingest, read_benchmark_json
    from nsbench.inputs import check_output_dir

    out = args.out or str(Path(args.file).with_suffix(""))
    read_benchmark_json(args.file)  # a missing, binary or malformed file is named before --out is checked
    check_output_dir(out, "--out")  # before resolve(): a symbolic-link loop is named, not raised
    if Path(out).resolve() == Path(args.file).resolve():
        raise ConfigError(f"--out {out} is the benchmark file itself; give --out DIR")
    from nsbench.bench.storage import done_ids

    held = len(done_ids(out))  # ingest replaces them: say how many, not silently
    frame = ingest(args.file, out)
    print(f"{len(frame)} benchmarks -> {Path(out) / 'results.parquet'} (and results.csv)")
    if held:
        print(
            f"nsbench: {out} held {held} stored case(s); ingest replaced them with the {len(frame)} of {args.file}",
            file=sys.stderr,
        )
    if args.report:
        from nsbench.bench.report import write_report

        print(f"report -> {write_report(out, frame).html}")
    return 0
