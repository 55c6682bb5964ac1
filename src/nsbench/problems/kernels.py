"""Compiled (numba) kernels of the friction oscillator, for integrators with compiled hot loops.

The problem's coefficients are packed into one float64 vector (:func:`pack`);
a mode is an int64 array of phases (-1, 0, +1); a guard is the pair
``(kind, block)`` with kind codes :data:`VELOCITY`, :data:`UPPER`, :data:`LOWER`
and a 0-based block. Every function works on one state ``y`` of shape ``(n,)``
and writes into caller-provided arrays, so it can be called from ``@njit``
code without allocation. The formulas are those of
:class:`nsbench.problems.oscillator.FrictionOscillator` (tested equal).

Importing this module imports numba: only compiled integrators do so.
"""

from __future__ import annotations

import hashlib
import importlib
import json
import re
from pathlib import Path
from typing import TYPE_CHECKING, Sequence

import numba
import numpy as np

# The first compilation of the compiled core takes minutes: say so, with a progress line. Imported by
# name so that the cache stamps below do not count nsbench.compiling (and what it imports) as
# compiled code: editing a message there must not recompile the core.
importlib.import_module("nsbench.compiling").announce()

if TYPE_CHECKING:  # pragma: no cover
    from nsbench.problems.modes import Guard, Mode
    from nsbench.problems.oscillator import FrictionOscillator

VELOCITY, UPPER, LOWER = 0, 1, 2
_KIND_CODES = {"velocity": VELOCITY, "upper": UPPER, "lower": LOWER}


#: ``from nsbench.x import a, b``, ``from nsbench.x import (a,\n b)`` or ``import nsbench.x``; the names of
#: the unparenthesised form stay on their line (``\s`` there would swallow the next import statement).
_IMPORTS = re.compile(r"^[ \t]*(?:from[ \t]+(nsbench[\w.]*)[ \t]+import[ \t]+(?:\(([\w\s,]*)\)?|([\w \t,]*))"
                      r"|import[ \t]+(nsbench[\w.]*))", re.MULTILINE)


def _drop_stale_numba_caches() -> None:
    """Delete the on-disk numba caches of every compiled source whose code, or code it uses, changed.

    numba invalidates a cached function only when its *own* file changes, but
    compiled code calls (and inlines) functions and constants of other files:
    the hybrid loop holds the arc kernels' machine code. So each compiled file
    gets a stamp over its own text and the stamps of every nsbench module it
    imports, recursively; a file whose stamp changed loses its caches, the
    others keep them.
    """
    root = Path(__file__).resolve().parents[1]
    paths = {".".join(("nsbench",) + p.relative_to(root).with_suffix("").parts).removesuffix(".__init__"): p
             for p in root.rglob("*.py")}
    texts = {name: path.read_text(encoding="utf-8", errors="ignore") for name, path in paths.items()}

    def imports(name: str) -> set[str]:
        out = set()
        for frm, grouped, names, plain in _IMPORTS.findall(texts[name]):
            module = frm or plain
            if module in paths:
                out.add(module)
            for item in (grouped or names).replace("\n", " ").split(","):
                sub = f"{frm}.{item.strip()}"
                if frm and sub in paths:
                    out.add(sub)
        return out

    stamps: dict[str, str] = {}

    def stamp(name: str, seen: frozenset[str]) -> str:
        if name not in stamps:
            digest = hashlib.sha256(texts[name].encode())
            for dep in sorted(imports(name) - seen - {name}):
                digest.update(stamp(dep, seen | {name}).encode())
            stamps[name] = digest.hexdigest()
        return stamps[name]

    compiled = [name for name, text in texts.items() if "@jit" in text or "@hot" in text]
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


_drop_stale_numba_caches()
jit = numba.njit(cache=True, fastmath=False, nogil=True)
#: Functions that allocate nothing are compiled without numba's reference counting: in the hot
#: loops its updates (two calls per array argument and per inlined helper) cost far more than the
#: arithmetic (``rhs`` of the 2-DOF problem: 160 ns with them, 18 ns without). LLVM inlines them.
hot = numba.njit(cache=True, fastmath=False, nogil=True, _nrt=False)
#: The smallest of them are also inlined by numba itself: LLVM keeps some as calls, whose
#: argument passing costs as much as their arithmetic.
inline = numba.njit(cache=True, fastmath=False, nogil=True, _nrt=False, inline="always")


def pack(problem: "FrictionOscillator") -> np.ndarray:
    """Coefficients as ``[nb, m.., c.., k.., h.., fs.., fr.., F, w, v0]`` (float64)."""
    c = problem.coefficients
    return np.array([float(c.n_blocks), *c.m, *c.c, *c.k, *c.h, *c.fs, *c.fr, c.F, c.w, c.v0],
                    dtype=np.float64)


def mode_array(mode: "Mode") -> np.ndarray:
    """A mode as an int64 array of phases."""
    return np.array(mode, dtype=np.int64)


