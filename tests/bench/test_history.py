"""history: runs stored by machine, environment and commit; a planted change is found at its commit.

The statistics are checked on planted samples (no clock); the run over the commits
of a git repository is checked end to end on counted work (nfev), which does not
depend on the machine's speed.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import pandas as pd
import pytest

from nsbench.bench import history, storage
from nsbench.bench.storage import to_frame
from nsbench.cli import main

PROV = {
    "python": "3.11.7",
    "version_numpy": "2.4.6",
    "version_scipy": "1.17.1",
    "cpu": "Planted CPU",
    "cpu_count": 2,
    "date": "2026-11-25T10:00:00+00:00",
}
A = [0.100, 0.104, 0.098, 0.110, 0.101]  # five samples (seconds per run)


def _row(integrator: str, slow: float = 1.0, err: float = 1e-9) -> dict:
    return {
        "case_id": f"two-dof-2-{integrator}",
        "problem_label": "two-dof/2",
        "integrator": integrator,
        "level": 0,
        "options": "{}",
        "status": "success",
        "sequence_ok": True,
        "switch_err_max": err,
        "nfev": 1000,
        "wall_times": [slow * t for t in A],
        "cpu_times": [slow * 0.95 * t for t in A],
        "wall_time": slow * 0.101,
        "wall_time_min": slow * 0.098,
        "wall_time_max": slow * 0.110,
        "wall_spread": 0.12,
        "cpu_time": slow * 0.096,
    }


def _run(folder: Path, rows: list[dict], prov: dict = PROV) -> Path:
    folder.mkdir(parents=True)
    storage.write_results(to_frame(rows), folder / "results.parquet", prov)
    (folder / "provenance.json").write_text(json.dumps(prov))
    return folder


@pytest.fixture
def store(tmp_path):
    """Three commits: b gets twice as slow at c2 (every sample, on both clocks); a's error
    grows 10-fold at c3."""
    out = tmp_path / "store"
    runs = [
        ("c1" * 20, [_row("a"), _row("b")]),
        ("c2" * 20, [_row("a"), _row("b", slow=2.0)]),
        ("c3" * 20, [_row("a", err=1e-8), _row("b", slow=2.0)]),
    ]
    for i, (commit, rows) in enumerate(runs):
        history.add(
            _run(tmp_path / f"run{i}", rows),
            out,
            machine="box",
            commit=commit,
            commit_time=f"2026-11-2{i + 1}T10:00:00+00:00",
        )
    return out


def test_runs_are_keyed_by_machine_environment_and_commit(store):
    found = history.entries(store)
    assert [e.commit[:2] for e in found] == ["c1", "c2", "c3"]
    name, versions = history.environment_of(PROV)
    assert {e.environment for e in found} == {name} and name.startswith("py3.11-")
    assert versions["version_numpy"] == "2.4.6" and {e.machine for e in found} == {"box"}
    path = Path(found[1].path)
    assert path.parts[-4:-1] == ("box", name, "c2" * 20) and (path / "results.parquet").exists()
    # another environment (numpy upgraded) is another series, never compared with this one
    assert history.environment_of({**PROV, "version_numpy": "2.5.0"})[0] != name


def test_the_planted_change_is_found_at_its_commit(store):
    tab = history.table(store)
    assert len(tab) == 6 and list(tab.drop_duplicates("order")["commit"]) == ["c1c1c1c1c1", "c2c2c2c2c2", "c3c3c3c3c3"]
    found = history.steps(store).set_index(["commit", "integrator"])
    assert list(found.index) == [("c2c2c2c2c2", "b"), ("c3c3c3c3c3", "a")]
    assert found.loc[("c2c2c2c2c2", "b"), "flags"] == "slower"
    assert found.loc[("c2c2c2c2c2", "b"), "cpu_ratio"] == pytest.approx(2.0)
    assert found.loc[("c3c3c3c3c3", "a"), "flags"] == "less accurate"
    assert found.loc[("c2c2c2c2c2", "b"), "previous"] == "c1c1c1c1c1"


def test_show_writes_the_table_steps_and_figure_and_checks_the_newest(store, tmp_path, capsys):
    out = tmp_path / "shown"
    assert main(["history", "show", "--store", str(store), "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "2 flagged step(s)" in text and "c2c2c2c2c2" in text
    assert len(pd.read_csv(out / "history.csv")) == 6 and len(pd.read_csv(out / "steps.csv")) == 2
    assert (out / "history.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    # b has two levels in the store below: level 1 is drawn dashed, so the two lines can be told apart
    levels = [dict(r, case_id=r["case_id"] + "-1", level=1) for r in (_row("b"),)]
    two = tmp_path / "two"
    history.add(_run(tmp_path / "lv", [_row("b"), *levels]), two, machine="box", commit="d1" * 20)
    history.add(_run(tmp_path / "lv2", [_row("b"), *levels]), two, machine="box", commit="d2" * 20)
    assert main(["history", "show", "--store", str(two), "--out", str(tmp_path / "two-out")]) == 0
    assert "stroke-dasharray" in (tmp_path / "two-out" / "history.svg").read_text()
    assert "stroke-dasharray" not in (out / "history.svg").read_text()  # one level each: solid lines
    # the newest run (c3) has a flagged step: --check fails the job; restricted to b, its step is older
    assert main(["history", "show", "--store", str(store), "--check"]) == 1
    assert main(["history", "show", "--store", str(store), "--check", "--integrator", "b"]) == 0


@pytest.mark.parametrize(
    "argv, message",
    [
        (["history", "show", "--store", "{d}/none"], "does not exist"),
        (["history", "show", "--store", "{d}/store", "--confidence", "1"], "confidence = 1.0 must be"),
        (["history", "show", "--store", "{d}/store", "--factor", "nan"], "factor = nan"),
        (["history", "add", "{d}/none", "--store", "{d}/store"], "do not exist"),
        (["history", "run", "--repo", "{d}/none", "--commits", "a..b", "--store", "{d}/s"], "is not a folder"),
    ],
)
def test_bad_input_is_one_line(store, argv, message, capsys):
    d = str(Path(store).parent)
    assert main([a.replace("{d}", d) for a in argv]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and message in err[0]


PLUGIN = '''\
"""A plug-in integrator whose work per arc is WORK times the plain one's."""
import dataclasses

