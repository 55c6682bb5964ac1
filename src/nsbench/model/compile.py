"""numba settings shared by every compiled function of nsbench, and the guard that keeps their disk caches honest.

``jit`` compiles with numba's defaults for nsbench (disk cache, no fast-math, no
GIL); ``hot`` leaves out numba's reference counting for functions that allocate
nothing (in the hot loops its updates cost more than the arithmetic: the 2-DOF
``rhs`` took 160 ns with them, 18 ns without); ``inline`` also inlines the
smallest of them in numba itself.

Importing this module imports numba: only compiled code does so (``import
nsbench`` does not).
"""

from __future__ import annotations

import fcntl
import hashlib
import importlib
import json
import os
import re
import warnings
from pathlib import Path

import numba
from numba.core.errors import NumbaIRAssumptionWarning

# The first compilation of the compiled core takes minutes: say so, with a progress line. Imported by
# name so that the cache stamps below do not count nsbench.compiling (and what it imports) as
# compiled code: editing a message there must not recompile the core.
importlib.import_module("nsbench.compiling").announce()

#: ``from nsbench.x import a, b``, ``from nsbench.x import (a,\n b)`` or ``import nsbench.x``; the names of
#: the unparenthesised form stay on their line (``\s`` there would swallow the next import statement).
_IMPORTS = re.compile(
    r"^[ \t]*(?:from[ \t]+(nsbench[\w.]*)[ \t]+import[ \t]+(?:\(([\w\s,]*)\)?|([\w \t,]*))"
    r"|import[ \t]+(nsbench[\w.]*))",
    re.MULTILINE,
)


def imported_modules(text: str, known) -> set[str]:
    """The modules among ``known`` that ``text`` imports: ``import nsbench.x``, ``from nsbench.x
    import ...`` and the modules imported by name from a package (``from nsbench.x import y as z``:
    ``nsbench.x.y``, the alias dropped)."""
    out = set()
    for frm, grouped, names, plain in _IMPORTS.findall(text):
        module = frm or plain
        if module in known:
            out.add(module)
        for item in (grouped or names).replace("\n", " ").split(","):
            words = item.split()  # "y" or "y as z"
            sub = f"{frm}.{words[0]}" if words else ""
            if frm and sub in known:
                out.add(sub)
    return out


def drop_stale_numba_caches() -> None:
    """Delete the on-disk numba caches of every compiled source whose code, or code it uses, changed.

    numba invalidates a cached function only when its *own* file changes, but
    compiled code calls (and inlines) functions and constants of other files.
    So each compiled file gets a stamp over its own text and the stamps of every
    nsbench module it imports, recursively; a file whose stamp changed loses its
    caches, the others keep them.
    """
    root = Path(__file__).resolve().parents[1]
    paths = {
        ".".join(("nsbench",) + p.relative_to(root).with_suffix("").parts).removesuffix(".__init__"): p
        for p in root.rglob("*.py")
    }
    texts = {name: path.read_text(encoding="utf-8", errors="ignore") for name, path in paths.items()}

    def imports(name: str) -> set[str]:
        return imported_modules(texts[name], paths)

    stamps: dict[str, str] = {}

    def stamp(name: str, seen: frozenset[str]) -> str:
        if name not in stamps:
            digest = hashlib.sha256(texts[name].encode())
            for dep in sorted(imports(name) - seen - {name}):
                digest.update(stamp(dep, seen | {name}).encode())
            stamps[name] = digest.hexdigest()
        return stamps[name]

    compiled = [
        name for name, text in texts.items() if any(f"@{kind}" in text for kind in ("jit", "hot", "inline", "with_gil"))
    ]
    record = root / "__pycache__" / "numba-sources.json"
    try:
        old = json.loads(record.read_text()) if record.exists() else {}
    except (OSError, ValueError):
        old = {}
    new = {name: stamp(name, frozenset()) for name in compiled}
    if new == old:
        return
    try:
        for name in compiled:
            if old.get(name) != new[name]:
                path = paths[name]
                for cached in path.parent.glob(f"__pycache__/{path.stem}.*.nb[ic]"):
                    cached.unlink(missing_ok=True)
        record.parent.mkdir(exist_ok=True)
        record.write_text(json.dumps(new, indent=0, sort_keys=True))
    except OSError:  # a read-only install: numba then caches elsewhere or compiles in memory
        pass


