"""``nsbench archive merge A B --to C``: two archives joined, each run once.

A run's folder is named by the checksum of its rows (:func:`nsbench.archive.layout.run_id`), so a
run found in both archives (or already in ``C``) is copied once. Every run's files are checked
against its manifest before they are copied: a damaged archive is not merged.
"""

from __future__ import annotations

import shutil
from dataclasses import dataclass
from pathlib import Path

from nsbench.archive import layout


@dataclass(frozen=True)
class MergeOutcome:
    """Runs copied into the target, and runs skipped because it held them already."""

    copied: int
    duplicates: int


def _copy_run(source: Path, target: Path, run: layout.Run) -> None:
    src, dst = layout.run_folder(source, run.run_id), layout.run_folder(target, run.run_id)
    dst.mkdir(parents=True, exist_ok=True)
    for name in (*layout.CHECKED, layout.MANIFEST):  # the manifest last: it marks a complete copy
        shutil.copyfile(src / name, dst / name)


def _copy_references(source: Path, target: Path) -> None:
    """The references ``target`` lacks (each one's three files, its JSON, which marks it complete, last)."""
    folder = source / layout.REFERENCES
    if not folder.is_dir():
        return
    (target / layout.REFERENCES).mkdir(parents=True, exist_ok=True)
    for meta in sorted(folder.glob("*.json")):
        key = meta.name[: -len(".json")]
        if (target / layout.REFERENCES / meta.name).exists():
            continue
        for name in (f"{key}.events.parquet", f"{key}.dense.npy", meta.name):
            if (folder / name).exists():
                shutil.copyfile(folder / name, target / layout.REFERENCES / name)


def merge_archives(sources: tuple[str | Path, ...], target: str | Path) -> MergeOutcome:
    """Copy every run of ``sources`` into ``target`` (created if absent), each run once."""
    to = Path(target)
    checked = []
    for source in map(Path, sources):
        found = layout.runs(source)
        for run in found:
            layout.verify(source, run)
        checked.append((source, found))
    layout.create(to)
    present = {r.run_id for r in layout.runs(to)}
    copied = duplicates = 0
    for source, found in checked:
        if source.resolve() == to.resolve():
            continue
        for run in found:
            if run.run_id in present:
                duplicates += 1
                continue
            _copy_run(source, to, run)
            present.add(run.run_id)
            copied += 1
        _copy_references(source, to)
    return MergeOutcome(copied, duplicates)
