"""Results across commits: one store keyed by machine, environment and commit; steps flagged like ``compare``.

A *history store* is a folder of finished runs::

    STORE/<machine>/<environment>/<commit>/<added>/results.parquet   the run's rows (the tidy schema)
                                                  /provenance.json   the run's provenance
                                                  /entry.json        machine, environment, commit, commit time, added

``machine`` is a name (the host's, unless given) with the CPU and core count in
``entry.json``; ``environment`` a short hash of the Python version and the
numerical stack's versions (numpy, scipy, pandas, heyoka, scikit-sundae, numba;
nsbench's own version is the commit's, so it is not part of it); ``commit`` the
commit of the package under study (nsbench's, or an integrator package's from
its repository). Runs of one machine and environment are compared in commit
order (commit time, then the time they were added), each with the one before
through :func:`nsbench.bench.compare.compare_frames`: the same statistics and
flags as ``nsbench compare``.

:func:`run_commits` runs a suite at every commit of a range of a git repository
(each in a temporary ``git worktree``, its sources first on ``PYTHONPATH``) and
adds each run to a store. asv's results database works the same way; its layout
keys benchmarks by Python function and keeps one number per benchmark, where a
row here also holds its configuration, counters and accuracy, so the store keeps
nsbench's own rows instead.
"""

from __future__ import annotations

import datetime as _dt
import hashlib
import json
import os
import platform
import shlex
import subprocess
import sys
import tempfile
from contextlib import contextmanager
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Any, Callable, Iterable

import pandas as pd

from nsbench.bench import storage
from nsbench.bench.compare import CONFIDENCE, FACTOR, compare_frames
from nsbench.bench.labels import configuration
from nsbench.errors import ConfigError

#: Versions that make an environment (nsbench's own is the commit's).
ENVIRONMENT_KEYS = (
    "python",
    "version_numpy",
    "version_scipy",
    "version_pandas",
    "version_heyoka",
    "version_scikit-sundae",
    "version_numba",
)
ENTRY_FILE = "entry.json"


@dataclass(frozen=True)
class Entry:
    """One run in a history store."""

    machine: str
    environment: str
    commit: str
    commit_time: str
    added: str
    path: str
    cpu: str = ""
    cores: int = 0
    versions: dict[str, Any] | None = None
    #: SHA-256 of the entry's files (``results.parquet``, ``provenance.json``), checked on every read:
    #: one entry's file copied over another's is refused, not read as the other commit's. ``None`` in an
    #: entry added before the store kept them (read unchecked).
    sha256: dict[str, str] | None = None

    @property
    def short(self) -> str:
        return self.commit[:10]


def _slug(text: str, what: str) -> str:
    if not str(text).strip():
        raise ConfigError(f"{what} expects a name, got {str(text)!r}")
    cleaned = "".join(c if c.isalnum() or c in "._+-" else "-" for c in str(text)).strip("-.") or "unknown"
    return storage.file_name(cleaned[:100], what)


def environment_of(provenance: dict[str, Any]) -> tuple[str, dict[str, Any]]:
    """``(name, versions)`` of a run's environment: ``py<version>-<hash of the versions>``."""
    versions = {k: provenance.get(k) for k in ENVIRONMENT_KEYS}
    digest = hashlib.sha1(json.dumps(versions, sort_keys=True).encode()).hexdigest()[:8]
    python = ".".join(str(versions.get("python") or "unknown").split(".")[:2])
    return f"py{python}-{digest}", versions


def _git(repo: Path, *args: str) -> str:
    from nsbench.provenance import SAFE_GIT

    env = {**os.environ, "GIT_OPTIONAL_LOCKS": "0"}
    env.pop("GIT_DIR", None)
    env.pop("GIT_WORK_TREE", None)
    try:
        done = subprocess.run([*SAFE_GIT, *args], cwd=repo, capture_output=True, text=True, timeout=60, env=env)
    except (OSError, subprocess.SubprocessError) as exc:
        raise ConfigError(f"git {' '.join(args)} in {str(repo)!r} failed: {exc}") from None
    if done.returncode != 0:
        reason = " ".join(done.stderr.split())[:300] or f"exit status {done.returncode}"
        raise ConfigError(f"git {' '.join(args)} in {str(repo)!r} failed: {reason}")
    return done.stdout.strip()


