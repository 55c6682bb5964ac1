"""The first compilation is announced: numba's compile events, a real (uncached) compilation."""

from __future__ import annotations

import io
import time

import numba
from numba.core import event

from nsbench.compiling import _Notice, listener


def _fresh():
    # a new function object each call: numba compiles it (no cache), broadcasting numba:compile
    def inner(x):
        return x * 2.0 + 1.0

    compiled_inner = numba.njit(inner)

    def outer(x):
        s = 0.0
        for i in range(3):
            s += compiled_inner(x + i)
        return s

    return numba.njit(outer)


def test_a_long_compilation_is_announced_with_progress_and_an_end():
    out = io.StringIO()  # no terminal: whole lines
    notice = _Notice(stream=out, delay=0.0, every=0.001)
    func = _fresh()
    with event.install_listener("numba:compile", listener(notice)):
        assert func(1.0) == 15.0
    text = out.getvalue()
    lines = text.splitlines()
    assert lines[0].startswith(f"nsbench: compiling {__name__}.") and "_fresh.<locals>.outer" in lines[0]
    assert "cached afterwards" in lines[0]
    assert lines[-1].startswith("nsbench: compiled 2 function(s) in ")  # outer and the inner it calls
    assert notice.depth == 0


def test_a_short_or_cached_compilation_says_nothing():
    out = io.StringIO()
    notice = _Notice(stream=out, delay=60.0)
    func = _fresh()
    tic = time.monotonic()
    with event.install_listener("numba:compile", listener(notice)):
        func(1.0)
        func(2.0)  # compiled already: no event at all
    assert out.getvalue() == "" and time.monotonic() - tic < 60.0  # the reporter did not hold the run up
    assert notice.done == 2


def test_a_watcher_is_told_when_the_outermost_compilation_starts_and_ends():
    told = []
    notice = _Notice(stream=io.StringIO(), delay=60.0)
    notice.watchers.append(told.append)
    func = _fresh()
    with event.install_listener("numba:compile", listener(notice)):
        func(1.0)  # outer and the inner it calls: one compilation, nested
        func(2.0)  # compiled already: nothing
    assert told == [True, False] and notice.done == 2
