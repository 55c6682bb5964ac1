"""A worker process: ``python -m nsbench.workers.worker``.

The runner starts workers with :mod:`subprocess`, never with ``multiprocessing``,
so a worker never imports the user's ``__main__`` (a script without a
``if __name__ == "__main__":`` guard would otherwise run again in every worker).
The worker speaks :mod:`nsbench.workers.protocol` on private duplicates of its
stdin and stdout; file descriptor 1 is then pointed at stderr, so whatever an
integrator prints (Python or C) cannot corrupt the protocol.

It ignores SIGINT: on Ctrl-C the runner keeps the finished rows and ends its
workers itself. If the runner disappears without ending it (killed), the worker
notices within a second and exits; it never stores a row once its parent is
gone: a task still in the pipe when the parent died would otherwise fail on
its first message to the parent and leave an ``error`` row that a resumed run
takes for a result.
"""

from __future__ import annotations

import faulthandler
import os
import pickle
import signal
import sys
import threading
import time
import traceback
from typing import Any, BinaryIO

from nsbench.workers import protocol as msg

#: The process that started this worker (set by :func:`main`); ``None`` when served in-process (tests).
_PARENT: int | None = None
#: The task in hand and the stream to its parent, while :func:`serve_tasks` runs one (for :func:`_compiling`).
_IN_HAND: tuple[int, BinaryIO] | None = None


class ParentGone(BaseException):
    """The parent has ended: nothing of the task in hand may be reported or stored.

    A ``BaseException``, so that a case's own error handling (which turns an
    ``Exception`` into an ``error`` row) lets it through.
    """


def _parent_alive() -> bool:
    return _PARENT is None or os.getppid() == _PARENT


def _send(out: BinaryIO, message: Any) -> None:
    """Write ``message`` to the parent; :class:`ParentGone` if it is not there to read it."""
    if not _parent_alive():
        raise ParentGone
    try:
        msg.write_message(out, message)
    except (BrokenPipeError, ConnectionResetError) as exc:
        raise ParentGone from exc


def _channels() -> tuple[BinaryIO, BinaryIO]:
    """The protocol streams; fds 0 and 1 are then /dev/null and stderr."""
    inp = os.fdopen(os.dup(0), "rb")
    out = os.fdopen(os.dup(1), "wb")
    devnull = os.open(os.devnull, os.O_RDONLY)
    os.dup2(devnull, 0)
    os.close(devnull)
    os.dup2(2, 1)
    return inp, out


def register(hello: msg.Hello) -> None:
    """Take the runner's path and runtime registrations (a worker's first message)."""
    from nsbench import registry

    sys.path[:] = [p for p in hello.sys_path] + [p for p in sys.path if p not in hello.sys_path]
    for kind, objs in pickle.loads(hello.components).items():
        for name, obj in objs.items():
            registry.register(kind, name, obj)  # the parent's runtime registrations follow the work


class _Context:
    """A task's :class:`~nsbench.workers.protocol.Context`: its stages and parts go to the parent at once."""

    def __init__(self, task: int, out: BinaryIO, hello: msg.Hello) -> None:
        self.task, self.out, self.hello = task, out, hello

    def stage(self, what: str, limit: float | None) -> None:
        _send(self.out, msg.Stage(self.task, what, limit))

    def emit(self, item: Any) -> None:
        _send(self.out, msg.Partial(self.task, item))


def _handle(task: Any, out: BinaryIO, hello: msg.Hello) -> Any:
    # each kind of task imports what it needs: a sweep's worker (``Call``) never needs the suite
    # runner's modules, whose pandas alone is a quarter of a second of every worker's start
    context = _Context(task.task, out, hello)
    if isinstance(task, msg.Call):
        import importlib

        module, _, name = task.target.partition(":")
        target = getattr(importlib.import_module(module), name)
        return target(*task.args, stage=context.stage, emit=context.emit)
    perform = getattr(task, "perform", None)
    if perform is None:
        raise TypeError(f"unknown task {task!r}: neither a Call nor a message with perform(context)")
    return perform(context)


