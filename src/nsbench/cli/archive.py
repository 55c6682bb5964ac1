"""``nsbench archive``: a results archive of runs from many machines, re-graded on arrival.

``add`` re-grades a results folder against the archive's own references and adds it (exit
status 1, nothing added, when a row's submitted errors disagree: the rows are named on stderr);
``show`` prints the archive's runs, its leaderboard per (problem, target) and its
bifurcation-target tables (as submitted, not re-graded); ``merge`` joins two or more archives
into one (``--to`` may be one of them), each run once; ``site`` writes the leaderboard, the
runtime distributions and the bifurcation-target tables as a static HTML page. Each action maps its
arguments onto one request of :mod:`nsbench.archive` (every value checked there) and calls one
app function.
"""

from __future__ import annotations

import argparse


def add_parser(sub) -> None:
    p = sub.add_parser("archive", help="keep runs of many machines in one archive, re-graded, with a leaderboard")
    actions = p.add_subparsers(dest="action", metavar="ACTION")
    actions.required = True

    a = actions.add_parser("add", help="re-grade a results folder and add it to an archive")
    a.add_argument("run", metavar="RUN", help="output folder of 'nsbench bench' or 'nsbench run'")
    a.add_argument("--to", required=True, metavar="ARCHIVE", help="the archive (made if absent or empty)")
    a.add_argument("--machine", default=None, help="machine name (default: the run's CPU and core count)")
    a.set_defaults(handler=add)

    s = actions.add_parser("show", help="the archive's runs and its leaderboard per problem and target")
    s.add_argument("archive", metavar="ARCHIVE", help="the archive")
    s.add_argument("--problem", default=None, help="only this problem label, e.g. one-dof/1")
    s.add_argument("--target", default=None, help="only this switching-time error target (default: 1e-4, 1e-8, 1e-12)")
    s.add_argument(
        "--every-configuration",
        action="store_true",
        help="bifurcation targets: list every configuration of every run (default: each method's cheapest that located it)",
    )
    s.set_defaults(handler=show)

    m = actions.add_parser("merge", help="join archives into one, each run once")
    m.add_argument("sources", metavar="ARCHIVE", nargs="+", help="two or more archives")
    m.add_argument("--to", required=True, metavar="ARCHIVE", help="the merged archive (may be one of the sources)")
    m.set_defaults(handler=merge)

    w = actions.add_parser("site", help="the leaderboard and runtime distributions as a static HTML page")
    w.add_argument("archive", metavar="ARCHIVE", help="the archive")
    w.add_argument("--out", required=True, metavar="DIR", help="folder for index.html and figures/ (made if absent)")
    w.set_defaults(handler=site)


def add(args: argparse.Namespace) -> int:
    from nsbench.archive.add import ArchiveAddRequest, add_to_archive

    return add_to_archive(ArchiveAddRequest(run=args.run, to=args.to, machine=args.machine)).exit_code


def show(args: argparse.Namespace) -> int:
    from nsbench.archive.show import ArchiveShowRequest, show_archive

    request = ArchiveShowRequest(
        archive=args.archive, problem=args.problem, target=args.target, every_configuration=args.every_configuration
    )
    return show_archive(request).exit_code


def merge(args: argparse.Namespace) -> int:
    from nsbench.archive.merge import ArchiveMergeRequest
    from nsbench.archive.merge import merge as merge_archives

    merge_archives(ArchiveMergeRequest(sources=tuple(args.sources), to=args.to))
    return 0


def site(args: argparse.Namespace) -> int:
    from nsbench.archive.site import ArchiveSiteRequest, build_site

    return build_site(ArchiveSiteRequest(archive=args.archive, out=args.out)).exit_code
