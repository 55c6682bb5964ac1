"""Compiled functions as values: a jitted function's addresses in an int64 table, called from compiled code.

The loop calls an integrator's arc kernel without importing it: the kernel is
compiled for a fixed signature (:func:`nsbench.model.abi.arc_signature`) and
handed over as a pair of addresses in an int64 array, which :func:`caller`
calls. So the loop never names a kernel and caches on disk. (A jitted function
passed as an argument would make numba key the compiled caller on that
function object, and compile it again in every process; numba's first-class
function values cost tens of microseconds per call to unbox from Python and
add a Python fallback to every call site. An array of addresses unboxes like
any array; a call through it costs a few nanoseconds.)

The pair is numba's own: the address of the function's C wrapper and of the
function itself, which calls through numba's calling convention (errors
propagate). :func:`addresses` compiles the function for the signature first,
from its disk cache when it has one.
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
        raise ImportError(
            f"nsbench needs numba >= 0.61 (first-class functions with a direct entry); "
            f"numba {numba.__version__} is installed"
        )


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
        raise ConfigError(
            f"{dispatcher.py_func.__module__}.{name} does not compile for the signature {signature}: {first}"
        ) from None


def caller(signature) -> Callable:
    """A compiled ``call(jit_addr, args)`` that calls the function at ``jit_addr`` (numba's calling
    convention) with the tuple ``args``, cast to ``signature``'s argument types; errors propagate.

    Leaner than calling a first-class function value, whose lowering adds a fallback through the
    Python interpreter at every call site (code that bloats the callers and keeps small ones from
    being inlined; the address here is never null).
    """
    n_args = len(signature.args)

    @intrinsic
    def call(typingctx, jit_addr, args):
        if not isinstance(args, types.BaseTuple) or len(args) != n_args:
            return None
        for given, wanted in zip(args.types, signature.args):
            if given != wanted and typingctx.can_convert(given, wanted) is None:
                return None

        def codegen(context, builder, sig, llargs):
            address, packed = llargs
            values = [
                context.cast(builder, builder.extract_value(packed, i), given, wanted)
                for i, (given, wanted) in enumerate(zip(args.types, signature.args))
            ]
            fnty = context.call_conv.get_function_type(signature.return_type, signature.args)
            fptr = builder.inttoptr(address, fnty.as_pointer())
            status, result = context.call_conv.call_function(
                builder, fptr, signature.return_type, signature.args, values
            )
            with cgutils.if_unlikely(builder, status.is_error):
                context.call_conv.return_status_propagate(builder, status)
            return result

        return signature.return_type(types.int64, args), codegen

    return call


def table(functions: Mapping[int, tuple[Any, Any]], size: int) -> np.ndarray:
    """An int64 table of ``2 * size`` addresses: slot ``k`` at ``[2k, 2k + 1]``, zero where absent.

    ``functions`` maps a slot to ``(dispatcher, signature)``.
    """
    out = np.zeros(2 * size, np.int64)
    for slot, (dispatcher, signature) in functions.items():
        out[2 * slot], out[2 * slot + 1] = addresses(dispatcher, signature)
    return out
