"""The runner-worker protocol: framing over pipes, and how a worker's end is described."""

from __future__ import annotations

import io
import math
import os
import signal

import pytest

from nsbench.workers import protocol as msg
from nsbench.workers.pool import describe_exit


def test_messages_round_trip_through_a_pipe():
    r, w = os.pipe()
    big = msg.Done(7, {"x": list(range(50_000))})  # larger than a pipe buffer
    pid = os.fork()
    if pid == 0:  # the writer: a raw fd, like the parent
        os.close(r)
        msg.write_fd(w, msg.Stage(7, "timed run 1 of 3", 30.0))
        msg.write_fd(w, big)
        os._exit(0)
    os.close(w)
    with os.fdopen(r, "rb", buffering=0) as stream:  # unbuffered, like the parent's reads
        assert msg.read_message(stream) == msg.Stage(7, "timed run 1 of 3", 30.0)
        assert msg.read_message(stream) == big
        with pytest.raises(EOFError):
            msg.read_message(stream)
    os.waitpid(pid, 0)


def test_a_cut_message_is_an_end_of_file():
    buf = io.BytesIO()
    msg.write_message(buf, msg.Ready(1))
    with pytest.raises(EOFError):
        msg.read_message(io.BytesIO(buf.getvalue()[:-1]))


def test_exit_descriptions():
    assert describe_exit(3) == "exit code 3"
    assert describe_exit(-signal.SIGSEGV) == "signal 11 (SIGSEGV)"
    assert describe_exit(None) == "still running"


def test_a_stage_is_held_while_it_compiles():
    from nsbench.workers.protocol import COMPILE_LIMIT, Compiling, held

    start, end = Compiling(1, True), Compiling(1, False)
    deadline, left = held(110.0, None, start, now=100.0)  # 10 s left when the compilation began
    assert deadline == 100.0 + COMPILE_LIMIT and left == 10.0
    assert held(deadline, left, start, now=150.0) == (deadline, 10.0)  # one hold at a time
    assert held(deadline, left, end, now=400.0) == (410.0, None)  # what it had left, from the end
    assert held(None, None, start, now=100.0) == (None, None)  # an unlimited stage stays so
    assert held(math.inf, None, start, now=100.0) == (math.inf, None)
    assert held(110.0, None, end, now=100.0) == (110.0, None)  # an end without a start changes nothing
