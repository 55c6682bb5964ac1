"""SUNDIALS' C API through ctypes, on the shared libraries scikit-sundae's wheel ships, and calls of it from numba.

Why this binding (docs/core.md, "SUNDIALS natively: the binding"): scikit-sundae, a
dependency already, ships SUNDIALS 7 as shared libraries beside its extension
modules (``scikit_sundae.libs/libsundials_{core,cvode,ida}-<hash>.so.<version>`` in
the Linux wheel; ``libsundials_cvode`` and ``libsundials_ida`` carry their own serial
vectors, dense matrix and dense linear solver). Its Python API takes Python
callables only; ``sundials4py`` (the official bindings) needs Python >= 3.12 and
takes Python callables too; ``pycvodes`` and ``scikits-odes`` build against a
system SUNDIALS. So the libraries are loaded here with ctypes and driven through
their C API: the right-hand sides, Jacobians and root functions are numba
``cfunc`` pointers (:mod:`nsbench.integrators._sundials_callbacks`), and the event
loop calls ``CVode``/``IDASolve`` by address from compiled code (:func:`c_function`).

The library names are the wheel's internal ones (hashed by auditwheel): they are
found by pattern, and the binding is refused, with a reason, when a library is
missing or ambiguous, is not SUNDIALS 7, or a function the native path calls is
absent. The caller then runs the per-arc path and says why (:func:`load`).

What a binding owns (:class:`Owned`): the ``SUNContext``, vectors, matrix, linear
solver and solver memory it creates, freed in the reverse order by ``close`` or,
at the latest, when the owner is collected (``weakref.finalize``).
"""

from __future__ import annotations

import ctypes
import glob
import importlib.util
import os
import re
import weakref
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Literal

import numpy as np
from llvmlite import ir
from numba import types
from numba.extending import intrinsic

#: The SUNDIALS major version whose C API this module is written for (7: ``SUNContext`` first argument,
#: ``SUNComm`` an ``int`` without MPI, ``sunrealtype`` a double).
MAJOR = 7
#: The libraries the native path loads, by their base names in the wheel.
LIBRARIES = ("core", "cvode", "ida")

# ---------------------------------------------------------------------- constants of the C API (cvode.h, ida.h)
CV_ADAMS, CV_BDF = 1, 2
CV_NORMAL, CV_ONE_STEP = 1, 2
IDA_NORMAL, IDA_ONE_STEP = 1, 2
SUCCESS, TSTOP_RETURN, ROOT_RETURN = 0, 1, 2  # the same values in CVODE and IDA

#: Functions the compiled loop calls by address, per solver: the slots of the address table
#: (:attr:`Binding.table`), and their C signatures for :func:`c_function`.
CALLS = (
    "N_VGetArrayPointer",
    "SUNDenseMatrix_Data",
    "CVode",
    "CVodeReInit",
    "CVodeSetStopTime",
    "CVodeGetRootInfo",
    "CVodeGetDky",
    "CVodeGetNumRhsEvals",
    "CVodeGetNumJacEvals",
    "IDASolve",
    "IDAReInit",
    "IDASetStopTime",
    "IDAGetRootInfo",
    "IDAGetDky",
    "IDAGetNumResEvals",
    "IDAGetNumJacEvals",
    "IDASetId",
)
SLOT = {name: k for k, name in enumerate(CALLS)}


class BindingUnavailable(RuntimeError):
    """The native SUNDIALS binding cannot be used here; the message says why in one line."""


def _wheel_library_dirs() -> list[Path]:
    """Where scikit-sundae's wheel keeps its bundled libraries (without importing it)."""
    spec = importlib.util.find_spec("sksundae")
    if spec is None or spec.origin is None:
        raise BindingUnavailable("scikit-sundae is not installed")
    package = Path(spec.origin).parent
    # auditwheel (Linux): <site-packages>/scikit_sundae.libs; delocate (macOS): sksundae/.dylibs
    return [package.parent / "scikit_sundae.libs", package / ".dylibs"]


