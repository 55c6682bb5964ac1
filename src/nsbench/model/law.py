"""A problem's law: the compiled functions that make a hybrid automaton, and the core's calls of them.

A problem family writes these functions once, as plain ``@numba.njit`` functions
of its own module (its *law module*), on its parameter vector ``p`` (a named
layout of the family) and the mode vector ``mode`` (int64; any finite set of
modes, encoded as the family likes):

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
``accumulation_limit``    (optional) events of guard ``(kind, index)`` accumulate (Zeno): apply
                          the limit behaviour at ``(t, y)`` (mode and state in place); return its
                          event kind code, or -1 if the problem declares none for that guard
========================= ====================================================================

How the core reaches them without importing the problem: a problem hands compiled
code a :class:`ProblemData`-like named tuple ``(p,)`` whose *class* belongs to its
law module (:func:`data_class`: one class per law module, its name carrying a hash
of the law's source). The calls below (``rhs(prob, mode, t, y, out)``, ...) are
typed by numba from that class: they call the law module's own function, which
numba compiles into the caller and can inline. So the loop and every arc kernel
are written once and compiled once per problem family, each instance cached on
disk under its own signature; a law that changes gets a new class name, hence a
fresh instance, never a stale one.
"""

from __future__ import annotations

import hashlib
import importlib
import inspect
from types import ModuleType
from typing import Any, NamedTuple

import numpy as np
from numba import types
from numba.core.errors import TypingError
from numba.extending import overload

from nsbench.errors import ConfigError
from nsbench.model.compile import hot

f8, i8 = types.float64, types.int64
_F1, _F2 = types.Array(types.float64, 1, "C"), types.Array(types.float64, 2, "C")
_I1, _B1 = types.Array(types.int64, 1, "C"), types.Array(types.boolean, 1, "C")

#: The law's functions and the signature each is checked against when a law is loaded (contiguous
#: arrays; compiled code may call them with any layout, numba specialises).
SIGNATURES: tuple[tuple[str, Any], ...] = (
    ("rhs", types.void(_F1, _I1, f8, _F1, _F1)),
    ("jacobian", types.void(_F1, _I1, f8, _F1, _F2)),
    ("guard_value", f8(_F1, _I1, i8, i8, f8, _F1)),
    ("guard_rate", f8(_F1, _I1, i8, i8, f8, _F1, _F1)),
    ("guards_of", i8(_F1, _I1, _I1, _I1, _I1)),
    ("transition", i8(_F1, _I1, i8, i8, f8, _F1, _B1)),
    ("initial_mode", types.void(_F1, f8, _F1, _I1)),
    ("start_fresh", types.void(_F1, _I1, f8, _F1, _B1)),
    ("accumulation_limit", i8(_F1, _I1, i8, i8, f8, _F1)),
)
NAMES = tuple(name for name, _ in SIGNATURES)
#: Functions every law must have; the others have defaults (no accumulation limit).
REQUIRED = NAMES[:-1]


@hot
def no_accumulation_limit(p, mode, kind, index, t, y):
    """The default: no limit behaviour declared, so an accumulation of events is not extrapolated."""
    return -1


def _imported(module: ModuleType) -> set[str]:
    """Names of the modules of the same top-level package that ``module``'s source imports."""
    import ast

    package = module.__name__.split(".")[0]
    try:
        tree = ast.parse(inspect.getsource(module))
    except (OSError, TypeError, SyntaxError):
        return set()
    found = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            found.add(node.module)
            found.update(f"{node.module}.{alias.name}" for alias in node.names)
        elif isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
    return {name for name in found if name.split(".")[0] == package}


def _source_stamp(module: ModuleType) -> str:
    """A hash of the law module's source and of the sources of the modules of its package it imports,
    recursively (their constants are compiled into the law's functions)."""
    import sys

    digest = hashlib.sha256()
    seen: set[str] = set()
    todo = [module.__name__]
    while todo:
        name = todo.pop()
        mod = sys.modules.get(name)
        if name in seen or mod is None:
            continue
        seen.add(name)
        try:
            digest.update(name.encode() + inspect.getsource(mod).encode())
        except (OSError, TypeError):  # no source (a frozen or C module): its name stands in
            digest.update(name.encode())
        todo.extend(sorted(_imported(mod) - seen))
    return digest.hexdigest()[:12]


