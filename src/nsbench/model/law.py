"""A problem's law: the compiled functions that make a hybrid automaton, and the core's calls of them.

A problem family writes these functions once, as plain ``@numba.njit`` functions
of its own module, on its parameter vector ``p`` (a named layout of the family)
and the mode vector ``mode`` (int64; any finite set of modes, encoded as the
family likes). :class:`Law` compiles them for the signatures below and keeps
their addresses in a table; compiled code calls them through the helpers of
this module (``rhs(prob, mode, t, y, out)``, ...), which read the table in
``prob.law``.

========================= ====================================================================
function                  what it does
========================= ====================================================================
``rhs``                   ``out = f(t, y)``, the vector field of the frozen ``mode``
``jacobian``              ``out = df/dy`` (``n x n``)
``guard_value``           the guard ``(kind, index)`` of the mode at ``(t, y)``
``guard_rate``            its time derivative along ``dy`` (explicit time dependence included)
``guards_of``             the guards of ``mode`` into ``(kind, index, sign)`` arrays, in tie order
                          (an exact tie goes to the first); returns their number. ``sign`` is the
                          sign the guard keeps while the mode holds
``transition``            the guard ``(kind, index)`` fired at ``(t, y)``: set the next mode and
                          reset the state in place, mark in ``fresh[index]`` an element whose
                          new guard starts on its surface by construction (it is not tested
                          again at once); return the event kind code
``initial_mode``          the mode a state starts in
``start_fresh``           the ``fresh`` marks of a run's first state
``accumulation_limit``    events of guard ``(kind, index)`` accumulate (Zeno): apply the limit
                          behaviour at ``(t, y)`` (mode and state in place); return its event
                          kind code, or -1 if the problem declares none for that guard
========================= ====================================================================
"""

from __future__ import annotations

from types import ModuleType
from typing import Any

import numpy as np
from numba import types

from nsbench.errors import ConfigError
from nsbench.model import functions
from nsbench.model.compile import hot, inline
from nsbench.model.functions import any_layout as _a

f8, i8 = types.float64, types.int64
# the law takes arrays of any layout (see nsbench.model.functions.any_layout)
F1 = types.Array(types.float64, 1, "A")
F2 = types.Array(types.float64, 2, "A")
I1 = types.Array(types.int64, 1, "A")
B1 = types.Array(types.boolean, 1, "A")

#: Slots of the law table, in order: (name, signature).
SIGNATURES: tuple[tuple[str, Any], ...] = (
    ("rhs", types.void(F1, I1, f8, F1, F1)),
    ("jacobian", types.void(F1, I1, f8, F1, F2)),
    ("guard_value", f8(F1, I1, i8, i8, f8, F1)),
    ("guard_rate", f8(F1, I1, i8, i8, f8, F1, F1)),
    ("guards_of", i8(F1, I1, I1, I1, I1)),
    ("transition", i8(F1, I1, i8, i8, f8, F1, B1)),
    ("initial_mode", types.void(F1, f8, F1, I1)),
    ("start_fresh", types.void(F1, I1, f8, F1, B1)),
    ("accumulation_limit", i8(F1, I1, i8, i8, f8, F1)),
)
NAMES = tuple(name for name, _ in SIGNATURES)
RHS, JACOBIAN, GUARD_VALUE, GUARD_RATE, GUARDS_OF, TRANSITION, INITIAL_MODE, START_FRESH, ACCUMULATION = range(
    len(SIGNATURES))
#: Functions every law must have; the others have defaults (no accumulation limit).
REQUIRED = ("rhs", "jacobian", "guard_value", "guard_rate", "guards_of", "transition", "initial_mode",
            "start_fresh")


class Law:
    """A problem family's compiled functions and their address table.

    Parameters
    ----------
    source
        The module (or any object) with the functions of the table in the module
        docstring as ``numba.njit`` functions.

    Attributes
    ----------
    table
        The int64 address table compiled code reads (``ProblemData.law``).
    functions
        Name -> the numba dispatcher (callable from Python with the same arguments).
    """

    def __init__(self, source: ModuleType | Any) -> None:
        missing = [name for name in REQUIRED if not hasattr(source, name)]
        where = getattr(source, "__name__", repr(source))
        if missing:
            raise ConfigError(f"the law {where} lacks the compiled function(s) {', '.join(missing)}")
        self.functions = {name: getattr(source, name) for name in NAMES if hasattr(source, name)}
        if "accumulation_limit" not in self.functions:
            self.functions["accumulation_limit"] = no_accumulation_limit
        self.source = where
        self.table = functions.table({k: (self.functions[name], sig) for k, (name, sig) in enumerate(SIGNATURES)},
                                     len(SIGNATURES))

    def __getattr__(self, name: str):
        try:
            return self.__dict__["functions"][name]
        except KeyError:
            raise AttributeError(name) from None


_LAWS: dict[int, Law] = {}


def law_of(source: ModuleType | Any) -> Law:
    """The :class:`Law` of ``source``, compiled once per process."""
    key = id(source)
    if key not in _LAWS:
        _LAWS[key] = Law(source)
    return _LAWS[key]


@hot
def no_accumulation_limit(p, mode, kind, index, t, y):
    """The default: no limit behaviour declared, so an accumulation of events is not extrapolated."""
    return -1


# ---------------------------------------------------------------------- calls from compiled code
_as = [functions.caster(types.FunctionType(sig)) for _, sig in SIGNATURES]
_as_rhs, _as_jac, _as_gv, _as_gr, _as_gof, _as_tr, _as_im, _as_sf, _as_acc = _as