def find_library(name: str, dirs: list[Path] | None = None) -> Path:
    """The path of ``libsundials_<name>`` in the wheel: exactly one file named
    ``libsundials_<name>[-<hash>].so[.<version>]`` (or ``.dylib``)."""
    pattern = re.compile(rf"^libsundials_{name}(-[0-9a-f]+)?(\.so(\.[0-9.]+)?|(\.[0-9.]+)?\.dylib)$")
    found: list[Path] = []
    for d in dirs if dirs is not None else _wheel_library_dirs():
        found.extend(Path(p) for p in sorted(glob.glob(os.path.join(str(d), f"libsundials_{name}*"))))
    matches = sorted({p for p in found if pattern.match(p.name)})
    if not matches:
        raise BindingUnavailable(f"no libsundials_{name} in scikit-sundae's wheel (looked for libsundials_{name}-*.so)")
    if len(matches) > 1:
        raise BindingUnavailable(
            f"several libsundials_{name} in scikit-sundae's wheel: {', '.join(p.name for p in matches)}"
        )
    return matches[0]


def _version(core: ctypes.CDLL) -> tuple[int, int, int]:
    major, minor, patch = ctypes.c_int(), ctypes.c_int(), ctypes.c_int()
    label = ctypes.create_string_buffer(64)
    core.SUNDIALSGetVersionNumber.restype = ctypes.c_int
    flag = core.SUNDIALSGetVersionNumber(
        ctypes.byref(major), ctypes.byref(minor), ctypes.byref(patch), label, ctypes.c_int(len(label))
    )
    if flag != 0:
        raise BindingUnavailable(f"SUNDIALSGetVersionNumber failed ({flag})")
    return major.value, minor.value, patch.value


def _index_type() -> Any:
    """``sunindextype`` of the wheel's build, as scikit-sundae's build records it (``int`` or ``long int``)."""
    try:
        from sksundae import _cy_common
    except ImportError as exc:  # pragma: no cover - scikit-sundae is a dependency
        raise BindingUnavailable(f"scikit-sundae does not import: {exc}") from None
    name = str(getattr(_cy_common, "SUNDIALS_INT_TYPE", "")).strip()
    types_ = {"int": ctypes.c_int32, "int32_t": ctypes.c_int32, "long int": ctypes.c_int64, "int64_t": ctypes.c_int64}
    if name not in types_:
        raise BindingUnavailable(f"scikit-sundae's SUNDIALS has an index type this binding does not know ({name!r})")
    if getattr(_cy_common, "SUNDIALS_FLOAT_TYPE", "double") != "double":
        raise BindingUnavailable(f"scikit-sundae's SUNDIALS computes in {_cy_common.SUNDIALS_FLOAT_TYPE}, not double")
    return types_[name]


@dataclass
class Binding:
    """The loaded libraries, the SUNDIALS version, and the C functions the native path uses."""

    paths: dict[str, Path]
    version: tuple[int, int, int]
    index: Any  # ctypes type of sunindextype
    libs: dict[str, ctypes.CDLL]
    #: Addresses of :data:`CALLS` (int64), for the compiled loop.
    table: np.ndarray = field(default_factory=lambda: np.zeros(len(CALLS), np.int64))

    @property
    def version_text(self) -> str:
        return ".".join(str(v) for v in self.version)

    def fn(self, lib: str, name: str, restype: Any, *argtypes: Any) -> Callable:
        """The C function ``name`` of library ``lib``, typed."""
        f = getattr(self.libs[lib], name)
        f.restype, f.argtypes = restype, list(argtypes)
        return f

    def flag_name(self, solver: str, flag: int) -> str:
        """SUNDIALS' name of a return flag (``CV_TOO_MUCH_WORK``, ...)."""
        lib, getter = ("cvode", "CVodeGetReturnFlagName") if solver == "cvode" else ("ida", "IDAGetReturnFlagName")
        f = self.fn(lib, getter, ctypes.c_void_p, ctypes.c_long)
        ptr = f(int(flag))
        if not ptr:
            return f"flag {flag}"
        try:
            return ctypes.string_at(ptr).decode("ascii", "replace")
        finally:
            _libc_free(ptr)  # the name is malloc'ed by SUNDIALS