_DATA_CLASSES: dict[str, type] = {}


def _new_data_class(name: str, law_module: str | None) -> type:
    # a class per law, named at run time (mypy wants a literal name: the class it builds is the same)
    cls = NamedTuple(name, [("p", np.ndarray)])  # type: ignore[misc]
    cls.__module__ = __name__
    cls.__qualname__ = name
    cls.__doc__ = f"The parameter vector of a problem whose law is {law_module}."
    setattr(cls, "__law_module__", law_module)  # noqa: B010 (a new attribute of a built class)
    return cls


def data_class(module: ModuleType) -> type:
    """The problem-data class of a law module: a named tuple ``(p,)``, one class per law (and law source).

    Its name encodes the law module and a hash of its source; numba's disk cache
    stores it by that name, and this module finds it again in another process
    (:func:`__getattr__`).
    """
    name = f"ProblemData_{module.__name__.encode().hex()}_{_source_stamp(module)}"
    if name not in _DATA_CLASSES:
        _DATA_CLASSES[name] = _new_data_class(name, module.__name__)
    return _DATA_CLASSES[name]


def __getattr__(name: str):
    """A problem-data class by name, for unpickling numba's cache indexes in a new process.

    An index lists the signatures of every family a kernel was compiled for; a
    class whose law is not importable here, or whose source has changed since
    (another hash), comes back as a stand-in that matches no current class, so
    that entry is simply not used.
    """
    if not name.startswith("ProblemData_"):
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    if name in _DATA_CLASSES:
        return _DATA_CLASSES[name]
    try:
        module_name = bytes.fromhex(name.split("_")[1]).decode()
        cls = data_class(importlib.import_module(module_name))
    except Exception:  # noqa: BLE001 - not importable here: a stand-in
        cls = None
    if cls is None or cls.__qualname__ != name:
        cls = _DATA_CLASSES[name] = _new_data_class(name, None)
    return cls


class Law:
    """A problem family's compiled functions, checked, and the class its problems' data take.

    Parameters
    ----------
    source
        The law module: the functions of the table in the module docstring as ``numba.njit``
        functions.

    Attributes
    ----------
    functions
        Name -> the numba dispatcher (callable from Python with the same arguments).
    data_class
        The class of the problems' :attr:`~nsbench.problems.base.HybridProblem.data`.

    Raises
    ------
    ConfigError
        A function missing, not compiled by numba, or that does not compile for its signature.
    """

    def __init__(self, source: ModuleType) -> None:
        from numba.core.dispatcher import Dispatcher

        where = getattr(source, "__name__", repr(source))
        missing = [name for name in REQUIRED if not hasattr(source, name)]
        if missing:
            raise ConfigError(f"the law {where} lacks the compiled function(s) {', '.join(missing)}")
        self.functions = {name: getattr(source, name) for name in NAMES if hasattr(source, name)}
        if "accumulation_limit" not in self.functions:
            self.functions["accumulation_limit"] = no_accumulation_limit
            if not hasattr(source, "accumulation_limit"):
                setattr(source, "accumulation_limit", no_accumulation_limit)
        for name, sig in SIGNATURES:
            fn = self.functions[name]
            if not isinstance(fn, Dispatcher):
                raise ConfigError(f"{where}.{name} is not a numba-compiled function (decorate it with numba.njit)")
            try:
                fn.compile(sig.args)
            except Exception as exc:  # numba's typing errors: say which function and which signature
                first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
                raise ConfigError(f"{where}.{name} does not compile for the signature {sig}: {first}") from None
        self.source = where
        self.data_class = data_class(source)

    def __getattr__(self, name: str):
        try:
            return self.__dict__["functions"][name]
        except KeyError:
            raise AttributeError(name) from None


_LAWS: dict[str, Law] = {}


def law_of(source: ModuleType | str) -> Law:
    """The :class:`Law` of a law module (or its import path), loaded once per process."""
    module = importlib.import_module(source) if isinstance(source, str) else source
    if module.__name__ not in _LAWS:
        _LAWS[module.__name__] = Law(module)
    return _LAWS[module.__name__]


