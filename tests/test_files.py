"""Atomic writes never go through a link, temporary files of others are never removed, links refused."""

from __future__ import annotations

import os
import time

import pytest

from nsbench.errors import ConfigError
from nsbench.files import refuse_links, remove_stale_temporaries, write_atomic


def test_an_atomic_write_never_writes_through_a_link(tmp_path):
    outside = tmp_path / "outside.txt"
    outside.write_text("precious")
    store = tmp_path / "store"
    store.mkdir()
    (store / "a.json.tmp").symlink_to(outside)  # a link where the temporary file goes
    (store / "b.json").symlink_to(outside)  # a link where the file goes
    write_atomic(store / "a.json", "one")
    write_atomic(store / "b.json", b"two")
    assert outside.read_text() == "precious"
    assert (store / "a.json").read_text() == "one" and not (store / "a.json.tmp").exists()
    assert (store / "b.json").read_text() == "two" and not (store / "b.json").is_symlink()


def test_only_nsbench_temporary_files_are_removed(tmp_path):
    mine, theirs, young = tmp_path / "chunk-1.tmp", tmp_path / "notes.tmp", tmp_path / "chunk-2.tmp"
    for f in (mine, theirs, young):
        f.write_text("x")
    for f in (mine, theirs):
        os.utime(f, (time.time() - 3600, time.time() - 3600))
    assert remove_stale_temporaries([(tmp_path, "chunk-*.tmp")]) == 1
    assert not mine.exists() and theirs.exists() and young.exists()


def test_links_among_the_written_entries_are_refused(tmp_path):
    outside = tmp_path / "elsewhere"
    outside.mkdir()
    root = tmp_path / "out"
    (root / "cases").mkdir(parents=True)
    refuse_links(root, ["cases", "report.md"], ["cases"])  # nothing linked: fine
    (root / "cases" / "x.parquet").symlink_to(outside / "x.parquet")
    with pytest.raises(ConfigError, match="x.parquet is a symbolic link"):
        refuse_links(root, ["cases"], ["cases"])
    (root / "cases" / "x.parquet").unlink()
    (root / "report.md").symlink_to(outside / "r.md")
    with pytest.raises(ConfigError, match="report.md is a symbolic link"):
        refuse_links(root, ["cases", "report.md"], ["cases"])
    linked_root = tmp_path / "chosen"
    linked_root.symlink_to(root / "cases")  # the folder the user names may itself be a link
    refuse_links(linked_root, ["*.parquet"])