def serve(inp: BinaryIO, out: BinaryIO) -> None:
    """Answer tasks until :class:`~nsbench.workers.protocol.Stop` or the end of the input."""
    try:
        hello = msg.read_message(inp)
        register(hello)
    except Exception as exc:  # e.g. a component whose module this process cannot import
        msg.write_message(out, msg.InitFailed(f"{type(exc).__name__}: {exc}"))
        return
    msg.write_message(out, msg.Ready(os.getpid()))
    serve_tasks(inp, out, hello)


def _compiling(active: bool) -> None:
    """Tell the parent that the task in hand starts or ends compiling: it holds the stage's limit meanwhile."""
    if _IN_HAND is not None:
        task, out = _IN_HAND
        _send(out, msg.Compiling(task, active))


def serve_tasks(inp: BinaryIO, out: BinaryIO, hello: msg.Hello) -> None:
    """Answer tasks until :class:`~nsbench.workers.protocol.Stop` or the end of the input (after the Ready)."""
    global _IN_HAND
    from nsbench import compiling

    compiling.watch(_compiling)
    while True:
        try:
            task = msg.read_message(inp)
        except EOFError:  # the parent is gone
            return
        if isinstance(task, msg.Stop):
            return
        try:
            _IN_HAND = (task.task, out)
            result = _handle(task, out, hello)
        except ParentGone:
            return
        except KeyboardInterrupt:
            msg.write_message(out, msg.Interrupted(task.task))
            continue
        except Exception as exc:  # a bug outside the task's own guard: report it (with its traceback), keep serving
            msg.write_message(out, msg.Failed(task.task, f"{type(exc).__name__}: {exc}", traceback.format_exc()))
            continue
        finally:
            _IN_HAND = None
        msg.write_message(out, msg.Done(task.task, result))


def _exit_with_parent(parent: int) -> None:
    """End this process once its parent is gone (a blocked or busy worker would not notice)."""
    while os.getppid() == parent:
        time.sleep(1.0)
    os._exit(0)


def _watch_parent() -> None:
    global _PARENT
    _PARENT = os.getppid()
    threading.Thread(target=_exit_with_parent, args=(_PARENT,), daemon=True).start()


def main() -> None:
    _watch_parent()
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    faulthandler.enable()  # a crash in compiled code leaves a traceback on stderr
    inp, out = _channels()
    try:
        serve(inp, out)
    except BrokenPipeError:  # the parent has ended: nothing left to report to
        pass
    except Exception:
        traceback.print_exc()
        raise
    # Asked to stop (or the parent is gone), with every result written: leave without the
    # interpreter's clean-up of a thousand modules and the compiled code (about 0.4 s, which a
    # command ending its workers would wait for). Nothing of a worker's is left to flush but stderr.
    sys.stderr.flush()
    os._exit(0)


def run_forked(inp_fd: int, out_fd: int, hello: msg.Hello, init_error: str = "") -> None:
    """Serve as a worker forked from a factory (:mod:`nsbench.workers.factory`), on the channels the parent
    sent it; never returns. The factory is this process's parent: once it is gone (it leaves when the
    runner does) the worker ends, as a worker started by the runner ends with the runner."""
    code = 0
    try:
        _watch_parent()  # the factory's watcher thread is not in this process: threads do not survive a fork
        inp, out = os.fdopen(inp_fd, "rb"), os.fdopen(out_fd, "wb")
        if init_error:
            msg.write_message(out, msg.InitFailed(init_error))
        else:
            msg.write_message(out, msg.Ready(os.getpid()))
            serve_tasks(inp, out, hello)
    except BrokenPipeError:
        pass
    except BaseException:
        traceback.print_exc()
        code = 1
    finally:  # never back into the factory's loop
        sys.stderr.flush()
        os._exit(code)


if __name__ == "__main__":
    main()
