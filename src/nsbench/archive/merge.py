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
from nsbench.files import refuse_links


@dataclass(frozen=True)
class MergeOutcome:
    """Runs copied into the target, and runs skipped because it held them already."""

    copied: int
    duplicates: int


def _copy_run(source: Path, target: Path, run: layout.Run) -> None:
    src, dst = layout.run_folder(source, run.run_id), layout.run_folder(target, run.run_id)
    dst.mkdir(parents=True, exist_ok=True)
    for name in (*layout.files_of(run), layout.MANIFEST):  # the manifest last: it marks a complete copy
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
    refuse_links(to, (layout.RUNS, layout.REFERENCES), (layout.RUNS, layout.REFERENCES))
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


@dataclass(frozen=True)
class ArchiveMergeRequest:
    """What ``archive merge`` asks for, checked at its construction (a :class:`~nsbench.errors.ConfigError`
    naming the value before anything is read or written).

    Attributes
    ----------
    sources
        Two or more archives (schema ``nsbench-results/1``).
    to
        The merged archive: one of the sources (the others are merged into it), another archive, or
        a folder to make one (absent or empty).
    """

    sources: tuple[str, ...]
    to: str

    def __post_init__(self) -> None:
        from nsbench.errors import ConfigError

        object.__setattr__(self, "sources", tuple(str(s) for s in self.sources))
        if len(self.sources) < 2:
            raise ConfigError(f"archive merge takes two or more archives, got {len(self.sources)}")
        for source in self.sources:
            if not source.strip():
                raise ConfigError("ARCHIVE expects an archive folder, got ''")
            layout.check_schema(Path(source))
        layout.check_target(Path(self.to), "--to")


def merge(request: ArchiveMergeRequest) -> MergeOutcome:
    """Merge the request's archives (:func:`merge_archives`) and print what was copied."""
    outcome = merge_archives(request.sources, request.to)
    print(
        f"merged {', '.join(request.sources)} into {request.to}: {outcome.copied} run(s) copied, "
        f"{outcome.duplicates} already there"
    )
    return outcome
