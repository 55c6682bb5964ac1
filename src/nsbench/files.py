"""Files of nsbench's stores: atomic writes, the temporary files a killed run leaves, links.

Every store (benchmark cases, cached references, sweep chunks) writes a file
under a temporary name and renames it, so a reader never sees half a file; a
run killed in between leaves the temporary file, which the next run removes.
Neither the write nor the rename follows a symbolic link: a link in the way is
replaced, never written through. A store refuses to work in a folder whose
entries it writes are links (:func:`refuse_links`): they could lead anywhere.
"""

from __future__ import annotations

import os
import time
from pathlib import Path
from typing import Iterable

from nsbench.errors import ConfigError

#: Temporary files younger than this (seconds) may belong to a run writing right now.
STALE_AFTER = 60.0


def write_atomic(path: str | os.PathLike, data: str | bytes) -> Path:
    """Write ``data`` to ``path`` through ``path.tmp`` and a rename (a reader sees all or nothing).

    A leftover ``path.tmp`` (a link included) is removed first and the new one
    created exclusively, so the data never goes through a link to another file;
    the rename replaces a link at ``path`` itself, not the file it points to.
    """
    target = Path(path)
    tmp = fresh_temporary(target)
    raw = data if isinstance(data, bytes) else data.encode()
    fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_NOFOLLOW", 0), 0o666)
    with os.fdopen(fd, "wb") as fh:
        fh.write(raw)
    os.replace(tmp, target)
    return target


def fresh_temporary(target: Path) -> Path:
    """``target.tmp``, with whatever was there (a killed run's file, a link) removed."""
    tmp = target.with_name(target.name + ".tmp")
    try:
        tmp.unlink()
    except FileNotFoundError:
        pass
    return tmp


def remove_stale_temporaries(folders: Iterable[tuple[str | os.PathLike, str]], stale_after: float = STALE_AFTER) -> int:
    """Delete nsbench's temporary files older than ``stale_after`` seconds; their number.

    ``folders`` are ``(folder, pattern)`` pairs: the ``*.tmp`` names nsbench
    writes there (``'*.parquet.tmp'``), so no file of anyone else is touched.
    Younger ones may be another run's, being written into the same folder, and
    are left alone.
    """
    now, removed = time.time(), 0
    for folder, pattern in folders:
        folder = Path(folder)
        for tmp in folder.glob(pattern) if folder.is_dir() and not folder.is_symlink() else ():
            try:
                if now - tmp.lstat().st_mtime > stale_after:
                    tmp.unlink()
                    removed += 1
            except FileNotFoundError:  # another run renamed or removed it meanwhile
                pass
    return removed


def refuse_links(root: str | os.PathLike, names: Iterable[str], folders: Iterable[str] = ()) -> None:
    """``ConfigError`` if an entry nsbench writes in the folder ``root`` is a symbolic link.

    ``names`` are the entries (glob patterns allowed) nsbench writes or deletes
    in ``root``; ``folders`` those of them whose every entry it writes or deletes
    too. ``root`` itself may be a link: the user chose it.
    """
    import fnmatch

    base = Path(root)
    if not base.is_dir():
        return
    patterns = list(names)
    for entry in base.iterdir():  # every entry, a dangling link included (a glob would skip it)
        if any(fnmatch.fnmatchcase(entry.name, pattern) for pattern in patterns):
            _refuse_link(base, entry)
    for name in folders:
        folder = base / name
        if folder.is_dir() and not folder.is_symlink():
            for entry in folder.iterdir():
                _refuse_link(base, entry)


def _refuse_link(root: Path, entry: Path) -> None:
    if entry.is_symlink():
        raise ConfigError(
            f"{entry} is a symbolic link: nsbench never follows a link inside the folder it "
            f"writes ({root}), it could lead anywhere; remove the link or choose another folder"
        )
