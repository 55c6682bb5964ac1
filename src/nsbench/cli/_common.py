"""Argument helpers shared by sub-commands: the problem's arguments and the report formats.

The values themselves are parsed and checked in :mod:`nsbench.inputs` (counts, reals, options,
output paths, figure paths), where the apps' requests check theirs too. Each check raises a
:class:`~nsbench.errors.ConfigError` whose message names the option, the bad value and what is
allowed; ``nsbench.cli.main`` prints it as one line and exits with status 2.
"""

from __future__ import annotations

import argparse
from typing import Any

from nsbench.errors import ConfigError
from nsbench.inputs import parse_assignment, parse_number


def add_problem_arguments(p: argparse.ArgumentParser) -> None:
    """PROBLEM, --case, --param, --dimensional."""
    p.add_argument("problem", metavar="PROBLEM", help="registered problem, e.g. one-dof or two-dof")
    p.add_argument("--case", default=None, help="preset 1..4 (default 1); one-dof also 'leine'")
    p.add_argument(
        "--param",
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="parameter override (repeatable); dimensionless names unless --dimensional; "
        "law=coulomb|weakening|stribeck picks the friction law",
    )
    p.add_argument("--n", default=None, help="number of blocks of a chain problem (same as --param n=N)")
    p.add_argument(
        "--dimensional", action="store_true", help="parameters, integration and outputs in dimensional units"
    )


def shared_params(args: argparse.Namespace) -> dict[str, Any]:
    """``--param NAME=VALUE`` (repeatable) and ``--n N`` as problem parameters (``law`` and ``case`` stay text)."""
    params: dict[str, Any] = {}
    for text in args.param:
        name, value = parse_assignment(text, "--param")
        if name in params:
            raise ConfigError(f"--param {name} is given twice ({name}={params[name]!r} and {text!r}); give it once")
        # a command with --case (simulate, bifurcation, ...) takes the preset there: --param case= would reach
        # get_problem twice; `nsbench check` has no --case and takes the preset as --param case=N|NAME
        if name == "dimensional" or (name == "case" and hasattr(args, "case")):
            hint = (
                "give --case instead" if name == "case" else "commands that take dimensional values have --dimensional"
            )
            raise ConfigError(f"--param {text}: {name} is not a parameter; {hint}")
        # the friction law is a name (coulomb, weakening, stribeck) and a preset a number or a name
        # (one-dof's 'leine'); every other parameter is a number
        params[name] = value.strip() if name in ("law", "case") else parse_number(value, f"parameter {name}")
    if getattr(args, "n", None) is not None:
        if "n" in params:
            raise ConfigError("give the number of blocks once: --n or --param n=..., not both")
        params["n"] = parse_number(args.n, "--n")
    return params


def add_factory_limit(p) -> None:
    """The ``--setup-limit`` of a command that builds its problem in its own process (simulate, lyapunov)."""
    p.add_argument(
        "--setup-limit",
        default="1800",
        metavar="SECONDS",
        help="hard limit of a plug-in problem's factory, which is built first in a worker: past it, or if "
        "the factory crashes or raises, the command says so in one line and exits 1 (default 1800)",
    )


def add_report_formats(p) -> None:
    """The ``--formats`` option of a command that writes a benchmark report."""
    p.add_argument(
        "--formats",
        default="png",
        metavar="LIST",
        help="the report figures' formats, comma-separated from png, svg, pdf (default png; png is always "
        "written, the HTML page embeds it; svg for the web, pdf for a LaTeX paper)",
    )