def _libc_free(ptr: int) -> None:
    libc = ctypes.CDLL(None)
    libc.free.argtypes = [ctypes.c_void_p]
    libc.free(ptr)


_BINDING: dict[str, Binding | BindingUnavailable] = {}


def load() -> Binding:
    """The binding, loaded once per process; :class:`BindingUnavailable` (with its reason) if it cannot be."""
    if "b" not in _BINDING:
        try:
            _BINDING["b"] = _load()
        except BindingUnavailable as exc:
            _BINDING["b"] = exc
        except OSError as exc:  # a library that does not load (a broken install, another platform's file)
            _BINDING["b"] = BindingUnavailable(f"SUNDIALS' libraries do not load: {exc}")
    got = _BINDING["b"]
    if isinstance(got, BindingUnavailable):
        raise got
    return got


def unavailable() -> str | None:
    """Why the native binding cannot be used here, or ``None`` if it can."""
    try:
        load()
    except BindingUnavailable as exc:
        return str(exc)
    return None


def _load() -> Binding:
    paths = {name: find_library(name) for name in LIBRARIES}
    mode = getattr(os, "RTLD_GLOBAL", 0)  # core first and global: the solvers' libraries resolve it
    libs = {name: ctypes.CDLL(str(paths[name]), mode=mode) for name in LIBRARIES}
    version = _version(libs["core"])
    if version[0] != MAJOR:
        raise BindingUnavailable(
            f"scikit-sundae ships SUNDIALS {'.'.join(map(str, version))}; the native path is written for SUNDIALS {MAJOR}"
        )
    binding = Binding(paths, version, _index_type(), libs)
    where = {"N_VGetArrayPointer": "core", "SUNDenseMatrix_Data": "cvode"}
    for k, name in enumerate(CALLS):
        lib = where.get(name, "cvode" if name.startswith("CVode") else "ida")
        try:
            binding.table[k] = ctypes.cast(getattr(libs[lib], name), ctypes.c_void_p).value
        except AttributeError:
            raise BindingUnavailable(f"{paths[lib].name} has no {name}") from None
    return binding


# ---------------------------------------------------------------------- owning what is created
class Owned:
    """SUNDIALS objects created for one solver, freed in the reverse order of their creation.

    ``add(pointer, free)`` registers an object with the function that frees it;
    :meth:`close` frees them all (at most once), and so does the garbage collector
    when the owner goes (``weakref.finalize``), so no run leaks them.
    """

    def __init__(self) -> None:
        self._items: list[tuple[int, Callable[[int], None]]] = []
        self._finalizer = weakref.finalize(self, Owned._free_all, self._items)

    def add(self, pointer: int | None, free: Callable[[int], None], what: str) -> int:
        if not pointer:
            self.close()
            raise MemoryError(f"SUNDIALS could not create the {what}")
        self._items.append((int(pointer), free))
        return int(pointer)

    @property
    def alive(self) -> int:
        """How many objects are held (0 once closed)."""
        return len(self._items)

    @staticmethod
    def _free_all(items: list[tuple[int, Callable[[int], None]]]) -> None:
        while items:
            pointer, free = items.pop()
            free(pointer)

    def close(self) -> None:
        Owned._free_all(self._items)


# ---------------------------------------------------------------------- calls from compiled code
_LL = {
    "i32": ir.IntType(32),
    "i64": ir.IntType(64),
    "f64": ir.DoubleType(),
    "p": ir.IntType(8).as_pointer(),
    "v": ir.VoidType(),
}
_NB = {"i32": types.int32, "i64": types.int64, "f64": types.float64, "p": types.int64, "v": types.none}


