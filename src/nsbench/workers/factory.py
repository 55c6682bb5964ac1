"""A worker factory: ``python -m nsbench.workers.factory FD``, which imports and prepares once, then forks workers.

A supervised pool (:mod:`nsbench.workers.jobs`) needs several workers that have each
imported numpy, numba and the hybrid core (about half a CPU second apiece) before
their first job. Started from the shell on two cores, those imports compete with
each other and with the command itself. The factory does them once: it is started
with :mod:`subprocess` like a worker (so it never imports the user's
``__main__``), runs the pool's preparation, and then forks each worker the pool
asks for. A forked worker starts with everything loaded, in a few milliseconds,
and is a full worker (:func:`nsbench.workers.worker.run_forked`): its own process,
its own channels to the runner, ended alone at a time limit, dying alone.

The factory is the workers' parent, so it is what learns how one ended; it reports
that (:class:`~nsbench.workers.protocol.Exited`) on its control socket, where the
runner sends :class:`~nsbench.workers.protocol.Hello`, a preparation
(:class:`~nsbench.workers.protocol.Call`), :class:`~nsbench.workers.protocol.Fork`
(with the worker's two pipe ends), :class:`~nsbench.workers.protocol.Kill` and
:class:`~nsbench.workers.protocol.Stop`. It runs no job itself, so it is never busy
when a worker ends. It leaves when the runner does (its end of the socket closes);
its workers then leave within a second.

Linux only (:func:`nsbench.workers.pool.can_fork`): forking a process that has
loaded compiled libraries is not safe on macOS, and Windows has no fork.
"""

from __future__ import annotations

import os
import pickle
import select
import signal
import socket
import sys
import traceback
import warnings
from typing import Any

from nsbench.workers import protocol as msg
from nsbench.workers.worker import register, run_forked


def _describe(status: int) -> str:
    from nsbench.workers.pool import describe_exit

    return describe_exit(os.waitstatus_to_exitcode(status))


class _Factory:
    def __init__(self, ctrl: socket.socket) -> None:
        self.ctrl = ctrl
        self.parent = os.getppid()
        self.hello: msg.Hello | None = None
        self.init_error = ""
        self.children: dict[int, int] = {}  # pid -> token
        # a child's end wakes the loop at once: SIGCHLD writes to this pipe (its handler does nothing)
        self.wake_r, self.wake_w = os.pipe()
        os.set_blocking(self.wake_w, False)
        signal.set_wakeup_fd(self.wake_w, warn_on_full_buffer=False)
        signal.signal(signal.SIGCHLD, lambda *_: None)

    def _report(self, token: int, reason: str) -> None:
        try:
            self.ctrl.send(pickle.dumps(msg.Exited(token, reason), protocol=pickle.HIGHEST_PROTOCOL))
        except OSError:  # the runner is gone: nobody to tell
            pass

    def _reap(self) -> None:
        while self.children:
            try:
                pid, status = os.waitpid(-1, os.WNOHANG)
            except ChildProcessError:
                return
            if pid == 0:
                return
            token = self.children.pop(pid, None)
            if token is not None:
                self._report(token, _describe(status))

    def _fork(self, token: int, fds: list[int]) -> None:
        if len(fds) != 2:
            for fd in fds:
                os.close(fd)
            self._report(token, f"the fork request came with {len(fds)} file descriptors, not 2")
            return
        try:
            with warnings.catch_warnings():
                # Python 3.12+ warns about forking a process with threads: here they are the idle
                # pools of numpy's and scipy's OpenBLAS, which shut down before a fork and start again
                # on their next use (their pthread_atfork handlers); nothing of the factory's runs in a thread
                warnings.simplefilter("ignore", DeprecationWarning)
                pid = os.fork()
        except OSError as exc:
            for fd in fds:
                os.close(fd)
            self._report(token, f"could not fork a worker ({exc})")
            return
        if pid == 0:  # the worker: nothing of the factory's loop runs here again
            try:
                self.ctrl.close()
                signal.set_wakeup_fd(-1)
                signal.signal(signal.SIGCHLD, signal.SIG_DFL)
                os.close(self.wake_r)
                os.close(self.wake_w)
                assert self.hello is not None
                run_forked(fds[0], fds[1], self.hello, self.init_error)
            finally:
                os._exit(70)
        for fd in fds:  # the worker has them; the runner sees its end of file when the worker ends
            os.close(fd)
        self.children[pid] = token

    def _kill(self, token: int) -> None:
        for pid, tok in self.children.items():
            if tok == token:
                try:
                    os.kill(pid, signal.SIGKILL)
                except ProcessLookupError:
                    pass
                return

    def _prepare(self, call: msg.Call) -> None:
        import importlib

        module, _, name = call.target.partition(":")
        try:
            target = getattr(importlib.import_module(module), name)
            target(*call.args, stage=lambda what, limit: None, emit=lambda item: None)
        except Exception:  # as a worker's preparation: not reported; a worker that needs it fails in its job
            pass

    def serve(self) -> None:
        while True:
            ready, _, _ = select.select([self.ctrl, self.wake_r], [], [], 1.0)
            if self.wake_r in ready:
                try:
                    os.read(self.wake_r, 4096)
                except BlockingIOError:
                    pass
            self._reap()
            if os.getppid() != self.parent:
                return  # the runner is gone (killed): the workers follow within a second
            if self.ctrl not in ready:
                continue
            data, fds, _, _ = socket.recv_fds(self.ctrl, msg.MAX_CONTROL_RECORD, 2)
            if not data:
                return  # the runner closed its end
            m: Any = pickle.loads(data)
            if isinstance(m, msg.Fork):
                self._fork(m.token, fds)
                continue
            for fd in fds:
                os.close(fd)
            if isinstance(m, msg.Hello):
                self.hello = m
                try:
                    register(m)
                except Exception as exc:  # every worker forked reports it, as a started worker would
                    self.init_error = f"{type(exc).__name__}: {exc}"
            elif isinstance(m, msg.Call):
                self._prepare(m)
            elif isinstance(m, msg.Kill):
                self._kill(m.token)
            elif isinstance(m, msg.Stop):
                return


def main() -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the runner's to handle, as for its workers
    import faulthandler

    faulthandler.enable()
    ctrl = socket.socket(fileno=int(sys.argv[1]))
    devnull = os.open(os.devnull, os.O_RDONLY)
    os.dup2(devnull, 0)
    os.close(devnull)
    os.dup2(2, 1)  # what a preparation (or a worker) prints cannot reach the runner's stdout
    try:
        _Factory(ctrl).serve()
    except Exception:
        traceback.print_exc()
    sys.stderr.flush()
    os._exit(0)  # the workers are not waited for: they end once their parent is gone


if __name__ == "__main__":
    main()
