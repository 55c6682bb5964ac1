"""The messages between a parent and its worker processes, and their framing.

A worker is our own child (:mod:`nsbench.workers.worker`), so messages are
pickled objects: an 8-byte big-endian length, then the pickle. Classes travel by
reference, so a worker can unpickle only what it can import (hence the runner's
rule on components defined in ``__main__``).

This floor knows no app: a task is either a :class:`Call` (a function named by
its module, as the sweeps, Lyapunov ensembles, the conformance kit and
continuation send) or any message with a ``task`` number and a
``perform(context)`` method (:class:`Task`; the suite runner's own tasks live in
:mod:`nsbench.bench.tasks`), which the worker imports when it unpickles it.

Parent to worker: :class:`Hello` (once), then tasks and :class:`Stop`. Worker to
parent: :class:`Ready` or :class:`InitFailed` (once), then any number of
:class:`Stage`, :class:`Compiling` and :class:`Partial` per task and exactly one :class:`Done`,
:class:`Failed` or :class:`Interrupted`. A worker forked from a factory gets no
:class:`Hello` (the factory had it) and starts with its :class:`Ready`.

Parent to worker factory, on its control socket: :class:`Hello`, :class:`Call`
(a preparation, run in the factory), :class:`Fork`, :class:`Kill`, :class:`Stop`;
factory to parent: :class:`Exited`.
"""

from __future__ import annotations

import math
import os
import pickle
import struct
from dataclasses import dataclass
from typing import Any, BinaryIO, Protocol

_HEADER = struct.Struct(">Q")


# ---------------------------------------------------------------- parent -> worker
@dataclass(frozen=True)
class Hello:
    """First message: the parent's ``sys.path``, its runtime registrations, where rows go.

    ``components`` is a separate pickle so that the worker can extend its path
    before it imports the modules the components live in. A worker stores the
    rows it times itself (``out``, with ``provenance``), so that the parent stays
    idle while others are timing.
    """

    sys_path: list[str]
    components: bytes
    out: str
    provenance: dict[str, Any]


class Context(Protocol):
    """What a worker hands a :class:`Task`'s ``perform``."""

    hello: Hello

    def stage(self, what: str, limit: float | None) -> None:
        """Announce the step ``what`` and the wall-clock seconds it may take (``None``: not limited)."""

    def emit(self, item: Any) -> None:
        """Send ``item``, a finished part of the result, at once (kept if the task is stopped later)."""


class Task(Protocol):
    """A task message an app defines: its number, and what the worker does with it."""

    task: int

    def perform(self, context: Context) -> Any:
        """Do the task in the worker; the return value goes back in :class:`Done`."""


@dataclass(frozen=True)
class Call:
    """Run ``target(*args, stage=..., emit=...)``, ``target`` given as ``'module:function'``.

    The generic task of :mod:`nsbench.workers.jobs` (sweep values, Lyapunov members):
    ``stage(what, limit)`` announces a step and its hard limit, ``emit(item)``
    sends a finished part of the result at once (kept if the task is stopped later).
    """

    task: int
    target: str
    args: tuple = ()


@dataclass(frozen=True)
class Stop:
    pass


# ---------------------------------------------------------------- worker -> parent
@dataclass(frozen=True)
class Ready:
    pid: int


@dataclass(frozen=True)
class InitFailed:
    error: str


@dataclass(frozen=True)
class Stage:
    """The worker starts ``what`` (``'setup'``, ``'warm-up run'``, ``'timed run 2 of 3'``).

    ``limit`` is the wall-clock seconds it may take (``None``: not limited); the
    parent stops the worker past it.
    """

    task: int
    what: str
    limit: float | None


#: Longest wall-clock time a compilation holds a stage's clock (seconds): past it the parent stops the
#: worker as it would past the stage's own limit. Compiling the whole core once takes minutes on a
#: busy machine; this bounds only a compilation that never ends.
COMPILE_LIMIT = 1800.0


