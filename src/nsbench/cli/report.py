"""``nsbench report DIR``: report.md, a self-contained index.html, table.tex and figures."""

from __future__ import annotations

import argparse
from pathlib import Path

from nsbench.cli._common import add_report_formats
from nsbench.errors import ConfigError


def add_parser(sub) -> None:
    p = sub.add_parser("report", help="write the report of a results directory")
    p.add_argument("directory", metavar="DIR", help="output directory of 'nsbench bench', 'run' or 'ingest'")
    add_report_formats(p)
    p.set_defaults(handler=main)


def main(args: argparse.Namespace) -> int:
    from nsbench.bench.compare import read_results
    from nsbench.bench.report import write_report
    from nsbench.bench.figures import parse_formats
    from nsbench.inputs import check_output_dir

    formats = parse_formats(args.formats)
    if not Path(args.directory).is_dir():
        raise ConfigError(f"{args.directory!r} is not a directory")
    results = read_results(args.directory)  # another tool's folder or an empty one: one line, exit 2
    check_output_dir(args.directory, "the report into")
    if (Path(args.directory) / "figures").exists():
        check_output_dir(Path(args.directory) / "figures", "the report figures into")
    rep = write_report(args.directory, results, formats)
    print(f"report -> {rep.html}")
    print(f"          {rep.markdown}, {rep.latex}, {len(rep.figures)} figures ({', '.join(formats).upper()})")
    return 0