from nsbench.integrators.scipy_ import ScipyRK45

WORK = {work}


class Planted(ScipyRK45):
    name = "plant-rk45"
    accuracy_levels = ({{"rtol": 1e-6, "atol": 1e-8}},)

    def advance(self, request):
        out = super().advance(request)
        for _ in range(WORK - 1):  # the same arc again: more work, counted, same result
            more = super().advance(request)
            out = dataclasses.replace(more, nfev=out.nfev + more.nfev, nsteps=out.nsteps + more.nsteps)
        return out
'''

SUITE = """
name = "plant"
t_span = [0.0, 20.0]
repeats = 3
max_repeats = 3
min_sample_time = 0.01
reference = ["exact"]
[[problems]]
name = "one-dof"
case = 1
[integrators]
only = ["plant-rk45"]
"""


def _git(repo: Path, *args: str) -> str:
    return subprocess.run(
        ["git", "-c", "user.name=t", "-c", "user.email=t@t", *args],
        cwd=repo,
        check=True,
        capture_output=True,
        text=True,
    ).stdout.strip()


def test_history_run_over_three_commits_finds_the_commit_that_doubled_the_work(tmp_path):
    if shutil.which("git") is None:
        pytest.skip("git is not installed")
    repo = tmp_path / "plantpkg"
    (repo / "src" / "plantpkg-0.1.dist-info").mkdir(parents=True)
    # the package's metadata travels with its source, so the commit's tree registers the entry point
    (repo / "src" / "plantpkg-0.1.dist-info" / "METADATA").write_text(
        "Metadata-Version: 2.1\nName: plantpkg\nVersion: 0.1\n"
    )
    (repo / "src" / "plantpkg-0.1.dist-info" / "entry_points.txt").write_text(
        "[nsbench.integrators]\nplant-rk45 = plantpkg:Planted\n"
    )
    _git(repo, "init", "-q")
    shas = []
    for work, note in ((1, ""), (2, ""), (2, "# unchanged work\n")):
        (repo / "src" / "plantpkg").mkdir(exist_ok=True)
        (repo / "src" / "plantpkg" / "__init__.py").write_text(textwrap.dedent(PLUGIN.format(work=work)) + note)
        _git(repo, "add", "-A")
        _git(repo, "commit", "-q", "-m", f"work {work}")
        shas.append(_git(repo, "rev-parse", "HEAD"))
    suite = tmp_path / "plant.toml"
    suite.write_text(SUITE)
    store = tmp_path / "store"
    log = []
    added = history.run_commits(
        repo,
        ",".join(shas),
        store,
        suite=str(suite),
        machine="box",
        workers=1,
        runner=lambda argv, env, cwd: (
            log.append(argv) or subprocess.run(argv, env=env, cwd=cwd, capture_output=True).returncode
        ),
    )
    assert [e.commit for e in added] == shas and len(log) == 3
    assert _git(repo, "worktree", "list").count("\n") == 0  # every temporary worktree removed
    tab = history.table(store)
    assert list(tab.sort_values("order")["nfev"] / tab["nfev"].min()) == [1, 2, 2]
    found = history.steps(store)
    more = found[found["flags"].str.contains("more work")]
    assert list(more["commit"]) == [shas[1][:10]] and more["nfev_ratio"].iloc[0] == pytest.approx(2.0)
    # 3 samples a side can never reach 99 % (p >= 1/20): no time flag anywhere, whatever the machine did
    assert not found["flags"].str.contains("slower").any()
    assert not found["commit"].eq(shas[2][:10]).any()  # nothing changed at the third commit


def test_a_range_lists_commits_oldest_first(tmp_path):
    if shutil.which("git") is None:
        pytest.skip("git is not installed")
    repo = tmp_path / "r"
    repo.mkdir()
    _git(repo, "init", "-q")
    shas = []
    for i in range(3):
        (repo / "f").write_text(str(i))
        _git(repo, "add", "f")
        _git(repo, "commit", "-q", "-m", str(i))
        shas.append(_git(repo, "rev-parse", "HEAD"))
    assert history.revisions(repo, f"{shas[0]}..{shas[2]}") == shas[1:]
    assert history.revisions(repo, f"{shas[2]},{shas[0]}") == [shas[2], shas[0]]
    from nsbench.errors import ConfigError

    with pytest.raises(ConfigError, match="names no commit"):
        history.revisions(repo, f"{shas[2]}..{shas[2]}")
    # one name is no range (issue 52: the help asks for A..B; HEAD alone ran as a list of one);
    # the range the message proposes runs that commit alone
    with pytest.raises(ConfigError, match=r"--commits 'HEAD' is one commit, not a range A\.\.B.*HEAD~1\.\.HEAD"):
        history.revisions(repo, "HEAD")
    assert history.revisions(repo, "HEAD~1..HEAD") == [shas[2]]


def test_a_filter_that_matches_nothing_and_an_empty_machine_name_are_refused(store, tmp_path):
    from nsbench.errors import ConfigError

    with pytest.raises(ConfigError, match="--problem 'two-dof/9' is in no stored run; stored: two-dof/2"):
        history.table(store, problem="two-dof/9")
    with pytest.raises(ConfigError, match="machine name expects a name"):
        history.add(_run(tmp_path / "r9", [_row("a")]), store, machine=" ", commit="c9")
    with pytest.raises(ConfigError, match="suite"):
        history.run_commits(tmp_path, "HEAD", store, suite="no-such-suite")


def test_no_link_inside_the_store_or_the_show_folder_is_followed(store, tmp_path, capsys):
    from nsbench.errors import ConfigError

    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    # a linked machine folder: a new entry of that machine would be written through it
    linked = tmp_path / "linked-store"
    linked.mkdir()
    (linked / "box").symlink_to(elsewhere, target_is_directory=True)
    with pytest.raises(ConfigError, match="is a symbolic link"):
        history.add(_run(tmp_path / "r-link", [_row("a")]), linked, machine="box", commit="c4" * 20)
    assert list(elsewhere.iterdir()) == []
    # show --out with its steps table linked elsewhere
    out = tmp_path / "shown"
    out.mkdir()
    (out / "steps.csv").symlink_to(elsewhere / "steps.csv")
    assert main(["history", "show", "--store", str(store), "--out", str(out)]) == 2
    assert "steps.csv is a symbolic link" in capsys.readouterr().err
    assert list(elsewhere.iterdir()) == []


def test_an_entrys_file_copied_over_anothers_is_refused_not_read_as_the_other_commit(store, capsys):
    import shutil

    runs = history.entries(store)
    assert all(set(e.sha256 or {}) == {"results.parquet", "provenance.json"} for e in runs)
    assert main(["history", "show", "--store", str(store)]) == 0
    capsys.readouterr()
    first, last = runs[0], runs[-1]
    shutil.copyfile(Path(first.path) / "results.parquet", Path(last.path) / "results.parquet")  # valid by itself
    assert main(["history", "show", "--store", str(store)]) == 2
    err = capsys.readouterr().err
    assert f"{Path(last.path) / 'results.parquet'} is not the file this entry was added with" in err
    assert f"add the run of commit {last.short} again" in err


def _two_commit_repo(tmp_path):
    repo = tmp_path / "r1"
    repo.mkdir()
    _git(repo, "init", "-q")
    shas = []
    for text in ("x", "y"):
        (repo / "f").write_text(text)
        _git(repo, "add", "f")
        _git(repo, "commit", "-q", "-m", text)
        shas.append(_git(repo, "rev-parse", "HEAD"))
    return repo, shas


def test_a_killed_runs_worktrees_and_folders_are_removed_by_the_next(tmp_path):
    import tempfile

    if shutil.which("git") is None:
        pytest.skip("git is not installed")
    repo, (sha, _) = _two_commit_repo(tmp_path)
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()  # its pid names no process now: as a run killed with SIGKILL
    left = Path(tempfile.gettempdir()) / f"{history.TEMP_PREFIX}{dead.pid}-test"
    _git(repo, "worktree", "add", "--detach", str(left / "tree"), sha)
    assert _git(repo, "worktree", "list").count("\n") == 1
    assert left in history.clean_stale_runs(repo)
    assert not left.exists() and _git(repo, "worktree", "list").count("\n") == 0


def test_sigterm_ends_a_history_run_with_its_worktree_removed(tmp_path):
    import os
    import signal
    import tempfile

    if shutil.which("git") is None:
        pytest.skip("git is not installed")
    repo, shas = _two_commit_repo(tmp_path)
    suite = tmp_path / "plant.toml"
    suite.write_text(SUITE)

    def terminated(argv, env, cwd):
        assert _git(repo, "worktree", "list").count("\n") == 1  # the commit's worktree, while its run runs
        os.kill(os.getpid(), signal.SIGTERM)
        return 0

    with pytest.raises(KeyboardInterrupt):
        history.run_commits(repo, ",".join(shas), tmp_path / "store", suite=str(suite), runner=terminated)
    assert _git(repo, "worktree", "list").count("\n") == 0
    assert not list(Path(tempfile.gettempdir()).glob(f"{history.TEMP_PREFIX}{os.getpid()}-*"))
    assert signal.getsignal(signal.SIGTERM) is not None  # the previous handler is back