def commit_of(repo: str | Path) -> tuple[str, str]:
    """``(commit, commit time)`` of a git checkout's HEAD (``+dirty`` when its tracked files are modified)."""
    repo = Path(repo)
    if not repo.is_dir():
        raise ConfigError(f"--repo {str(repo)!r} is not a folder")
    sha = _git(repo, "rev-parse", "HEAD")
    dirty = _git(repo, "status", "--porcelain", "--untracked-files=no")
    return sha + ("+dirty" if dirty else ""), _git(repo, "show", "-s", "--format=%cI", sha)


def add(
    run: str | Path,
    store: str | Path,
    *,
    machine: str | None = None,
    commit: str | None = None,
    commit_time: str | None = None,
    repo: str | Path | None = None,
) -> Entry:
    """Copy a finished run (an ``nsbench run``/``bench`` output folder) into ``store``; its :class:`Entry`.

    The commit is ``commit`` if given, else the HEAD of ``repo``, else nsbench's
    commit in the run's provenance (``git_commit``). The run's rows are checked
    as ``nsbench compare`` checks them (a damaged case file is refused).
    """
    from nsbench.bench.compare import read_results

    run = Path(run)
    frame = read_results(run)
    prov = storage.read_provenance(run)
    if commit is None and repo is not None:
        commit, commit_time = commit_of(repo)
    commit = commit or prov.get("git_commit")
    if not commit:
        raise ConfigError(
            f"{str(run)!r} records no git commit (nsbench ran outside a checkout): give --commit SHA or --repo PATH"
        )
    environment, versions = environment_of(prov)
    name = _slug(machine or platform.node() or "machine", "machine name")
    added = _dt.datetime.now(_dt.timezone.utc).strftime("%Y%m%dT%H%M%S.%fZ")
    parts = (name, environment, _slug(commit, "commit"))
    from nsbench.files import refuse_links

    for depth, part in enumerate(parts):  # a linked machine, environment or commit folder could lead anywhere
        refuse_links(Path(store).joinpath(*parts[:depth]), (part,))
    folder = Path(store).joinpath(*parts) / added
    folder.mkdir(parents=True, exist_ok=False)
    entry = Entry(
        machine=name,
        environment=environment,
        commit=str(commit),
        commit_time=commit_time or str(prov.get("date", "")),
        added=added,
        path=str(folder),
        cpu=str(prov.get("cpu", "")),
        cores=int(prov.get("cpu_count") or 0),
        versions=versions,
    )
    storage.write_results(frame, folder / "results.parquet", prov)
    (folder / "provenance.json").write_text(json.dumps(prov, indent=1, default=str))
    entry = replace(entry, sha256={name: _digest(folder / name) for name in CHECKED_FILES})
    (folder / ENTRY_FILE).write_text(json.dumps({k: v for k, v in asdict(entry).items() if k != "path"}, indent=1))
    return entry


#: The files of an entry whose checksums its ``entry.json`` records.
CHECKED_FILES = ("results.parquet", "provenance.json")


def _digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def verify(entry: Entry) -> None:
    """``ConfigError`` naming the first file of ``entry`` whose content is not the one it was added with."""
    for name, wanted in (entry.sha256 or {}).items():
        path = Path(entry.path) / name
        try:
            got = _digest(path)
        except OSError as exc:
            raise ConfigError(f"{path} cannot be read ({exc.strerror or exc}); delete its entry's folder") from None
        if got != wanted:
            raise ConfigError(
                f"{path} is not the file this entry was added with (its checksum differs: copied from another "
                f"entry, or edited); delete {entry.path} and add the run of commit {entry.short} again"
            )


