"""The parent's handle on one worker process (:mod:`nsbench.workers.worker`).

A worker is ``python -m nsbench.workers.worker`` started with :mod:`subprocess`:
it never imports the user's ``__main__``. The parent writes to its stdin and
reads its stdout (unbuffered, so that ``select`` sees every pending message);
its stderr is the parent's. The parent can end it at any time (time limit,
interrupt); how it ended (exit code or signal) names a crash.
"""

from __future__ import annotations

import os
import pickle
import select
import signal
import subprocess
import sys
from pathlib import Path
from typing import Any, BinaryIO, Iterable, cast

from nsbench.workers import protocol as msg


def hello(components: dict[str, dict[str, Any]], out: str | Path, provenance: dict[str, Any]) -> msg.Hello:
    """The first message of every worker: this process's path and runtime registrations, where rows go."""
    return msg.Hello(
        sys_path=[p for p in sys.path if p], components=pickle.dumps(components), out=str(out), provenance=provenance
    )


def importable(obj: Any) -> bool:
    """Whether a worker process can unpickle ``obj`` (pickled by reference, so not from ``__main__``)."""
    if getattr(obj, "__module__", None) == "__main__":
        return False
    try:
        pickle.dumps(obj)
    except Exception:  # a local class, a lambda...
        return False
    return True


def _environment() -> dict[str, str]:
    """The parent's environment, with the directory of *this* nsbench first on the path."""
    import nsbench

    root = str(Path(nsbench.__file__).resolve().parents[1])
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([root] + [p for p in env.get("PYTHONPATH", "").split(os.pathsep) if p])
    return env


def describe_exit(returncode: int | None) -> str:
    """``'exit code 3'``, ``'signal 11 (SIGSEGV)'``, or ``'still running'``."""
    if returncode is None:
        return "still running"
    if returncode < 0:
        try:
            name = signal.Signals(-returncode).name
        except ValueError:
            return f"signal {-returncode}"
        return f"signal {-returncode} ({name})"
    return f"exit code {returncode}"


class _Asking:
    """What both kinds of worker handle share: asking the worker to leave."""

    _asked = False  # a Stop sent

    def send(self, message: Any) -> None:
        raise NotImplementedError

    def ask_to_stop(self) -> None:
        """Ask the worker to exit, without waiting (``stop`` then waits)."""
        if not self._asked:
            self._asked = True
            try:
                self.send(msg.Stop())
            except (BrokenPipeError, OSError):
                pass


class WorkerProcess(_Asking):
    """One running worker: send it messages, read its messages, end it."""

    def __init__(self, first: msg.Hello) -> None:
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "nsbench.workers.worker"],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            bufsize=0,
            env=_environment(),
            close_fds=True,
        )
        # both pipes exist: they were asked for (PIPE); bufsize=0 makes them raw binary streams
        assert self.proc.stdin is not None and self.proc.stdout is not None
        self._stdin: BinaryIO = cast(BinaryIO, self.proc.stdin)
        self._stdout: BinaryIO = cast(BinaryIO, self.proc.stdout)
        self.send(first)

    @property
    def pid(self) -> int:
        return self.proc.pid

    def fileno(self) -> int:
        return self._stdout.fileno()

    def send(self, message: Any) -> None:
        """Send one message; ``BrokenPipeError`` if the worker is gone."""
        msg.write_fd(self._stdin.fileno(), message)

    def receive(self) -> Any:
        """The next message (blocks until it is complete); ``EOFError`` if the worker is gone."""
        return msg.read_message(self._stdout)

    def exit_reason(self, timeout: float = 5.0) -> str:
        """How the (ending) process ended, waiting up to ``timeout`` seconds for it."""
        try:
            self.proc.wait(timeout)
        except subprocess.TimeoutExpired:
            self.kill()
        return describe_exit(self.proc.returncode)

    def kill(self) -> None:
        """End the process now (time limit, interrupt) and reap it."""
        if self.proc.poll() is None:
            self.proc.kill()
        self.proc.wait()
        self._close()

    def stop(self, timeout: float = 10.0) -> None:
        """Ask the worker to exit; end it if it does not within ``timeout`` seconds."""
        try:
            self.ask_to_stop()
            self.proc.wait(timeout)
        except (BrokenPipeError, OSError, subprocess.TimeoutExpired):
            pass
        self.kill()

    def _close(self) -> None:
        for stream in (self._stdin, self._stdout):
            try:
                stream.close()
            except OSError:
                pass


