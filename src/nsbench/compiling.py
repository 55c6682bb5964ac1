"""Saying so when numba compiles: the first use of the compiled core is not silent.

numba compiles nsbench's compiled core (the hybrid loop, its arc kernels, the
rules they call) on its first use on a machine and caches the machine code on
disk; that first compilation takes minutes on a fresh install. numba broadcasts
a ``numba:compile`` event for every function it actually compiles (loading one
from the disk cache broadcasts nothing), and :func:`announce` listens to them:
a compilation that is still running after :data:`DELAY` seconds is announced on
stderr with what is being compiled, followed by a progress line (rewritten in
place on a terminal; every :data:`EVERY` seconds in a log or a pipe) and a last
line with the time it took. A warm run prints nothing. :func:`watch` tells a callback when
this process starts and ends compiling (a worker tells its parent, which holds the task's
time limit meanwhile).

Importing this module is light; :func:`announce` imports numba (call it where
numba is imported anyway).
"""

from __future__ import annotations

import os
import sys
import threading
import time
from typing import Callable, TextIO

from nsbench.progress import clock

#: Seconds a compilation runs before it is announced: a small function compiles in under a
#: second, loading the whole core from the cache takes no event at all.
DELAY = 2.0
#: Seconds between two progress lines where there is no terminal (CI logs, pipes).
EVERY = 30.0
_installed = False


def _name(event) -> str:
    func = getattr(event.data.get("dispatcher"), "py_func", None)
    if func is None:
        return "a function"
    return f"{func.__module__}.{func.__qualname__}"


class _Notice:
    """The state of the compilations of this process: depth of the nested ones, counts, the reporter thread."""

    def __init__(self, stream: TextIO | None = None, delay: float = DELAY, every: float = EVERY) -> None:
        self.stream = stream
        self.delay, self.every = delay, every
        self.depth = 0
        self.lock = threading.Lock()
        #: Told ``True`` when the outermost compilation starts, ``False`` when it ends (:func:`watch`).
        self.watchers: list[Callable[[bool], None]] = []
        self._reset()

    def _tell(self, active: bool) -> None:
        for watcher in list(self.watchers):
            watcher(active)

    def _reset(self) -> None:
        self.top = ""
        self.current = ""
        self.done = 0
        self.start = 0.0
        self.announced = False
        self.finished = threading.Event()
        self.thread: threading.Thread | None = None

    def _out(self) -> TextIO:
        return self.stream if self.stream is not None else sys.stderr

    # ------------------------------------------------------------------ numba's events
    def on_start(self, name: str) -> None:
        with self.lock:
            outermost = self.depth == 0
            if outermost:
                self._reset()
                self.top, self.start = name, time.monotonic()
                self.thread = threading.Thread(target=self._report, name="nsbench-compile-notice", daemon=True)
                self.thread.start()
            self.depth += 1
            self.current = name
        if outermost:
            self._tell(True)

    def on_end(self) -> None:
        with self.lock:
            self.depth = max(0, self.depth - 1)
            self.done += 1
            if self.depth:
                return
            self.finished.set()
            thread, announced = self.thread, self.announced
        self._tell(False)
        if thread is not None:
            thread.join()
        if announced:
            self._print(
                f"nsbench: compiled {self.done} function(s) in {clock(time.monotonic() - self.start)}; "
                "cached on disk, later runs load them in seconds",
                end=True,
            )

    # ------------------------------------------------------------------ the reporter
    def _tty(self) -> bool:
        return bool(getattr(self._out(), "isatty", lambda: False)())

    def _print(self, text: str, end: bool = False) -> None:
        out = self._out()
        try:
            if self._tty():
                out.write("\r\033[K" + text + ("\n" if end else ""))
            else:
                out.write(text + "\n")
            out.flush()
        except (OSError, ValueError):  # a closed stream: nothing to say it on
            pass

    def _report(self) -> None:
        if self.finished.wait(self.delay):
            return  # done before anyone waited long: nothing to say
        with self.lock:
            self.announced = True
        self._print(
            f"nsbench: compiling {self.top} and the functions it calls with numba (pid {os.getpid()}): "
            "first use on this install, cached afterwards (the whole compiled core takes minutes once)",
            end=True,
        )
        tty = self._tty()
        while not self.finished.wait(1.0 if tty else self.every):
            with self.lock:
                done, current = self.done, self.current
            self._print(
                f"nsbench: compiling, {clock(time.monotonic() - self.start)} so far, {done} function(s) "
                f"done, now {current}",
                end=not tty,
            )


_NOTICE = _Notice()


def listener(notice: _Notice):
    """A numba event listener that feeds ``notice``."""
    from numba.core import event

    class Listener(event.Listener):
        def on_start(self, ev) -> None:
            notice.on_start(_name(ev))

        def on_end(self, ev) -> None:
            notice.on_end()

    return Listener()


def watch(callback: Callable[[bool], None]) -> None:
    """Call ``callback(True)`` when this process starts compiling with numba and ``callback(False)``
    when it is done (nested compilations count once; loading from the disk cache is not compiling).
    The callback runs in the compiling thread and should be quick; what it raises reaches the code
    that triggered the compilation."""
    if callback not in _NOTICE.watchers:
        _NOTICE.watchers.append(callback)


def announce() -> None:
    """Listen to numba's compilations in this process and announce the long ones (idempotent)."""
    global _installed
    if _installed:
        return
    from numba.core import event

    event.register("numba:compile", listener(_NOTICE))
    _installed = True
