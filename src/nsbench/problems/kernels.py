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
from pathlib import Path
from typing import TYPE_CHECKING, Sequence

import numba
import numpy as np

if TYPE_CHECKING:  # pragma: no cover
    from nsbench.problems.modes import Guard, Mode
    from nsbench.problems.oscillator import FrictionOscillator

VELOCITY, UPPER, LOWER = 0, 1, 2
_KIND_CODES = {"velocity": VELOCITY, "upper": UPPER, "lower": LOWER}


def _drop_stale_numba_caches() -> None:
    """Delete nsbench's on-disk numba caches when any compiled source changed.

    numba invalidates a cached function only when its *own* file changes, but
    the compiled arcs inline these kernels and each other's helpers across
    files; an edit of one file would otherwise leave stale machine code in
    the others' caches. One hash over every compiled source decides.
    """
    root = Path(__file__).resolve().parents[1]
    sources = sorted(path for path in root.rglob("*.py")
                     if "@jit" in path.read_text(encoding="utf-8", errors="ignore"))
    digest = hashlib.sha256()
    for path in sources:
        digest.update(path.relative_to(root).as_posix().encode())
        digest.update(path.read_bytes())
    stamp = root / "__pycache__" / "numba-sources.sha256"
    try:
        if stamp.exists() and stamp.read_text() == digest.hexdigest():
            return
        for path in sources:
            for cached in path.parent.glob(f"__pycache__/{path.stem}.*.nb[ic]"):
                cached.unlink(missing_ok=True)
        stamp.parent.mkdir(exist_ok=True)
        stamp.write_text(digest.hexdigest())
    except OSError:  # a read-only install: numba then caches elsewhere or compiles in memory
        pass


_drop_stale_numba_caches()
jit = numba.njit(cache=True, fastmath=False, nogil=True)


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


@jit
def n_blocks(p):
    return int(p[0])


@jit
def v0_of(p):
    nb = int(p[0])
    return p[3 + 6 * nb]


@jit
def link_tension(p, y, j):
    """Tension of spring link j (0: ground to block 1) and its stiffness d(tension)/d(extension)."""
    nb = int(p[0])
    d = y[0] if j == 0 else y[2 * j] - y[2 * j - 2]
    k = p[1 + 2 * nb + j]
    h = p[1 + 3 * nb + j]
    if h != 0.0:
        return k * d + h * (d * d * d), k + 3.0 * h * d * d
    return k * d, k


@jit
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


@jit
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


@jit
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


@jit
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


@jit
def guard_value(p, kind, i, t, y):
    """Guard value: v_i - v0 (VELOCITY), R_i - fr_i (UPPER) or R_i + fr_i (LOWER)."""
    nb = int(p[0])
    if kind == 0:
        return y[2 * i + 1] - p[3 + 6 * nb]
    fr = p[1 + 5 * nb + i]
    r = restoring(p, t, y, i)
    return r - fr if kind == 1 else r + fr


@jit
def guard_rate(p, kind, i, t, y, dy):
    """Time derivative of a guard along ``dy``."""
    if kind == 0:
        return dy[2 * i + 1]
    return restoring_rate(p, t, y, dy, i)


@jit
def linear_section_value(coeffs, level, y):
    out = -level
    for j in range(y.shape[0]):
        out += coeffs[j] * y[j]
    return out


@jit
def linear_section_rate(coeffs, dy):
    out = 0.0
    for j in range(dy.shape[0]):
        out += coeffs[j] * dy[j]
    return out


@jit
def section_crossed(direction, before, after):
    """:meth:`nsbench.sections.StateSection.crossed` compiled (``direction`` -1, 0 or +1)."""
    if before == 0.0 or (after != 0.0 and (before < 0.0) == (after < 0.0)):
        return False
    upward = before < 0.0
    return direction == 0 or (direction > 0) == upward