def readable(workers: Iterable[WorkerProcess], timeout: float | None) -> list[WorkerProcess]:
    """The workers with a message (or an end of file) to read, waiting up to ``timeout`` seconds."""
    ready, _, _ = select.select(list(workers), [], [], timeout)
    return ready


# ------------------------------------------------------------------------- forked workers
def can_fork() -> bool:
    """Whether workers may be forked from a factory (:mod:`nsbench.workers.factory`): on Linux, unless
    ``NSBENCH_FORK_WORKERS=0`` asks for every worker to be started on its own."""
    return sys.platform.startswith("linux") and os.environ.get("NSBENCH_FORK_WORKERS", "1") != "0"


class WorkerFactory:
    """The parent's handle on a worker factory: it prepares once and forks each worker asked for.

    Parameters
    ----------
    first
        The :class:`~nsbench.workers.protocol.Hello` every forked worker has had.
    """

    def __init__(self, first: msg.Hello) -> None:
        import socket

        mine, theirs = socket.socketpair(socket.AF_UNIX, socket.SOCK_SEQPACKET)
        try:
            self.proc = subprocess.Popen(
                [sys.executable, "-m", "nsbench.workers.factory", str(theirs.fileno())],
                stdin=subprocess.DEVNULL,
                env=_environment(),
                close_fds=True,
                pass_fds=(theirs.fileno(),),
            )
        finally:
            theirs.close()
        self._sock = mine
        self._tokens = 0
        self._exits: dict[int, str] = {}  # token -> how that worker ended, as reported
        self.prepared: set[str] = set()  # the preparations sent (by target)
        try:
            self._record(first)
        except OSError:  # a record too large for the socket, say: no factory (the caller starts workers alone)
            self.close(timeout=0.0)
            raise

    def _record(self, message: Any, fds: tuple[int, ...] = ()) -> None:
        import socket

        data = pickle.dumps(message, protocol=pickle.HIGHEST_PROTOCOL)
        if len(data) > msg.MAX_CONTROL_RECORD:
            import errno

            raise OSError(errno.EMSGSIZE, f"a record of {len(data)} bytes is more than the factory reads")
        if fds:
            socket.send_fds(self._sock, [data], list(fds))
        else:
            self._sock.send(data)

    def alive(self) -> bool:
        return self.proc.poll() is None

    def prepare(self, target: str, args: tuple = ()) -> None:
        """Run ``target(*args, stage=, emit=)`` in the factory before the next fork (once per target)."""
        if target not in self.prepared:
            self.prepared.add(target)
            self._record(msg.Call(0, target, args))

    def fork(self) -> "ForkedWorker":
        """A new worker; ``OSError`` if the factory cannot be asked (it has ended)."""
        to_worker_r, to_worker_w = os.pipe()
        from_worker_r, from_worker_w = os.pipe()
        self._tokens += 1
        try:
            self._record(msg.Fork(self._tokens), (to_worker_r, from_worker_w))
        except BaseException:
            os.close(to_worker_w)
            os.close(from_worker_r)
            raise
        finally:  # the worker holds them now (or nobody does): its end of file is the runner's news
            os.close(to_worker_r)
            os.close(from_worker_w)
        return ForkedWorker(self, self._tokens, to_worker_w, from_worker_r)

    def kill(self, token: int) -> None:
        try:
            self._record(msg.Kill(token))
        except OSError:
            pass

    def exit_reason(self, token: int, timeout: float) -> str | None:
        """How worker ``token`` ended, as the factory reports it within ``timeout`` seconds (``None``: not yet)."""
        import time

        deadline = time.monotonic() + timeout
        while token not in self._exits:
            left = deadline - time.monotonic()
            ready, _, _ = select.select([self._sock], [], [], max(0.0, left))
            if not ready:
                return None
            try:
                data = self._sock.recv(1 << 16)
            except OSError:
                data = b""
            if not data:  # the factory has ended, and its workers with it
                self.proc.wait()
                return f"its factory process ended ({describe_exit(self.proc.returncode)})"
            m = pickle.loads(data)
            if isinstance(m, msg.Exited):
                self._exits[m.token] = m.reason
        return self._exits.pop(token)

    def close(self, timeout: float = 2.0) -> None:
        """Ask the factory to leave (its idle workers were ended before); end it past ``timeout``."""
        try:
            self._record(msg.Stop())
            self.proc.wait(timeout)
        except (OSError, subprocess.TimeoutExpired):
            pass
        if self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait()
        self._sock.close()

    def cpu_seconds(self) -> float:
        """CPU seconds of the factory and of its workers that have ended (Linux ``/proc``; 0 elsewhere)."""
        return process_cpu_seconds(self.proc.pid, children=True)