def entries(store: str | Path, machine: str | None = None, environment: str | None = None) -> list[Entry]:
    """The runs in ``store`` (of one machine and environment if given), in commit order."""
    root = Path(store)
    if not root.is_dir():
        raise ConfigError(f"history store {str(store)!r} does not exist (add a run with 'nsbench history add')")
    found = []
    for path in sorted(root.glob(f"*/*/*/*/{ENTRY_FILE}")):
        try:
            data = json.loads(path.read_text())
            entry = Entry(path=str(path.parent), **data)
        except (OSError, ValueError, TypeError) as exc:
            raise ConfigError(f"{path} is damaged ({type(exc).__name__}: {exc}); delete its folder") from None
        if (machine is None or entry.machine == machine) and (environment is None or entry.environment == environment):
            found.append(entry)
    return sorted(found, key=lambda e: (e.machine, e.environment, e.commit_time, e.added))


def load(entry: Entry) -> pd.DataFrame:
    """The rows of one stored run, its files checked against the checksums it was added with (:func:`verify`)."""
    verify(entry)
    return storage.load_results(Path(entry.path) / "results.parquet")


#: Columns of :func:`table`.
TABLE_COLUMNS = [
    "machine",
    "environment",
    "order",
    "commit",
    "commit_time",
    "problem",
    "integrator",
    "level",
    "options",
    "status",
    "wall_time",
    "wall_spread",
    "cpu_time",
    "nfev",
    "switch_err_max",
    "case_id",
]


def table(
    store: str | Path,
    machine: str | None = None,
    environment: str | None = None,
    problem: str | None = None,
    integrator: str | None = None,
) -> pd.DataFrame:
    """Long table: each (problem, integrator, level)'s cost and accuracy at each stored run, in commit order."""
    parts = []
    for (mach, env), runs in _loaded(store, machine, environment, problem, integrator).items():
        for order, (entry, rows) in enumerate(runs):
            parts.append(
                pd.DataFrame(
                    {
                        "machine": mach,
                        "environment": env,
                        "order": order,
                        "commit": entry.short,
                        "commit_time": entry.commit_time,
                        "problem": rows["problem_label"],
                        "integrator": rows["integrator"],
                        "level": rows["level"],
                        "options": rows["options"],
                        "status": rows["status"],
                        "wall_time": rows["wall_time"],
                        "wall_spread": rows["wall_spread"],
                        "cpu_time": rows["cpu_time"],
                        "nfev": rows["nfev"],
                        "switch_err_max": rows["switch_err_max"],
                        "case_id": rows["case_id"],
                    }
                )
            )
    return pd.concat(parts, ignore_index=True) if parts else pd.DataFrame(columns=TABLE_COLUMNS)


def _loaded(
    store: str | Path, machine: str | None, environment: str | None, problem: str | None, integrator: str | None
) -> dict[tuple[str, str], list[tuple[Entry, pd.DataFrame]]]:
    """The runs of each (machine, environment) in commit order with their rows, filtered; a filter that
    matches no stored row is refused with the values there are."""
    series = {key: [(e, load(e)) for e in runs] for key, runs in _series(entries(store, machine, environment)).items()}
    frames = [f for runs in series.values() for _, f in runs]
    for column, value, flag in (("problem_label", problem, "--problem"), ("integrator", integrator, "--integrator")):
        if value is None:
            continue
        known = sorted({str(v) for f in frames for v in f[column].unique()})
        if value not in known:
            raise ConfigError(f"{flag} {value!r} is in no stored run; stored: {', '.join(known)}")
        series = {key: [(e, f[f[column] == value]) for e, f in runs] for key, runs in series.items()}
    return series


def _series(found: Iterable[Entry]) -> dict[tuple[str, str], list[Entry]]:
    out: dict[tuple[str, str], list[Entry]] = {}
    for e in found:
        out.setdefault((e.machine, e.environment), []).append(e)
    return out


#: Columns of :func:`steps`.
STEP_COLUMNS = [
    "machine",
    "environment",
    "order",
    "commit",
    "previous",
    "problem",
    "integrator",
    "level",
    "options",
    "time_ratio",
    "time_low",
    "time_high",
    "cpu_ratio",
    "time_verdict",
    "nfev_ratio",
    "err_ratio",
    "flags",
    "case_id",
]