drop_stale_numba_caches()
# numba's SSA pass has a pedantic self-check that warns when a variable of a
# function inlined with ``inline="always"`` (the law's ``rhs`` and guards inside
# the arc kernels) is not in scope in its IR. It is a note to numba's developers,
# not a defect of the compiled code (the kernels' event logs are bit-identical to
# the ones compiled without inlining: tests/hybrid/test_event_logs.py), and it
# would print about 90 lines at every first compilation.
warnings.filterwarnings("ignore", category=NumbaIRAssumptionWarning)


# ---------------------------------------------------------------------- compiled once per machine
#: The lock files this process holds (a function compiled again inside its own compilation, for
#: another signature, must not wait for itself).
_HELD: set[str] = set()


def _lock_path(dispatcher) -> str | None:
    """The lock file of ``dispatcher`` beside its disk cache, or ``None`` (no disk cache)."""
    cache = getattr(dispatcher, "_cache", None)
    where = getattr(cache, "cache_path", None)
    func = getattr(dispatcher, "py_func", None)
    if not where or func is None:
        return None
    name = re.sub(r"[^A-Za-z0-9_.-]+", "_", f"{func.__qualname__}-{func.__code__.co_firstlineno}")
    return os.path.join(where, f"{name}.nsbench-lock")


def compiled_once(dispatcher):
    """``dispatcher`` with its compilations serialised across processes by a lock file beside its cache.

    Two bench workers that start on the same kernel would both compile it (minutes on a
    fresh install, every announcement printed twice). With the lock the second waits while
    the first compiles and saves to the disk cache, then finds it there: numba's
    ``compile`` looks in the cache before it compiles. The lock is taken inside numba's own
    compiler lock, so the threads of one process take the two in one order; a function's
    compilation locks only the functions it calls, whose graph has no cycle, so processes
    cannot wait for each other in a ring. Where the lock file cannot be made (a read-only
    cache), the function compiles as numba alone would.
    """
    from numba.core.compiler_lock import global_compiler_lock

    compile_one = dispatcher.compile

    def compile(sig):
        path = _lock_path(dispatcher)
        with global_compiler_lock:
            if path is None or path in _HELD or _known(dispatcher, sig):
                return compile_one(sig)
            try:
                os.makedirs(os.path.dirname(path), exist_ok=True)
                fd = os.open(path, os.O_CREAT | os.O_RDWR, 0o666)
            except OSError:
                return compile_one(sig)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX)  # released when fd closes, or when the process ends
                _HELD.add(path)
                try:
                    return compile_one(sig)
                finally:
                    _HELD.discard(path)
            finally:
                os.close(fd)

    dispatcher.compile = compile
    return dispatcher


def _known(dispatcher, sig) -> bool:
    """Whether ``dispatcher`` holds an overload for ``sig`` already (no compilation, so no lock)."""
    from numba.core import sigutils

    try:
        args, _ = sigutils.normalize_signature(sig)
    except Exception:  # a form numba itself must judge: let its compile decide
        return False
    return tuple(args) in dispatcher.overloads


def _once(decorator):
    """A numba decorator whose functions compile once per machine (:func:`compiled_once`)."""

    def decorate(func):
        return compiled_once(decorator(func))

    return decorate


jit = _once(numba.njit(cache=True, fastmath=False, nogil=True))
#: Functions that allocate nothing: compiled without numba's reference counting.
hot = _once(numba.njit(cache=True, fastmath=False, nogil=True, _nrt=False))
#: The smallest of them that take arrays, inlined by numba itself (LLVM keeps them as calls unless forced:
#: ``small`` below, for functions of scalars).
inline = _once(numba.njit(cache=True, fastmath=False, nogil=True, _nrt=False, inline="always"))
#: Small functions of scalars called from many places (a law's parameter lookups): inlined by LLVM
#: (``alwaysinline``) where numba's own inliner would type their IR again at every call site, nested
#: inside every inlined right-hand side and guard of every kernel (on 2-DOF case 1, beside another job,
#: ``henon-rk4``'s first run compiled in 50 s rather than 82 s, ``mcpi``'s in 40 s rather than 62 s,
#: with the same warm run time). Functions that take a state array stay ``inline``: called on a
#: row of a node array, they ran 20 % slower when LLVM rather than numba inlined them.
small = _once(numba.njit(cache=True, fastmath=False, nogil=True, _nrt=False, forceinline=True))
#: Functions with an object-mode block (a call back into Python): not ``nogil``, since they hold
#: the GIL for the block (numba warns about object mode in a ``nogil`` function).
with_gil = _once(numba.njit(cache=True, fastmath=False, _nrt=False))
