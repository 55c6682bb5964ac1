"""``nsbench history``: runs kept across commits in one store, keyed by machine, environment and commit.

``add`` copies a finished run into the store; ``show`` prints each run of a
machine and environment in commit order and the steps flagged between
consecutive runs (the statistics of ``nsbench compare``), and writes the long
table, the steps and a figure; ``run`` runs a suite at every commit of a range
of a git repository and adds each run. Exit status 1 from ``show --check`` when
the newest run has a flagged step.
"""

from __future__ import annotations

import argparse


def add_parser(sub) -> None:
    p = sub.add_parser("history", help="keep runs across commits and find where cost or accuracy changed")
    actions = p.add_subparsers(dest="action", metavar="ACTION")
    actions.required = True

    a = actions.add_parser("add", help="copy a finished run into a history store")
    a.add_argument("run", metavar="RUN", help="output folder of 'nsbench run' or 'nsbench bench'")
    _store(a)
    a.add_argument(
        "--commit",
        default=None,
        help="the commit the run measured (default: --repo's HEAD, else nsbench's commit in the run's provenance)",
    )
    a.add_argument("--repo", default=None, help="git checkout of the package under study (its HEAD is the commit)")
    a.add_argument("--machine", default=None, help="machine name (default: this host's name)")
    a.set_defaults(handler=add)

    s = actions.add_parser("show", help="cost and accuracy over commits, and the flagged steps")
    _store(s)
    s.add_argument("--machine", default=None, help="only this machine's runs")
    s.add_argument("--environment", default=None, help="only this environment's runs (see the listing)")
    s.add_argument("--problem", default=None, help="only this problem label, e.g. two-dof/2")
    s.add_argument("--integrator", default=None, help="only this integrator")
    s.add_argument("--factor", default="1.5", help="smallest ratio that counts as a change (default 1.5)")
    s.add_argument("--confidence", default="0.99", help="confidence of a flagged time change (default 0.99)")
    s.add_argument("--out", default=None, help="write history.csv, steps.csv and the figure here")
    s.add_argument("--check", action="store_true", help="exit 1 when the newest run has a flagged step (CI)")
    s.set_defaults(handler=show)

    r = actions.add_parser("run", help="run a suite at every commit of a range and add each run to the store")
    r.add_argument("--repo", required=True, help="git repository of the package under study")
    r.add_argument(
        "--commits",
        required=True,
        metavar="A..B",
        help="a range A..B (B's ancestors that are not A's, oldest first) or SHA,SHA,...; one commit alone: SHA~1..SHA",
    )
    _store(r)
    r.add_argument("--suite", default="default", help="packaged suite name or suite TOML (default: default)")
    r.add_argument(
        "--src",
        default=None,
        help="folder of the commit's tree put first on PYTHONPATH (default: src if it exists, else the tree's root)",
    )
    r.add_argument(
        "--setup",
        default=None,
        help="command run in each commit's tree first, e.g. 'pip install --no-deps .' for compiled packages",
    )
    r.add_argument("--machine", default=None, help="machine name (default: this host's name)")
    r.add_argument("--workers", default=None, help="processes per run (default: all cores)")
    r.add_argument("--keep", default=None, help="keep each run's folder here, as <keep>/<commit>")
    r.set_defaults(handler=run)


def _store(p: argparse.ArgumentParser) -> None:
    p.add_argument("--store", default="nsbench-history", help="the history store (default: ./nsbench-history)")


def add(args: argparse.Namespace) -> int:
    from nsbench.bench import history
    from nsbench.inputs import check_output_dir

    check_output_dir(args.store, "--store")
    entry = history.add(args.run, args.store, machine=args.machine, commit=args.commit, repo=args.repo)
    print(
        f"added {args.run} as machine {entry.machine}, environment {entry.environment}, commit {entry.short} "
        f"-> {entry.path}"
    )
    return 0


def show(args: argparse.Namespace) -> int:
    from nsbench.bench.history_show import HistoryShowRequest, show_history

    request = HistoryShowRequest(
        store=args.store,
        machine=args.machine,
        environment=args.environment,
        problem=args.problem,
        integrator=args.integrator,
        factor=args.factor,
        confidence=args.confidence,
        out=args.out,
        check=args.check,
    )
    return show_history(request).exit_code


def run(args: argparse.Namespace) -> int:
    from nsbench.bench import history
    from nsbench.inputs import check_output_dir, parse_count

    check_output_dir(args.store, "--store")
    if args.keep:
        check_output_dir(args.keep, "--keep")
    workers = parse_count(str(args.workers), "--workers", low=1, bound="MAX_WORKERS") if args.workers else None
    added = history.run_commits(
        args.repo,
        args.commits,
        args.store,
        suite=args.suite,
        src=args.src,
        setup=args.setup,
        machine=args.machine,
        workers=workers,
        keep=args.keep,
    )
    print(f"{len(added)} run(s) added to {args.store}: " + ", ".join(e.short for e in added))
    return 0 if added else 1
