"""``nsbench compare A B``: per-case time, work and error ratios; flags a slowdown only when it exceeds a
factor and a test on both runs' samples says so at a stated confidence. Exit status 1 if anything is flagged."""

from __future__ import annotations

import argparse


def add_parser(sub) -> None:
    p = sub.add_parser("compare", help="compare two result directories (or Parquet/CSV files)")
    p.add_argument("a", metavar="A", help="baseline results")
    p.add_argument("b", metavar="B", help="new results")
    p.add_argument("--factor", default="1.5", help="smallest ratio that counts as a change (default 1.5)")
    p.add_argument(
        "--confidence",
        default="0.99",
        help="confidence of a flagged time change: the one-sided Mann-Whitney test on the two runs' "
        "samples at 1 - confidence (default 0.99)",
    )
    p.add_argument("--all", action="store_true", help="list every common case, not only the changes")
    p.add_argument("--out", default=None, metavar="FILE.csv", help="write the full comparison table")
    p.set_defaults(handler=main)


def main(args: argparse.Namespace) -> int:
    from nsbench.bench.compare import compare
    from nsbench.bench.report import markdown_table
    from nsbench.inputs import check_output_file, parse_number
    from nsbench.errors import ConfigError

    factor = parse_number(args.factor, "--factor")  # its range (finite, > 1) is checked by compare
    confidence = parse_number(args.confidence, "--confidence")  # in [0.5, 1): checked by compare
    if args.out:
        check_output_file(args.out, "--out")
    table, counts = compare(args.a, args.b, factor, confidence)
    if counts["common"] == 0:
        raise ConfigError(
            f"no common cases: {args.a} and {args.b} share no case id ({counts['only_a']} cases "
            f"only in A, {counts['only_b']} only in B); compare runs of the same suite"
        )
    print(
        f"{counts['common']} common cases ({counts['only_a']} only in A, {counts['only_b']} only in B); "
        f"factor {factor:g}, confidence {confidence:g}; {counts['flagged']} flagged"
    )
    quiet = ("same", "n/a")
    changed = (
        table["flagged"]
        | ~table["time_verdict"].isin(quiet)
        | ~table["err_verdict"].isin(quiet)
        | ~table["nfev_verdict"].isin(quiet)
    )
    view = table if args.all else table[changed]
    if len(view):
        view = view.assign(
            time_interval=[
                f"[{lo:.3g}, {hi:.3g}]" if lo == lo else "" for lo, hi in zip(view["time_low"], view["time_high"])
            ]
        )
        cols = [
            "problem",
            "integrator",
            "options",
            "time_ratio",
            "time_interval",
            "time_p",
            "cpu_ratio",
            "time_verdict",
            "nfev_ratio",
            "err_ratio",
            "err_verdict",
            "status_b",
            "flags",
        ]
        print(markdown_table(view[cols]))
    if args.out:
        table.to_csv(args.out, index=False)
        print(f"comparison -> {args.out}")
    return 1 if counts["flagged"] else 0
