"""``nsbench list [integrators|problems|coverage]``: what is registered, whether it loads, and which
integrator runs which problem."""

from __future__ import annotations

import argparse

from nsbench import registry


def add_parser(sub) -> None:
    p = sub.add_parser(
        "list",
        help="list registered integrators and problems; 'coverage': which integrator runs which problem",
        description="Without KIND: the problems and the integrators. 'coverage': the matrix of which "
        "integrator runs which problem (each integrator's own refusals at its default options; nothing "
        "is integrated), then every refusal with its reason.",
    )
    p.add_argument("kind", nargs="?", choices=("integrators", "problems", "coverage"), default=None)
    p.add_argument(
        "--setup-limit",
        default=str(COVERAGE_SETUP_LIMIT),
        metavar="SECONDS",
        help="for 'coverage': hard limit of a plug-in problem's factory, built first in a supervised worker; "
        f"past it the problem's column says 'time limit' (default {COVERAGE_SETUP_LIMIT:g})",
    )
    p.set_defaults(handler=main)


#: A plug-in problem's factory at its defaults builds in well under a second; one that takes a minute
#: is looping, and the listing must end.
COVERAGE_SETUP_LIMIT = 60.0


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
    from nsbench.inputs import parse_real

    # checked whatever KIND is, so that a bad value is refused before anything is listed
    limit = parse_real(args.setup_limit, "--setup-limit", low=0.0, low_open=True, bound="MAX_TIME_LIMIT")
    if args.kind == "coverage":
        return _coverage(limit)
    kinds: list[registry.Kind] = [args.kind] if args.kind else ["problems", "integrators"]
    for kind in kinds:
        print(f"{kind}:")
        for entry, reason in registry.availability(kind):
            if reason is not None:
                print(f"  {entry.name:<16} UNAVAILABLE: {reason}")
                continue
            obj = registry.load(kind, entry.name)
            source = "" if entry.distribution in (None, "nsbench") else f"  [plug-in: {entry.distribution}]"
            if kind == "integrators":
                from nsbench.integrators.base import accepted_traits

                caps = obj.capabilities
                order = caps.order if caps.order is not None else "-"
                tags = (
                    f"family={caps.family}, events={caps.event_location}, order={order}, {stepping(caps)}, "
                    f"{caps.precision}"
                )
                accepts = accepted_traits(obj)
                if accepts is not None:
                    tags += f", problems with {' or '.join(accepts)}"
                if not caps.supports_nonlinear:
                    tags += ", linear problems only"
                if caps.reference_grade:
                    tags += ", reference-grade"
                print(f"  {entry.name:<16} {summary(obj)} ({tags}){source}")
            else:
                print(f"  {entry.name:<16} {summary(obj)}{source}")
    if not args.kind:
        print("which integrator runs which problem: nsbench list coverage")
    return 0


def _coverage(limit: float) -> int:
    """The coverage matrix; each plug-in problem is built first in a supervised worker (a factory that
    loops or raises costs its own column, with the reason, never the listing)."""
    from nsbench.factory_probe import is_plugin_problem, probe_problem
    from nsbench.coverage import coverage_matrix, text
    from nsbench.problems import list_problems

    unbuilt = {}
    for name in list_problems():
        if is_plugin_problem(name):
            fault = probe_problem(name, [{}], limit)
            if fault is not None:
                unbuilt[name] = fault
    print(text(coverage_matrix(unbuilt=unbuilt)))
    return 0