def steps(
    store: str | Path,
    machine: str | None = None,
    environment: str | None = None,
    problem: str | None = None,
    integrator: str | None = None,
    factor: float = FACTOR,
    confidence: float = CONFIDENCE,
) -> pd.DataFrame:
    """The flagged changes between consecutive runs of each machine and environment (``compare``'s statistics).

    One row per case flagged by :func:`nsbench.bench.compare.compare_frames`
    between a run and the one before it; ``commit`` is where the change appears.
    """
    rows = []
    for (mach, env), runs in _loaded(store, machine, environment, problem, integrator).items():
        before = None
        for order, (entry, frame) in enumerate(runs):
            if before is not None:
                diff = compare_frames(before[1], frame, factor, confidence)
                for r in diff[diff["flagged"]].itertuples():
                    rows.append(
                        {
                            "machine": mach,
                            "environment": env,
                            "order": order,
                            "commit": entry.short,
                            "previous": before[0].short,
                            "problem": r.problem,
                            "integrator": r.integrator,
                            "level": r.level,
                            "options": r.options,
                            "time_ratio": r.time_ratio,
                            "time_low": r.time_low,
                            "time_high": r.time_high,
                            "cpu_ratio": r.cpu_ratio,
                            "time_verdict": r.time_verdict,
                            "nfev_ratio": r.nfev_ratio,
                            "err_ratio": r.err_ratio,
                            "flags": r.flags,
                            "case_id": r.case_id,
                        }
                    )
            before = (entry, frame)
    return pd.DataFrame(rows, columns=STEP_COLUMNS)


# ---------------------------------------------------------------------- running a range of commits
def revisions(repo: str | Path, spec: str) -> list[str]:
    """The commits of ``spec`` in ``repo``, oldest first: a range ``A..B`` (B's ancestors not in A's, as
    git log), or commits separated by commas."""
    repo = Path(repo)
    if not repo.is_dir():
        raise ConfigError(f"--repo {str(repo)!r} is not a folder")
    if not spec.strip():
        raise ConfigError("--commits expects a range A..B or SHA,SHA,..., got ''")
    if ".." not in spec and "," not in spec:  # one name: a history of one commit is no range
        raise ConfigError(
            f"--commits {spec!r} is one commit, not a range A..B or a list SHA,SHA,...; "
            f"for that commit alone give {spec}~1..{spec}"
        )
    if ".." in spec:
        shas = _git(repo, "rev-list", "--reverse", "--topo-order", spec).split()
    else:
        shas = [_git(repo, "rev-parse", "--verify", f"{s.strip()}^{{commit}}") for s in spec.split(",") if s.strip()]
    if not shas:
        raise ConfigError(f"--commits {spec!r} names no commit in {str(repo)!r}")
    return shas


def run_commits(
    repo: str | Path,
    spec: str,
    store: str | Path,
    *,
    suite: str = "default",
    src: str | None = None,
    setup: str | None = None,
    machine: str | None = None,
    workers: int | None = None,
    keep: str | Path | None = None,
    stream=None,
    runner: Callable[[list[str], dict[str, str], Path], int] | None = None,
) -> list[Entry]:
    """Run ``suite`` at every commit of ``spec`` in ``repo`` and add each run to ``store``.

    Each commit is checked out in a temporary ``git worktree`` (the user's
    checkout is not touched); its ``src`` folder (default: ``src`` if the commit
    has one, else its root) goes first on ``PYTHONPATH``, so the commit's modules
    are imported instead of the installed ones (entry points come from the
    installed package: a plug-in registered only by a later commit is not seen).
    ``setup``, a command run in the worktree first (e.g. ``pip install --no-deps
    .`` for a package with compiled parts), installs the commit instead. The
    suite runs as ``python -m nsbench run --suite SUITE --fresh`` in a child
    process. A commit whose run fails is reported on ``stream`` and skipped; the
    others go on. ``keep`` keeps each run's folder there (``<keep>/<commit>``).
    """
    from nsbench.bench.suite import load_suite

    stream = stream or sys.stderr
    load_suite(suite)  # a bad suite is refused here, not once per commit in a child process
    repo = Path(repo).resolve()
    shas = revisions(repo, spec)
    run = runner or _run_suite
    added: list[Entry] = []
    clean_stale_runs(repo, stream)
    with _terminate_as_interrupt(), tempfile.TemporaryDirectory(prefix=f"{TEMP_PREFIX}{os.getpid()}-") as tmp:
        for i, sha in enumerate(shas, 1):
            tree = Path(tmp) / f"tree-{sha[:12]}"
            out = (Path(keep) / sha[:12]) if keep is not None else Path(tmp) / f"run-{sha[:12]}"
            print(f"nsbench: history: commit {sha[:12]} ({i} of {len(shas)})", file=stream, flush=True)
            _git(repo, "worktree", "add", "--detach", "--force", str(tree), sha)
            try:
                code = _at_commit(tree, out, suite, src, setup, workers, run)
                if code not in (0, 1):  # 1: the run finished with failures it records
                    print(
                        f"nsbench: history: commit {sha[:12]}: the run exited with status {code}; skipped", file=stream
                    )
                    continue
                when = _git(repo, "show", "-s", "--format=%cI", sha)
                added.append(add(out, store, machine=machine, commit=sha, commit_time=when))
            finally:
                _git(repo, "worktree", "remove", "--force", str(tree))
    return added


