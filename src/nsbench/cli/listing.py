"""``nsbench list [integrators|problems]``: what is registered, and whether it loads."""

from __future__ import annotations

import argparse

from nsbench import registry


def add_parser(sub) -> None:
    p = sub.add_parser("list", help="list registered integrators and problems")
    p.add_argument("kind", nargs="?", choices=("integrators", "problems"), default=None)
    p.set_defaults(handler=main)


def _first_line(obj) -> str:
    doc = (getattr(obj, "__doc__", None) or "").strip()
    return doc.splitlines()[0] if doc else ""


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
                tags = f"events={caps.event_location}, order={order}, " \
                       f"{'adaptive' if caps.adaptive else 'fixed-step'}, {caps.precision}"
                if not caps.supports_nonlinear:
                    tags += ", linear problems only"
                print(f"  {entry.name:<16} {_first_line(obj)} ({tags}){source}")
            else:
                print(f"  {entry.name:<16} {_first_line(obj)}{source}")
    return 0
