"""``nsbench list [integrators|problems]``: what is registered, and whether it loads."""

from __future__ import annotations

import argparse

from nsbench import registry


def add_parser(sub) -> None:
    p = sub.add_parser("list", help="list registered integrators and problems")
    p.add_argument("kind", nargs="?", choices=("integrators", "problems"), default=None)
    p.set_defaults(handler=main)


def summary(obj) -> str:
    """The first paragraph of ``obj``'s docstring on one line, RST markup (````x````, `x`) as plain text."""
    import re

    doc = (getattr(obj, "__doc__", None) or "").strip()
    paragraph = doc.split("\n\n")[0] if doc else ""
    text = " ".join(line.strip() for line in paragraph.splitlines())
    return re.sub(r"`{1,2}([^`]+)`{1,2}", r"\1", text)


def stepping(caps) -> str:
    """``adaptive``, ``fixed-step`` (a step-size option) or ``no steps`` (a closed form)."""
    if caps.adaptive:
        return "adaptive"
    return "fixed-step" if caps.step_option == "h" else "closed form"


def main(args: argparse.Namespace) -> int:
    kinds = [args.kind] if args.kind else ["problems", "integrators"]
    for kind in kinds:
        print(f"{kind}:")
        for entry, reason in registry.availability(kind):
            if reason is not None:
                print(f"  {entry.name:<16} UNAVAILABLE: {reason}")
                continue
            obj = registry.load(kind, entry.name)
            source = "" if entry.distribution in (None, "nsbench") else f"  [plug-in: {entry.distribution}]"
            if kind == "integrators":
                caps = obj.capabilities
                order = caps.order if caps.order is not None else "-"
                tags = (
                    f"family={caps.family}, events={caps.event_location}, order={order}, {stepping(caps)}, "
                    f"{caps.precision}"
                )
                if not caps.supports_nonlinear:
                    tags += ", linear problems only"
                if caps.reference_grade:
                    tags += ", reference-grade"
                print(f"  {entry.name:<16} {summary(obj)} ({tags}){source}")
            else:
                print(f"  {entry.name:<16} {summary(obj)}{source}")
    return 0