@inline
def rhs(prob, mode, t, y, out):
    _as_rhs(prob.law[2 * RHS], prob.law[2 * RHS + 1])(_a(prob.p), _a(mode), t, _a(y), _a(out))


@inline
def jacobian(prob, mode, t, y, out):
    _as_jac(prob.law[2 * JACOBIAN], prob.law[2 * JACOBIAN + 1])(_a(prob.p), _a(mode), t, _a(y), _a(out))


@inline
def guard_value(prob, mode, kind, index, t, y):
    return _as_gv(prob.law[2 * GUARD_VALUE], prob.law[2 * GUARD_VALUE + 1])(_a(prob.p), _a(mode), kind, index,
                                                                            t, _a(y))


@inline
def guard_rate(prob, mode, kind, index, t, y, dy):
    return _as_gr(prob.law[2 * GUARD_RATE], prob.law[2 * GUARD_RATE + 1])(_a(prob.p), _a(mode), kind, index, t,
                                                                          _a(y), _a(dy))


@inline
def guards_of(prob, mode, gk, gi, gs):
    return _as_gof(prob.law[2 * GUARDS_OF], prob.law[2 * GUARDS_OF + 1])(_a(prob.p), _a(mode), _a(gk), _a(gi),
                                                                         _a(gs))


@inline
def transition(prob, mode, kind, index, t, y, fresh):
    return _as_tr(prob.law[2 * TRANSITION], prob.law[2 * TRANSITION + 1])(_a(prob.p), _a(mode), kind, index, t,
                                                                          _a(y), _a(fresh))


@inline
def initial_mode(prob, t, y, mode):
    _as_im(prob.law[2 * INITIAL_MODE], prob.law[2 * INITIAL_MODE + 1])(_a(prob.p), t, _a(y), _a(mode))


@inline
def start_fresh(prob, mode, t, y, fresh):
    _as_sf(prob.law[2 * START_FRESH], prob.law[2 * START_FRESH + 1])(_a(prob.p), _a(mode), t, _a(y), _a(fresh))


@inline
def accumulation_limit(prob, mode, kind, index, t, y):
    return _as_acc(prob.law[2 * ACCUMULATION], prob.law[2 * ACCUMULATION + 1])(_a(prob.p), _a(mode), kind,
                                                                               index, t, _a(y))


# ---------------------------------------------------------------------- many states at once (numpy forms)
@hot
def rhs_rows(prob, mode, t, y, out):
    """``out[j] = f(t[j], y[j])`` for every row ``j`` of ``y`` (the numpy form of the field)."""
    for j in range(y.shape[0]):
        rhs(prob, mode, t[j], y[j], out[j])


@hot
def jacobian_rows(prob, mode, t, y, out):
    """``out[j] = df/dy(t[j], y[j])`` for every row ``j``."""
    for j in range(y.shape[0]):
        jacobian(prob, mode, t[j], y[j], out[j])


@hot
def guard_rows(prob, mode, kind, index, t, y, dy, out, rates):
    """Guard values (``rates`` false) or rates along ``dy`` at every row."""
    for j in range(y.shape[0]):
        if rates:
            out[j] = guard_rate(prob, mode, kind, index, t[j], y[j], dy[j])
        else:
            out[j] = guard_value(prob, mode, kind, index, t[j], y[j])


def _rows(y: np.ndarray, n: int) -> tuple[np.ndarray, bool]:
    """States as C-contiguous rows, and whether ``y`` was one state (shape ``(n,)``) or columns ``(n, k)``."""
    y = np.asarray(y, dtype=float)
    if y.ndim == 1:
        if y.shape[0] != n:
            raise ValueError(f"a state has {n} entries, not {y.shape[0]}")
        return np.array(y.reshape(1, n)), True  # a writable copy: the law's types are writable arrays
    if y.ndim != 2 or y.shape[0] != n:
        raise ValueError(f"states must have shape ({n},) or ({n}, k), not {y.shape}")
    return np.array(y.T, order="C"), False


def _times(t: Any, k: int) -> np.ndarray:
    t = np.asarray(t, dtype=float)
    return np.ascontiguousarray(np.broadcast_to(t, (k,)) if t.ndim == 0 else t.reshape(k))


def evaluate_rhs(prob, mode: np.ndarray, t: Any, y: Any) -> np.ndarray:
    """The field at one state ``(n,)`` or at columns ``(n, k)`` (``t`` a scalar or ``(k,)``), same shape out."""
    n = np.asarray(y).shape[0]
    rows, single = _rows(y, n)
    out = np.empty_like(rows)
    rhs_rows(prob, mode, _times(t, rows.shape[0]), rows, out)
    return out[0] if single else out.T


def evaluate_jacobian(prob, mode: np.ndarray, t: Any, y: Any) -> np.ndarray:
    """The Jacobian at one state (``(n, n)``) or at columns (``(n, n, k)``)."""
    n = np.asarray(y).shape[0]
    rows, single = _rows(y, n)
    out = np.zeros((rows.shape[0], n, n))
    jacobian_rows(prob, mode, _times(t, rows.shape[0]), rows, out)
    return out[0] if single else np.moveaxis(out, 0, -1)


def evaluate_guard(prob, mode: np.ndarray, kind: int, index: int, t: Any, y: Any, dy: Any = None):
    """A guard's values (or, with ``dy``, its rates) at one state (a float) or at columns (``(k,)``)."""
    n = np.asarray(y).shape[0]
    rows, single = _rows(y, n)
    drows = rows if dy is None else _rows(dy, n)[0]
    out = np.empty(rows.shape[0])
    guard_rows(prob, mode, int(kind), int(index), _times(t, rows.shape[0]), rows, drows, out, dy is not None)
    return float(out[0]) if single else out