class ForkedWorker(_Asking):
    """One worker forked from a :class:`WorkerFactory`: the interface of :class:`WorkerProcess`."""

    def __init__(self, factory: WorkerFactory, token: int, to_worker: int, from_worker: int) -> None:
        self._factory = factory
        self._token = token
        self._to = to_worker
        self._from = os.fdopen(from_worker, "rb", buffering=0)
        self._pid: int | None = None  # from its Ready
        self._reason: str | None = None

    @property
    def pid(self) -> int | None:
        return self._pid

    def fileno(self) -> int:
        return self._from.fileno()

    def send(self, message: Any) -> None:
        msg.write_fd(self._to, message)

    def receive(self) -> Any:
        m = msg.read_message(self._from)
        if isinstance(m, msg.Ready):
            self._pid = m.pid
        return m

    def exit_reason(self, timeout: float = 5.0) -> str:
        if self._reason is None:
            self._reason = self._factory.exit_reason(self._token, timeout)
            if self._reason is None:  # it has closed its pipes but not ended: end it
                self.kill()
        return self._reason or "still running"

    def kill(self) -> None:
        if self._reason is None:
            self._factory.kill(self._token)
            self._reason = self._factory.exit_reason(self._token, 5.0)
            if self._reason is None and self._pid is not None:  # the factory cannot: end it ourselves
                try:
                    os.kill(self._pid, signal.SIGKILL)
                except ProcessLookupError:
                    pass
                self._reason = "ended by the runner"
        self._close()

    def stop(self, timeout: float = 10.0) -> None:
        self.ask_to_stop()
        if self._reason is None:
            self._reason = self._factory.exit_reason(self._token, timeout)
        self.kill()

    def _close(self) -> None:
        for close in (lambda: os.close(self._to), self._from.close):
            try:
                close()
            except OSError:
                pass
        self._to = -1


def process_cpu_seconds(pid: int | None, children: bool = False) -> float:
    """utime + stime of process ``pid`` (and of its reaped children), from ``/proc``; 0 if unknown."""
    if pid is None:
        return 0.0
    ticks = os.sysconf("SC_CLK_TCK") if hasattr(os, "sysconf") else 100
    try:
        with open(f"/proc/{pid}/stat") as fh:
            fields = fh.read().rsplit(")", 1)[1].split()
    except OSError:
        return 0.0
    used = int(fields[11]) + int(fields[12]) + (int(fields[13]) + int(fields[14]) if children else 0)
    return used / ticks
