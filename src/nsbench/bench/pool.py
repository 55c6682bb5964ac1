"""The parent's handle on one worker process (:mod:`nsbench.bench.worker`).

A worker is ``python -m nsbench.bench.worker`` started with :mod:`subprocess`:
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
from typing import Any, Iterable

from nsbench.bench import protocol as msg


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


class WorkerProcess:
    """One running worker: send it messages, read its messages, end it."""

    def __init__(self, first: msg.Hello) -> None:
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "nsbench.bench.worker"],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            bufsize=0,
            env=_environment(),
            close_fds=True,
        )
        self._asked = False  # a Stop sent
        self.send(first)

    @property
    def pid(self) -> int:
        return self.proc.pid

    def fileno(self) -> int:
        return self.proc.stdout.fileno()

    def send(self, message: Any) -> None:
        """Send one message; ``BrokenPipeError`` if the worker is gone."""
        msg.write_fd(self.proc.stdin.fileno(), message)

    def receive(self) -> Any:
        """The next message (blocks until it is complete); ``EOFError`` if the worker is gone."""
        return msg.read_message(self.proc.stdout)

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

    def ask_to_stop(self) -> None:
        """Ask the worker to exit, without waiting (:meth:`stop` then waits)."""
        if not self._asked:
            self._asked = True
            try:
                self.send(msg.Stop())
            except (BrokenPipeError, OSError):
                pass

    def stop(self, timeout: float = 10.0) -> None:
        """Ask the worker to exit; end it if it does not within ``timeout`` seconds."""
        try:
            self.ask_to_stop()
            self.proc.wait(timeout)
        except (BrokenPipeError, OSError, subprocess.TimeoutExpired):
            pass
        self.kill()

    def _close(self) -> None:
        for stream in (self.proc.stdin, self.proc.stdout):
            try:
                stream.close()
            except OSError:
                pass


def readable(workers: Iterable[WorkerProcess], timeout: float | None) -> list[WorkerProcess]:
    """The workers with a message (or an end of file) to read, waiting up to ``timeout`` seconds."""
    ready, _, _ = select.select(list(workers), [], [], timeout)
    return ready
