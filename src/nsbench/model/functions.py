"""Compiled functions as values: a jitted function's addresses in an int64 table, called from compiled code.

The core calls a problem's law and an integrator's arc kernel without importing
either: each is compiled for a fixed signature (:mod:`nsbench.model.abi`) and
handed over as a pair of addresses in an int64 array; an intrinsic turns the
pair back into a callable first-class function. So one compiled loop serves
every problem and every kernel and caches on disk. (A jitted function passed
as an argument would make numba key the compiled caller on that function
object, and compile it again in every process; a function table built from
numba's wrapper-address protocol costs tens of microseconds per call to unbox.
An array of addresses unboxes like any array; a call through it costs a few
nanoseconds.)

The pair is numba's own: the address of the function's C wrapper and of the
function itself, which calls through numba's calling convention (errors
propagate). ``addresses`` compiles the function for the signature first, from
its disk cache when it has one.
"""

from __future__ import annotations

from typing import Any, Callable, Mapping

import numpy as np
from numba import types
from numba.core import cgutils
from numba.core.datamodel import default_manager
from numba.extending import intrinsic

from nsbench.errors import ConfigError

_MEMBERS = ("c_addr", "py_addr", "jit_addr")


def _check_numba() -> None:
    """nsbench needs numba's first-class functions with a direct (``jit_addr``) entry (numba >= 0.61)."""
    import numba
    import numba.experimental.function_type  # noqa: F401 - registers the data model of first-class functions

    model = default_manager.lookup(types.FunctionType(types.void()))
    names = tuple(getattr(model, "_fields", ()))
    if names != _MEMBERS:
        raise ImportError(f"nsbench needs numba >= 0.61 (first-class functions with a direct entry); "
                          f"numba {numba.__version__} is installed")


_check_numba()


def addresses(dispatcher: Any, signature: Any) -> tuple[int, int]:
    """``(C wrapper address, direct address)`` of ``dispatcher`` compiled for ``signature``.

    Raises
    ------
    ConfigError
        ``dispatcher`` is not a numba-compiled function, or does not compile for the signature.
    """
    from numba.core.dispatcher import Dispatcher
    from numba.experimental.function_type import _get_jit_address, _get_wrapper_address

    if not isinstance(dispatcher, Dispatcher):
        raise ConfigError(f"{dispatcher!r} is not a numba-compiled function (decorate it with numba.njit)")
    try:
        return int(_get_wrapper_address(dispatcher, signature)), int(_get_jit_address(dispatcher, signature))
    except Exception as exc:  # numba's typing errors: say which function and which signature
        name = getattr(dispatcher, "__qualname__", repr(dispatcher))
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise ConfigError(f"{dispatcher.py_func.__module__}.{name} does not compile for the signature "
                          f"{signature}: {first}") from None


def caster(fntype: types.FunctionType) -> Callable:
    """A compiled ``f(c_addr, jit_addr)`` that returns the function of type ``fntype`` at those addresses."""

    @intrinsic
    def as_function(typingctx, c_addr, jit_addr):
        def codegen(context, builder, signature, args):
            c, j = args
            fn = cgutils.create_struct_proxy(fntype)(context, builder)
            voidptr = context.get_value_type(types.voidptr)
            fn.c_addr = builder.inttoptr(c, voidptr)
            fn.py_addr = cgutils.get_null_value(voidptr)
            fn.jit_addr = builder.inttoptr(j, voidptr)
            return fn._getvalue()

        return fntype(types.int64, types.int64), codegen

    return as_function


@intrinsic
def any_layout(typingctx, array):
    """The same array typed with layout ``'A'`` (free: the data model does not depend on the layout).

    The law's functions take arrays of any layout (a kernel passes rows of its
    scratch, views whose type numba cannot prove contiguous); a first-class
    function call wants its argument types exactly, so callers cast.
    """
    if not isinstance(array, types.Array):
        return None
    result = array.copy(layout="A")

    def codegen(context, builder, signature, args):
        from numba.core.imputils import impl_ret_borrowed

        return impl_ret_borrowed(context, builder, result, args[0])

    return result(array), codegen


def table(functions: Mapping[int, tuple[Any, Any]], size: int) -> np.ndarray:
    """An int64 table of ``2 * size`` addresses: slot ``k`` at ``[2k, 2k + 1]``, zero where absent.

    ``functions`` maps a slot to ``(dispatcher, signature)``.
    """
    out = np.zeros(2 * size, np.int64)
    for slot, (dispatcher, signature) in functions.items():
        out[2 * slot], out[2 * slot + 1] = addresses(dispatcher, signature)
    return out
