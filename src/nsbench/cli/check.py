"""``nsbench check INTEGRATOR``: run the conformance kit on one integrator and print a pass/fail table."""

from __future__ import annotations

import argparse
import sys

from nsbench.cli._common import shared_params
from nsbench.inputs import parse_options, parse_real

#: Default hard limit of one check of a plug-in integrator, in seconds (``--time-limit``).
TIME_LIMIT = 600.0


def add_parser(sub) -> None:
    p = sub.add_parser("check", help="run the conformance kit on a registered integrator")
    p.add_argument("integrator", metavar="INTEGRATOR", help="registered integrator (built-in or plug-in)")
    p.add_argument(
        "--check", action="append", default=None, metavar="NAME", help="run only this check (repeatable); default: all"
    )
    p.add_argument("--option", action="append", default=[], metavar="NAME=VALUE", help="integrator option (repeatable)")
    p.add_argument(
        "--problem",
        default="two-dof",
        metavar="PROBLEM",
        help="registered problem the checks run on (default two-dof): the belt oscillators by their presets 1-4, any other as given",
    )
    p.add_argument("--n", default=None, help="number of blocks of a chain problem")
    p.add_argument(
        "--param",
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="parameter shared by every case of the problem (repeatable)",
    )
    p.add_argument(
        "--time-limit",
        default=f"{TIME_LIMIT:g}",
        metavar="SECONDS",
        help="hard limit of one check (and of the first call) of a plug-in integrator, which runs in a "
        "supervised worker: past it the worker is ended and the check fails with 'time limit' "
        f"(default {TIME_LIMIT:g}; built-in integrators run in this process)",
    )
    p.add_argument(
        "--setup-limit",
        default="1800",
        metavar="SECONDS",
        help="hard limit of a plug-in integrator's set-up in its worker, and of a plug-in problem's "
        "factory: past it the check (or the command) fails with 'time limit' (default 1800)",
    )
    p.set_defaults(handler=main)


def _one_line(text: str, width: int = 100) -> str:
    line = text.strip().splitlines()[0] if text.strip() else ""
    return line if len(line) <= width else line[: width - 3] + "..."


def _first_call(integ, problem, given) -> str:
    """The first-call flag's line (:func:`nsbench.testing.first_call_cost`); never fails the command."""
    from nsbench.testing import first_call_cost

    try:
        cost = first_call_cost(integ, problem, given)
    except Exception as exc:  # the checks below report what went wrong, with their own notes
        return f"first call: not measured ({type(exc).__name__}: {_one_line(str(exc), 120)})"
    return ("FLAG " if cost.flagged else "") + f"first call: {cost.message}"


def _first_call_line(first) -> str:
    """The first-call line of a supervised run: its times, or why they were not measured."""
    if isinstance(first, str):
        return f"first call: not measured ({_one_line(first, 160)})"
    return ("FLAG " if first.flagged else "") + f"first call: {first.message}"


def main(args: argparse.Namespace) -> int:
    from nsbench.factory_probe import probe_problem
    from nsbench.testing import check_integrator, configure, plan
    from nsbench.testing import checks_for
    from nsbench.testing import is_plugin

    time_limit = parse_real(args.time_limit, "--time-limit", low=0.0, low_open=True, bound="MAX_TIME_LIMIT")
    setup_limit = parse_real(args.setup_limit, "--setup-limit", low=0.0, low_open=True, bound="MAX_TIME_LIMIT")
    options = parse_options(args.option)
    integ, given = configure(args.integrator, options)  # an unknown option or a bad value: one line now
    selected = checks_for(integ, args.check)  # an unknown check: one line now
    problem = {"name": args.problem, **shared_params(args)}
    # a plug-in problem's factory is built first in a worker under the set-up limit: one that loops or
    # raises is one line here, not a hang or a traceback of this process
    fault = probe_problem(args.problem, [shared_params(args)], setup_limit)
    if fault is not None:
        print(f"nsbench: check: {fault}; no check was run", file=sys.stderr)
        return 1
    from nsbench.problems import get_problem

    get_problem(**problem)  # an unknown problem or a bad --n/--param: one line before anything runs
    print(f"conformance of {integ.name} {integ.settings} on {problem}")
    for line in plan(integ, given, args.check, problem):  # which configuration the accuracy checks run
        print(f"  {line}")
    if is_plugin(integ):
        # a plug-in runs in a supervised worker, one job per check: a loop or an os._exit costs its check,
        # not the command. Built-in integrators stay in this process: they are the project's own tested
        # code, and a worker would add its start and a second compile of their kernels to every check run.
        from nsbench.testing import supervised_checks

        first, results = supervised_checks(integ, given, selected, problem, time_limit, setup_limit)
        print(f"  {_first_call_line(first)}")
    else:
        # before the checks: the process's first use of the integrator (a later call is warm whatever setup does)
        print(f"  {_first_call(integ, problem, given)}")
        results = check_integrator(integ, args.check, problem=problem, options=given)
    width = max(len(r.check) for r in results)
    print(f"  {'check':<{width}}  {'status':<7}  {'seconds':>7}  note")
    for r in results:
        # a failure's note is its whole first line: it names the options the check ran with
        note = "" if r.status == "passed" else _one_line(r.message, 240 if r.status == "failed" else 100)
        print(f"  {r.check:<{width}}  {r.status.upper():<7}  {r.seconds:7.2f}  {note}".rstrip())
    counts = {s: sum(r.status == s for r in results) for s in ("passed", "failed", "skipped", "xfail", "xpass")}
    print(f"{len(results)} checks: " + ", ".join(f"{n} {s}" for s, n in counts.items() if n))
    if counts["failed"]:
        return 1
    running = [r for r in results if r.runs]
    if running and all(r.status == "skipped" for r in running):
        # a gate that checked nothing of the integrator's results must not pass in CI
        print(
            f"nothing applicable ran: each of the {len(running)} checks that run {integ.name} on "
            f"{args.problem} was skipped ({_one_line(running[0].message, 120)})"
        )
        return 1
    return 0