def guard_codes(guards: Sequence["Guard"]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(kinds, blocks, expected_signs)`` int64 arrays for a tuple of guards (blocks 0-based)."""
    kinds = np.array([_KIND_CODES[g.kind] for g in guards], dtype=np.int64)
    blocks = np.array([g.block - 1 for g in guards], dtype=np.int64)
    signs = np.array([g.expected_sign for g in guards], dtype=np.int64)
    return kinds, blocks, signs


@inline
def n_blocks(p):
    return int(p[0])


@inline
def v0_of(p):
    nb = int(p[0])
    return p[3 + 6 * nb]


@inline
def link_tension(p, y, j):
    """Tension of spring link j (0: ground to block 1) and its stiffness d(tension)/d(extension)."""
    nb = int(p[0])
    d = y[0] if j == 0 else y[2 * j] - y[2 * j - 2]
    k = p[1 + 2 * nb + j]
    h = p[1 + 3 * nb + j]
    if h != 0.0:
        return k * d + h * (d * d * d), k + 3.0 * h * d * d
    return k * d, k


@inline
def restoring(p, t, y, i):
    """R_i (0-based block i): every force on block i except friction."""
    nb = int(p[0])
    s_i, _ = link_tension(p, y, i)
    r = p[1 + nb + i] * y[2 * i + 1] + s_i
    if i + 1 < nb:
        s_next, _ = link_tension(p, y, i + 1)
        r -= s_next
    if i == nb - 1:
        F = p[1 + 6 * nb]
        if F != 0.0:
            r -= F * np.cos(p[2 + 6 * nb] * t)
    return r


@inline
def restoring_rate(p, t, y, dy, i):
    """dR_i/dt along the direction dy, including the forcing's explicit time dependence."""
    nb = int(p[0])
    _, k_i = link_tension(p, y, i)
    out = p[1 + nb + i] * dy[2 * i + 1] + k_i * dy[2 * i]
    if i > 0:
        out -= k_i * dy[2 * i - 2]
    if i + 1 < nb:
        _, k_next = link_tension(p, y, i + 1)
        out += k_next * (dy[2 * i] - dy[2 * i + 2])
    if i == nb - 1:
        F = p[1 + 6 * nb]
        if F != 0.0:
            w = p[2 + 6 * nb]
            out += F * w * np.sin(w * t)
    return out


@inline
def rhs(p, mode, t, y, out):
    """Frozen-mode vector field into ``out``."""
    nb = int(p[0])
    v0 = p[3 + 6 * nb]
    for i in range(nb):
        phase = mode[i]
        if phase == 0:
            out[2 * i] = v0
            out[2 * i + 1] = 0.0
        else:
            r = restoring(p, t, y, i)
            out[2 * i] = y[2 * i + 1]
            out[2 * i + 1] = (-r - p[1 + 4 * nb + i] * phase) / p[1 + i]


@hot
def jacobian(p, mode, t, y, out):
    """Frozen-mode Jacobian into ``out`` (n x n)."""
    nb = int(p[0])
    n = 2 * nb
    for a in range(n):
        for b in range(n):
            out[a, b] = 0.0
    for i in range(nb):
        if mode[i] == 0:
            continue
        m = p[1 + i]
        _, k_i = link_tension(p, y, i)
        diag = k_i
        if i > 0:
            out[2 * i + 1, 2 * i - 2] = k_i / m
        if i + 1 < nb:
            _, k_next = link_tension(p, y, i + 1)
            diag += k_next
            out[2 * i + 1, 2 * i + 2] = k_next / m
        out[2 * i, 2 * i + 1] = 1.0
        out[2 * i + 1, 2 * i] = -diag / m
        out[2 * i + 1, 2 * i + 1] = -p[1 + nb + i] / m


@inline
def guard_value(p, kind, i, t, y):
    """Guard value: v_i - v0 (VELOCITY), R_i - fr_i (UPPER) or R_i + fr_i (LOWER)."""
    nb = int(p[0])
    if kind == 0:
        return y[2 * i + 1] - p[3 + 6 * nb]
    fr = p[1 + 5 * nb + i]
    r = restoring(p, t, y, i)
    return r - fr if kind == 1 else r + fr


@inline
def guard_rate(p, kind, i, t, y, dy):
    """Time derivative of a guard along ``dy``."""
    if kind == 0:
        return dy[2 * i + 1]
    return restoring_rate(p, t, y, dy, i)


@inline
def linear_section_value(coeffs, level, y):
    out = -level
    for j in range(y.shape[0]):
        out += coeffs[j] * y[j]
    return out


@inline
def linear_section_rate(coeffs, dy):
    out = 0.0
    for j in range(dy.shape[0]):
        out += coeffs[j] * dy[j]
    return out


@inline
def section_crossed(direction, before, after):
    """:meth:`nsbench.sections.StateSection.crossed` compiled (``direction`` -1, 0 or +1)."""
    if before == 0.0 or (after != 0.0 and (before < 0.0) == (after < 0.0)):
        return False
    upward = before < 0.0
    return direction == 0 or (direction > 0) == upward