# ---------------------------------------------------------------------- calls from compiled code
def _law_function(prob, name: str):
    """The law module's function ``name`` for compiled code given a problem-data type (at typing time)."""
    cls = getattr(prob, "instance_class", None)
    module = getattr(cls, "__law_module__", None)
    if module is None:
        raise TypingError(f"{prob} is not a problem's data (nsbench.model.law.data_class)")
    return law_of(module).functions[name]


# Each call below is a stub for compiled code: numba resolves it, when it types the call, to the
# function of the law module the problem-data class names (``overload``, inlined).
def rhs(prob, mode, t, y, out):
    """``out = f(t, y)`` in ``mode`` (compiled code only)."""
    raise NotImplementedError("compiled code only")


@overload(rhs, inline="always")
def _rhs(prob, mode, t, y, out):
    fn = _law_function(prob, "rhs")
    return lambda prob, mode, t, y, out: fn(prob.p, mode, t, y, out)


def jacobian(prob, mode, t, y, out):
    """``out = df/dy`` (compiled code only)."""
    raise NotImplementedError("compiled code only")


@overload(jacobian, inline="always")
def _jacobian(prob, mode, t, y, out):
    fn = _law_function(prob, "jacobian")
    return lambda prob, mode, t, y, out: fn(prob.p, mode, t, y, out)


def guard_value(prob, mode, kind, index, t, y):
    """The value of guard ``(kind, index)`` (compiled code only)."""
    raise NotImplementedError("compiled code only")


@overload(guard_value, inline="always")
def _guard_value(prob, mode, kind, index, t, y):
    fn = _law_function(prob, "guard_value")
    return lambda prob, mode, kind, index, t, y: fn(prob.p, mode, kind, index, t, y)


def guard_rate(prob, mode, kind, index, t, y, dy):
    """The rate of guard ``(kind, index)`` along ``dy`` (compiled code only)."""
    raise NotImplementedError("compiled code only")


@overload(guard_rate, inline="always")
def _guard_rate(prob, mode, kind, index, t, y, dy):
    fn = _law_function(prob, "guard_rate")
    return lambda prob, mode, kind, index, t, y, dy: fn(prob.p, mode, kind, index, t, y, dy)


def guards_of(prob, mode, gk, gi, gs):
    """The guards of ``mode`` into the arrays; their number (compiled code only)."""
    raise NotImplementedError("compiled code only")


@overload(guards_of, inline="always")
def _guards_of(prob, mode, gk, gi, gs):
    fn = _law_function(prob, "guards_of")
    return lambda prob, mode, gk, gi, gs: fn(prob.p, mode, gk, gi, gs)


def transition(prob, mode, kind, index, t, y, fresh):
    """Apply the transition of guard ``(kind, index)``; the event kind (compiled code only)."""
    raise NotImplementedError("compiled code only")


@overload(transition, inline="always")
def _transition(prob, mode, kind, index, t, y, fresh):
    fn = _law_function(prob, "transition")
    return lambda prob, mode, kind, index, t, y, fresh: fn(prob.p, mode, kind, index, t, y, fresh)


def initial_mode(prob, t, y, mode):
    """The mode a state starts in, into ``mode`` (compiled code only)."""
    raise NotImplementedError("compiled code only")


@overload(initial_mode, inline="always")
def _initial_mode(prob, t, y, mode):
    fn = _law_function(prob, "initial_mode")
    return lambda prob, t, y, mode: fn(prob.p, t, y, mode)


def start_fresh(prob, mode, t, y, fresh):
    """The ``fresh`` marks of a run's first state (compiled code only)."""
    raise NotImplementedError("compiled code only")


@overload(start_fresh, inline="always")
def _start_fresh(prob, mode, t, y, fresh):
    fn = _law_function(prob, "start_fresh")
    return lambda prob, mode, t, y, fresh: fn(prob.p, mode, t, y, fresh)


def accumulation_limit(prob, mode, kind, index, t, y):
    """The limit behaviour of an accumulation of guard ``(kind, index)``'s events (compiled code only)."""
    raise NotImplementedError("compiled code only")


@overload(accumulation_limit, inline="always")
def _accumulation_limit(prob, mode, kind, index, t, y):
    fn = _law_function(prob, "accumulation_limit")
    return lambda prob, mode, kind, index, t, y: fn(prob.p, mode, kind, index, t, y)


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
        return np.array(y.reshape(1, n)), True  # a writable copy: one type for the compiled rows
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