@dataclass(frozen=True)
class Compiling:
    """The worker's task starts (``active``) or ends compiling with numba.

    Compilation is nsbench's first-use cost, not the task's: the parent holds the stage's clock
    while it lasts (:func:`held`), so that a warm-up run, a sweep value or a Lyapunov member that
    compiles on a fresh install is not stopped by a limit meant for the method's run.
    """

    task: int
    active: bool


def held(
    deadline: float | None, left: float | None, message: Compiling, now: float
) -> tuple[float | None, float | None]:
    """A stage's deadline and the seconds it had left, across a :class:`Compiling` message.

    ``deadline`` is the stage's (``None`` or ``inf``: not limited), ``left`` the seconds it had
    when a compilation began (``None``: none holds it). When a compilation begins the deadline
    becomes :data:`COMPILE_LIMIT` from ``now`` and what the stage had left is kept; when it ends
    the stage gets back what it had left. An unlimited stage stays unlimited.
    """
    if message.active:
        if left is None and deadline is not None and math.isfinite(deadline):
            return now + COMPILE_LIMIT, max(0.0, deadline - now)
        return deadline, left
    if left is not None:
        return now + left, None
    return deadline, None


@dataclass(frozen=True)
class Partial:
    """A finished part of a :class:`Call`'s result, sent before the task ends."""

    task: int
    item: Any


@dataclass(frozen=True)
class Done:
    task: int
    result: Any


@dataclass(frozen=True)
class Failed:
    """A task raised an exception that the task itself did not turn into a result (a bug).

    ``detail`` is its traceback: the parent writes it to a log file in the output folder and says
    so in one line (a worker prints nothing of its own on the terminal it shares with the command).
    """

    task: int
    error: str
    detail: str = ""


@dataclass(frozen=True)
class Interrupted:
    """A task raised ``KeyboardInterrupt``: the parent stops the run as if interrupted."""

    task: int


# ---------------------------------------------------------------- parent <-> worker factory
#: The largest record on a factory's control socket (a Hello carries the runner's path and runtime
#: registrations); the runner starts its workers alone rather than send a larger one.
MAX_CONTROL_RECORD = 1 << 22


# A worker factory (:mod:`nsbench.workers.factory`) imports and prepares once, then forks the
# workers of :mod:`nsbench.workers.jobs`; these travel on its control socket, one record each.
@dataclass(frozen=True)
class Fork:
    """Start a worker from the factory: its channels are the two file descriptors sent with this
    record (what the parent writes, what it reads); ``token`` names it in :class:`Kill` and
    :class:`Exited`."""

    token: int


@dataclass(frozen=True)
class Kill:
    """End the worker ``token`` now (a time limit, an interrupt)."""

    token: int


@dataclass(frozen=True)
class Exited:
    """Factory to parent: the worker ``token`` has ended; ``reason`` as :func:`nsbench.workers.pool.describe_exit`
    words it (``'exit code 3'``, ``'signal 11 (SIGSEGV)'``), or why it could not be started."""

    token: int
    reason: str


# ---------------------------------------------------------------- framing
def write_message(stream: BinaryIO, message: Any) -> None:
    """Write one message to a buffered binary stream and flush it."""
    data = pickle.dumps(message, protocol=pickle.HIGHEST_PROTOCOL)
    stream.write(_HEADER.pack(len(data)) + data)
    stream.flush()


def read_message(stream: BinaryIO) -> Any:
    """Read one message; ``EOFError`` if the other side has closed the pipe."""
    return pickle.loads(_read_exact(stream, _HEADER.unpack(_read_exact(stream, _HEADER.size))[0]))


def _read_exact(stream: BinaryIO, n: int) -> bytes:
    chunks, left = [], n
    while left:
        chunk = stream.read(left)  # a raw stream may return fewer bytes than asked
        if not chunk:
            raise EOFError("the other end of the pipe is closed")
        chunks.append(chunk)
        left -= len(chunk)
    return b"".join(chunks)


def write_fd(fd: int, message: Any) -> None:
    """Write one message to a raw file descriptor (the parent's side of a worker's stdin)."""
    data = pickle.dumps(message, protocol=pickle.HIGHEST_PROTOCOL)
    view = memoryview(_HEADER.pack(len(data)) + data)
    while view:
        view = view[os.write(fd, view) :]