#: The temporary folders of ``history run`` are ``<tmp>/nsbench-history-<pid>-<random>``: the pid tells a
#: later run whether the one that made it is gone (killed) and its worktrees are to be removed.
TEMP_PREFIX = "nsbench-history-"


def clean_stale_runs(repo: Path, stream=None) -> list[Path]:
    """Remove what a killed ``history run`` left (:data:`TEMP_PREFIX` folders of processes that are gone, and
    the worktrees of ``repo`` registered in them); the removed folders.

    A run that ends in any other way (an error, Ctrl-C, SIGTERM) removes its own.
    """
    import shutil

    gone = []
    for folder in Path(tempfile.gettempdir()).glob(f"{TEMP_PREFIX}*-*"):
        pid = folder.name[len(TEMP_PREFIX) :].split("-", 1)[0]
        if not pid.isdigit() or not folder.is_dir() or _alive(int(pid)):
            continue
        shutil.rmtree(folder, ignore_errors=True)
        gone.append(folder)
    if gone:
        _git(repo, "worktree", "prune")  # the registrations of worktrees whose folders are gone
        if stream is not None:
            print(f"nsbench: history: removed {len(gone)} folder(s) left by a killed run: {gone[0]}", file=stream)
    return gone


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's process: alive
        return True
    return True


@contextmanager
def _terminate_as_interrupt():
    """SIGTERM ends the run as Ctrl-C does, through every ``finally`` (its worktrees removed), in the main thread."""
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def interrupt(signum, frame):
        raise KeyboardInterrupt

    previous = signal.signal(signal.SIGTERM, interrupt)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def _at_commit(
    tree: Path,
    out: Path,
    suite: str,
    src: str | None,
    setup: str | None,
    workers: int | None,
    run: Callable[[list[str], dict[str, str], Path], int],
) -> int:
    source = tree / (src if src is not None else ("src" if (tree / "src").is_dir() else "."))
    if not source.is_dir():
        raise ConfigError(f"--src {src!r} is not a folder of the commit's tree")
    env = {
        **os.environ,
        "PYTHONPATH": os.pathsep.join([str(source), os.environ.get("PYTHONPATH", "")]).rstrip(os.pathsep),
    }
    if setup:
        code = run(shlex.split(setup), env, tree)
        if code != 0:
            return code
    suite_arg = str(Path(suite).resolve()) if Path(suite).exists() else suite
    argv = [sys.executable, "-m", "nsbench", "run", "--suite", suite_arg, "--out", str(out), "--fresh"]
    if workers:
        argv += ["--workers", str(workers)]
    return run(argv, env, tree)


def _run_suite(argv: list[str], env: dict[str, str], cwd: Path) -> int:
    return subprocess.run(argv, env=env, cwd=cwd).returncode


# ---------------------------------------------------------------------- the figure
#: Line styles of an integrator's levels 0, 1, 2, 3 (then again) in the history figure.
LEVEL_LINES = ("-", "--", ":", "-.")


