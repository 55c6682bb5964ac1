"""The ``nsbench`` command line: one module per sub-command.

Bad input (unknown problem, integrator or parameter, bad value) exits with
status 2 and one line on stderr, never a traceback.
"""

from __future__ import annotations

import argparse
import sys
from typing import Sequence

from nsbench.errors import NsbenchError

# Sub-command modules; each defines ``add_parser(subparsers)`` and ``main(args) -> int``.
COMMANDS = ("listing", "simulate", "check", "run", "bench", "report", "compare", "ingest",
            "bifurcation", "lyapunov", "paper")


def build_parser() -> argparse.ArgumentParser:
    import importlib

    parser = argparse.ArgumentParser(
        prog="nsbench",
        description="Compare time integrators on dry-friction (stick-slip) oscillators.",
    )
    from nsbench import __version__

    parser.add_argument("--version", action="version", version=f"nsbench {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    for name in COMMANDS:
        module = importlib.import_module(f"nsbench.cli.{name}")
        module.add_parser(sub)
    return parser


def fail(message: str) -> int:
    """Print one error line and return the bad-input exit status."""
    print(f"nsbench: error: {message}", file=sys.stderr)
    return 2


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``nsbench`` console script."""
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.handler(args) or 0)
    except NsbenchError as exc:
        return fail(str(exc))
    except KeyboardInterrupt:
        print("nsbench: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
