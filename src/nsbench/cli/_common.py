"""Argument helpers shared by sub-commands."""

from __future__ import annotations

import argparse
from typing import Any

from nsbench.errors import ConfigError


def parse_assignment(text: str, flag: str) -> tuple[str, str]:
    """Split ``NAME=VALUE``; raise a ``ConfigError`` naming ``flag`` otherwise."""
    name, sep, value = text.partition("=")
    if not sep or not name.strip() or not value.strip():
        raise ConfigError(f"{flag} expects NAME=VALUE, got {text!r}")
    return name.strip(), value.strip()


def parse_number(text: str, what: str) -> float:
    """A float (range checks are the consumer's), or a ``ConfigError`` naming ``what``."""
    try:
        return float(text)
    except ValueError:
        raise ConfigError(f"{what} = {text!r} is not a number") from None


def parse_value(text: str) -> Any:
    """An option value: int, float, bool, None or string, in that order."""
    low = text.lower()
    if low in ("true", "false"):
        return low == "true"
    if low in ("none", "null"):
        return None
    for kind in (int, float):
        try:
            return kind(text)
        except ValueError:
            pass
    return text


def add_problem_arguments(p: argparse.ArgumentParser) -> None:
    """PROBLEM, --case, --param, --dimensional."""
    p.add_argument("problem", metavar="PROBLEM", help="registered problem, e.g. one-dof or two-dof")
    p.add_argument("--case", default=None, help="preset 1..4 (default 1)")
    p.add_argument("--param", action="append", default=[], metavar="NAME=VALUE",
                   help="parameter override (repeatable); dimensionless names unless --dimensional")
    p.add_argument("--n", default=None, help="number of blocks of a chain problem (same as --param n=N)")
    p.add_argument("--dimensional", action="store_true",
                   help="parameters, integration and outputs in dimensional units")


def shared_params(args: argparse.Namespace) -> dict[str, float]:
    """``--param NAME=VALUE`` (repeatable) and ``--n N`` as problem parameters."""
    params: dict[str, float] = {}
    for text in args.param:
        name, value = parse_assignment(text, "--param")
        params[name] = parse_number(value, f"parameter {name}")
    if getattr(args, "n", None) is not None:
        if "n" in params:
            raise ConfigError("give the number of blocks once: --n or --param n=..., not both")
        params["n"] = parse_number(args.n, "--n")
    return params


def problem_from_args(args: argparse.Namespace):
    from nsbench.problems import get_problem

    return get_problem(args.problem, case=args.case, dimensional=args.dimensional, **shared_params(args))