def figure(tab: pd.DataFrame, found: pd.DataFrame, out: str | Path, name: str = "history"):
    """Cost (median wall time) and accuracy (max switching-time error) of each (problem, integrator, level)
    against commit, one row of panels per problem; flagged steps circled in red. Saved as PNG, SVG, PDF."""
    import numpy as np

    from nsbench.bench.figures import ERROR_FLOOR, _styles, slug
    from nsbench.plotting import pyplot

    plt = pyplot()
    problems = sorted(tab["problem"].unique())
    styles = _styles(sorted(tab["integrator"].unique()))
    fig, axes = plt.subplots(len(problems), 2, figsize=(12, 3.2 * len(problems)), squeeze=False, sharex=True)
    commits = tab.drop_duplicates("order").sort_values("order")
    flags = dict(zip(zip(found["case_id"], found["order"]), found["flags"])) if len(found) else {}
    for (ax_t, ax_e), label in zip(axes, problems):
        rows = tab[tab["problem"] == label]
        for (integ, level), g in rows.groupby(["integrator", "level"], sort=True):
            g = g.sort_values("order")
            st = styles[integ]
            tag = configuration(integ, g["options"].iloc[0]) if "options" in g else f"{integ} level {level}"
            # an integrator's levels share its colour and marker: the line style tells them apart
            dash = LEVEL_LINES[int(level) % len(LEVEL_LINES)]
            ax_t.plot(g["order"], g["wall_time"], dash, marker=st["marker"], color=st["color"], ms=4, lw=1, label=tag)
            ax_e.plot(
                g["order"],
                np.maximum(g["switch_err_max"].astype(float), ERROR_FLOOR),
                dash,
                marker=st["marker"],
                color=st["color"],
                ms=4,
                lw=1,
            )
            marks = [flags.get((c, o), "") for c, o in zip(g["case_id"], g["order"])]
            cost = g[[("slower" in m or "more work" in m) for m in marks]]
            worse = g[[any(w in m for w in ("less accurate", "event sequence", "status")) for m in marks]]
            ax_t.plot(cost["order"], cost["wall_time"], "o", ms=12, mfc="none", mec="red", mew=1.5)
            ax_e.plot(
                worse["order"],
                np.maximum(worse["switch_err_max"].astype(float), ERROR_FLOOR),
                "o",
                ms=12,
                mfc="none",
                mec="red",
                mew=1.5,
            )
        for ax, ylabel in ((ax_t, "median wall time (s)"), (ax_e, "max switching-time error")):
            ax.set_yscale("log")
            ax.set_ylabel(ylabel)
            ax.set_title(label, fontsize=9)
            ax.grid(True, alpha=0.3)
    for ax in axes[-1]:
        ax.set_xticks(commits["order"].to_numpy(), commits["commit"].tolist(), rotation=45, ha="right", fontsize=7)
        ax.set_xlabel("commit (oldest first)")
    entries_: dict[str, Any] = {}
    for ax in axes[:, 0]:
        for handle, text in zip(*ax.get_legend_handles_labels()):
            entries_.setdefault(text, handle)
    if entries_:
        fig.legend(
            list(entries_.values()),
            list(entries_),
            loc="upper left",
            bbox_to_anchor=(1.0, 0.98),
            fontsize=6,
            frameon=False,
            ncol=1 + len(entries_) // 40,
        )
    fig.suptitle("Cost and accuracy over commits (red circles: a step flagged as by nsbench compare)")
    fig.tight_layout()
    caption = (
        "Median warm wall time (left) and max switching-time error (right) of each (problem, integrator, "
        "level) at each stored run of one machine and environment, oldest commit first; an integrator's levels "
        "share its colour and marker, level 0 solid, 1 dashed, 2 dotted, 3 dash-dot. A red circle marks a "
        "step flagged as nsbench compare flags it against the run before: on the left slower (the test on "
        "the samples and the factor) or more work (nfev), on the right less accurate, a broken event "
        "sequence or a lost success."
    )
    from nsbench.bench.figures import _save

    return _save(fig, Path(out), slug(name), "Cost and accuracy over commits", caption, ("png", "svg", "pdf"))
