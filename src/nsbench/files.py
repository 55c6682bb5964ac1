"""Files of nsbench's stores: atomic writes and the temporary files a killed run leaves.

Every store (benchmark cases, cached references, sweep chunks) writes a file
under a temporary name and renames it, so a reader never sees half a file; a
run killed in between leaves the temporary file, which the next run removes.
"""

from __future__ import annotations

import os
import time
from pathlib import Path
from typing import Iterable

#: Temporary files younger than this (seconds) may belong to a run writing right now.
STALE_AFTER = 60.0


def write_atomic(path: str | os.PathLike, data: str | bytes) -> Path:
    """Write ``data`` to ``path`` through ``path.tmp`` and a rename (a reader sees all or nothing)."""
    target = Path(path)
    tmp = target.with_name(target.name + ".tmp")
    if isinstance(data, bytes):
        tmp.write_bytes(data)
    else:
        tmp.write_text(data)
    os.replace(tmp, target)
    return target


def remove_stale_temporaries(folders: Iterable[str | os.PathLike], stale_after: float = STALE_AFTER) -> int:
    """Delete the ``*.tmp`` files of ``folders`` older than ``stale_after`` seconds; their number.

    Younger ones may be another run's, being written into the same folder, and are left alone.
    """
    now, removed = time.time(), 0
    for folder in map(Path, folders):
        for tmp in folder.glob("*.tmp") if folder.is_dir() else ():
            try:
                if now - tmp.stat().st_mtime > stale_after:
                    tmp.unlink()
                    removed += 1
            except FileNotFoundError:  # another run renamed or removed it meanwhile
                pass
    return removed
