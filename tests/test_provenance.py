"""Provenance: what a result records about where it came from, and what asking git must not do."""

from __future__ import annotations

import os
import shutil
import subprocess

import pytest

from nsbench.provenance import git_commit, provenance


def test_provenance_has_versions_machine_and_date():
    info = provenance()
    for key in ("version_nsbench", "version_numpy", "version_scipy", "python", "cpu", "cpu_count", "date"):
        assert info[key], key
    assert all(p["distribution"] != "nsbench" for p in info["plugins"])  # built-ins are not plug-ins


def test_provenance_lists_a_component_registered_at_run_time():
    from nsbench import registry
    from nsbench.integrators.henon_rk4 import HenonRK4

    class Mine(HenonRK4):
        name = "test-provenance-mine"

    registry.register("integrators", Mine.name, Mine)
    try:
        rows = [p for p in provenance()["plugins"] if p["name"] == Mine.name]
    finally:
        registry.unregister("integrators", Mine.name)
    assert rows == [
        {
            "kind": "integrator",
            "name": Mine.name,
            "target": f"{__name__}:{Mine.__qualname__}",
            "distribution": None,
            "version": None,
        }
    ]


@pytest.mark.skipif(shutil.which("git") is None, reason="git is not installed")
def test_an_untrusted_checkout_in_the_current_directory_runs_nothing(tmp_path, monkeypatch):
    # A repository can name a program in its own config that `git status` runs
    # (core.fsmonitor). nsbench started inside such a checkout must not run it:
    # provenance asks git about nsbench's own source, with fsmonitor and hooks off.
    repo = tmp_path / "untrusted"
    repo.mkdir()
    marker = tmp_path / "fsmonitor-ran"
    hook = tmp_path / "hook.sh"
    hook.write_text(f"#!/bin/sh\ntouch {marker}\n")
    hook.chmod(0o755)
    env = {
        **os.environ,
        "GIT_AUTHOR_NAME": "t",
        "GIT_AUTHOR_EMAIL": "t@t",
        "GIT_COMMITTER_NAME": "t",
        "GIT_COMMITTER_EMAIL": "t@t",
    }
    for cmd in (["init", "-q"], ["config", "core.fsmonitor", str(hook)]):
        subprocess.run(["git", *cmd], cwd=repo, check=True, env=env)
    (repo / "f.txt").write_text("x")
    subprocess.run(["git", "add", "f.txt"], cwd=repo, check=True, env=env)
    subprocess.run(["git", "-c", "core.fsmonitor=false", "commit", "-qm", "x"], cwd=repo, check=True, env=env)
    # the hook is real: plain `git status` in that checkout runs it
    subprocess.run(["git", "status", "--porcelain"], cwd=repo, capture_output=True, env=env)
    assert marker.exists(), "this git does not run core.fsmonitor on status: the test would prove nothing"
    marker.unlink()
    monkeypatch.chdir(repo)
    provenance()
    git_commit(repo)  # asked about that checkout explicitly: still nothing runs
    assert not marker.exists()


def _git(repo, *args):
    env = {
        **os.environ,
        "GIT_AUTHOR_NAME": "t",
        "GIT_AUTHOR_EMAIL": "t@t",
        "GIT_COMMITTER_NAME": "t",
        "GIT_COMMITTER_EMAIL": "t@t",
    }
    return subprocess.run(["git", *args], cwd=repo, check=True, env=env, capture_output=True, text=True)


@pytest.mark.skipif(shutil.which("git") is None, reason="git is not installed")
def test_an_installed_copy_inside_another_repository_records_no_commit_and_runs_nothing(tmp_path):
    # nsbench installed in a virtual environment inside someone's checkout: that checkout's
    # commit is not nsbench's, and its clean filter (run by `git status`) must not run
    repo = tmp_path / "project"
    repo.mkdir()
    marker = tmp_path / "filter-ran"
    _git(repo, "init", "-q")
    _git(repo, "config", "filter.trap.clean", f"sh -c 'touch {marker}; cat'")
    (repo / ".gitattributes").write_text("*.txt filter=trap\n")
    (repo / "f.txt").write_text("x")
    _git(repo, "add", ".")
    _git(repo, "commit", "-qm", "x")
    package = repo / ".venv" / "lib" / "python3.11" / "site-packages" / "nsbench"
    package.mkdir(parents=True)
    (package / "__init__.py").write_text("")
    (repo / "f.txt").write_text("y")  # same size, new time: git must read it through the filter
    os.utime(repo / "f.txt", (1e9, 2e9))
    marker.unlink(missing_ok=True)
    _git(repo, "status", "--porcelain")  # the trap is real: plain `git status` runs the filter
    assert marker.exists(), "this git does not run the clean filter on status: the test would prove nothing"
    marker.unlink()
    assert git_commit(package) is None
    assert not marker.exists()


@pytest.mark.skipif(shutil.which("git") is None, reason="git is not installed")
def test_nsbench_own_checkout_records_its_commit(tmp_path):
    repo = tmp_path / "nsbench-checkout"
    (repo / "src" / "nsbench").mkdir(parents=True)
    (repo / "pyproject.toml").write_text('[project]\nname = "nsbench"\n')
    _git(repo, "init", "-q")
    _git(repo, "add", ".")
    _git(repo, "commit", "-qm", "x")
    sha = _git(repo, "rev-parse", "HEAD").stdout.strip()
    assert git_commit(repo / "src" / "nsbench") == sha
    (repo / "pyproject.toml").write_text('[project]\nname = "nsbench"\nversion = "1"\n')
    assert git_commit(repo / "src" / "nsbench") == sha + "+dirty"
    (repo / "pyproject.toml").write_text('[project]\nname = "other"\n')  # another project's checkout
    assert git_commit(repo / "src" / "nsbench") is None
