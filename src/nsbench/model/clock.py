"""A monotonic clock readable from compiled code, so the loop can time its arc kernels.

numba has no ``time`` module; ``clock_gettime(CLOCK_MONOTONIC)`` (the clock behind
:func:`time.perf_counter` on Linux and macOS) is called by its C symbol, which
keeps the calling functions cacheable on disk (a ctypes pointer would not). A
call costs a few tens of nanoseconds. Where the C library has no
``clock_gettime`` (Windows) the clock reads 0 and kernel times are reported as
unknown.
"""

from __future__ import annotations

import sys
import time

import numpy as np
from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.extending import intrinsic

from nsbench.model.compile import hot

AVAILABLE = sys.platform != "win32"
_CLOCK = int(getattr(time, "CLOCK_MONOTONIC", 1))


@intrinsic
def _clock_gettime(typingctx, clock, buf):
    sig = types.int32(types.int32, buf)

    def codegen(context, builder, signature, args):
        fnty = ir.FunctionType(ir.IntType(32), [ir.IntType(32), ir.IntType(8).as_pointer()])
        fn = cgutils.get_or_insert_function(builder.module, fnty, "clock_gettime")
        ary = context.make_array(signature.args[1])(context, builder, args[1])
        return builder.call(fn, [args[0], builder.bitcast(ary.data, ir.IntType(8).as_pointer())])

    return sig, codegen


if AVAILABLE:

    @hot
    def monotonic_ns(buf):
        """Nanoseconds of the monotonic clock (the origin is arbitrary); ``buf``: two int64 of scratch."""
        _clock_gettime(np.int32(_CLOCK), buf)  # struct timespec {tv_sec, tv_nsec} on 64-bit platforms
        return buf[0] * 1_000_000_000 + buf[1]
else:  # pragma: no cover - Windows

    @hot
    def monotonic_ns(buf):
        return 0
