"""The compiled loop's call back into Python, for integrators whose arcs run in Python.

An integrator without a compiled arc kernel (``heyoka``, SUNDIALS, scipy) runs its
``advance`` in Python once per arc. Returning from the compiled loop for that and
entering it again costs numba's unboxing of every array of the run's bundles (about
40 of them: 2 us warm, 6 us on caches a heyoka step has just cooled), paid once per
arc. Instead the loop calls :func:`python_arc`, a small object-mode block that
runs the arc runner of the current run (:func:`running`) and returns its code,
about 0.6 us. The runner reads and writes the run's arrays through the Python
objects it already holds: they share their memory with the loop's views.

The runners are kept on a per-thread stack, so runs on several threads and a run
started inside another run's arc each reach their own.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager

import numba

from nsbench.model.compile import with_gil

#: The arc is stored in the run's arc slots: the loop goes on.
ARC_STORED = 0
#: The arc is stored, but a record buffer was replaced (grown): the loop returns to be entered again.
ARC_STORED_REENTER = 1

_LOCAL = threading.local()


@contextmanager
def running(runner: Callable[[], int]) -> Iterator[None]:
    """Make ``runner`` the arc runner that :func:`python_arc` calls on this thread, for the ``with`` block."""
    stack = getattr(_LOCAL, "stack", None)
    if stack is None:
        stack = _LOCAL.stack = []
    stack.append(runner)
    try:
        yield
    finally:
        stack.pop()


def run_current_arc() -> int:
    """Run one arc with this thread's current runner (called from compiled code)."""
    return _LOCAL.stack[-1]()


# The loop that calls it releases the GIL; the object-mode block takes it back while Python runs the arc.
@with_gil
def python_arc() -> int:
    """Run the current arc in Python (:func:`run_current_arc`); its code (``ARC_STORED``...)."""
    with numba.objmode(code="int64"):
        code = run_current_arc()
    return code