def c_function(spec: str) -> Callable:
    """A compiled ``call(address, (args...))`` of the C function at ``address`` with the C signature ``spec``.

    ``spec`` is ``'ret(arg, ...)'`` with ``i32`` (C ``int``), ``i64`` (``long`` on LP64,
    ``int64_t``), ``f64`` (``double``), ``p`` (any pointer) and ``v`` (``void``, as a
    return). Pointers are handed and returned as int64 addresses; integers and
    doubles are converted to the declared type. The address is data, never a
    constant in the code, so the functions calling this stay cacheable on disk.
    """
    m = re.fullmatch(r"(\w+)\(([\w, ]*)\)", spec.replace(" ", ""))
    if m is None:
        raise ValueError(f"bad C signature {spec!r}")
    ret = m.group(1)
    args = [a for a in m.group(2).split(",") if a]

    @intrinsic
    def call(typingctx, address, values):
        if not isinstance(address, types.Integer) or not isinstance(values, types.BaseTuple):
            return None
        if len(values) != len(args):
            return None
        for given in values.types:
            if not isinstance(given, (types.Integer, types.Float, types.Boolean)):
                return None

        def codegen(context, builder, sig, llargs):
            addr, packed = llargs
            vals = []
            for i, (given, kind) in enumerate(zip(values.types, args)):
                v = builder.extract_value(packed, i)
                if kind == "p":
                    v = context.cast(builder, v, given, types.int64)
                    v = builder.inttoptr(v, _LL["p"])
                else:
                    v = context.cast(builder, v, given, _NB[kind])
                vals.append(v)
            fnty = ir.FunctionType(_LL[ret], [_LL[a] for a in args])
            a64 = context.cast(builder, addr, address, types.int64)
            fptr = builder.inttoptr(a64, fnty.as_pointer())
            out = builder.call(fptr, vals)
            if ret == "p":
                return builder.ptrtoint(out, _LL["i64"])
            if ret == "v":
                return context.get_dummy_value()
            return out

        return _NB[ret](address, values), codegen

    return call


def _view_intrinsic(dtype: Any, ndim: int, layout: Literal["C", "F"]) -> Callable:
    """``view(address, shape)``: an array of ``dtype`` over memory at ``address`` that nsbench or SUNDIALS
    owns (no meminfo: never freed through it), usable in functions compiled without reference counting
    (``numba.carray`` is not: its implementation returns an array it did not receive)."""
    aryty = types.Array(dtype, ndim, layout)

    @intrinsic
    def view(typingctx, address, shape):
        if not isinstance(address, types.Integer) or not isinstance(shape, types.BaseTuple) or len(shape) != ndim:
            return None

        def codegen(context, builder, sig, llargs):
            from numba.np.arrayobj import populate_array

            addr, shp = llargs
            a64 = context.cast(builder, addr, address, types.int64)
            data = builder.inttoptr(a64, context.get_value_type(types.CPointer(dtype)))
            dims = [
                context.cast(builder, builder.extract_value(shp, i), shape.types[i], types.intp) for i in range(ndim)
            ]
            itemsize = context.get_abi_sizeof(context.get_data_type(dtype))
            intp = context.get_value_type(types.intp)
            strides = [None] * ndim
            step = ir.Constant(intp, itemsize)
            order = range(ndim - 1, -1, -1) if layout == "C" else range(ndim)
            for i in order:
                strides[i] = step
                step = builder.mul(step, dims[i])
            ary = context.make_array(aryty)(context, builder)
            populate_array(
                ary, data=data, shape=dims, strides=strides, itemsize=ir.Constant(intp, itemsize), meminfo=None
            )
            return ary._getvalue()

        return aryty(address, shape), codegen

    return view


#: Views of memory by address: 1-d float64 and int64, 2-d float64 in C (row-major) and Fortran order.
f64_view = _view_intrinsic(types.float64, 1, "C")
i64_view = _view_intrinsic(types.int64, 1, "C")
f64_matrix = _view_intrinsic(types.float64, 2, "C")
f64_fmatrix = _view_intrinsic(types.float64, 2, "F")


@intrinsic
def address_of(typingctx, pointer):
    """A ``void*`` (or any C pointer) as an int64 address."""
    if not isinstance(pointer, (types.CPointer, types.RawPointer)):
        return None

    def codegen(context, builder, sig, llargs):
        return builder.ptrtoint(llargs[0], ir.IntType(64))

    return types.int64(pointer), codegen
