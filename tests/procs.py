"""Process helpers of the tests: the kill tests' (Linux ``/proc``), and the environment of an inner pytest run."""

from __future__ import annotations

import os


def _stat(pid: int | str) -> list[str]:
    with open(f"/proc/{pid}/stat") as fh:
        return fh.read().rsplit(")", 1)[1].split()  # the name in parentheses may hold spaces


def children_of(pid: int) -> set[int]:
    """The live processes whose parent is ``pid``."""
    out = set()
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                fields = _stat(entry)
            except OSError:
                continue
            if int(fields[1]) == pid and fields[0] != "Z":
                out.add(int(entry))
    return out


def descendants_of(pid: int) -> dict[int, set[int]]:
    """The live processes below ``pid``, each with its own live children."""
    tree: dict[int, set[int]] = {}
    todo = [pid]
    while todo:
        for child in children_of(todo.pop()):
            if child not in tree:
                tree[child] = set()
                todo.append(child)
    for child in tree:
        tree[child] = {c for c in tree if c in children_of(child)}
    return tree


def alive(pid: int) -> bool:
    """Whether ``pid`` exists and is not a zombie."""
    try:
        return _stat(pid)[0] != "Z"
    except OSError:
        return False


def kill_leaves_no_workers(proc, workers: int, start_within: float = 300.0, end_within: float = 30.0) -> None:
    """Wait until ``proc`` has ``workers`` workers, SIGKILL it, and assert every process below it ends too.

    The workers are the processes below ``proc`` with no children of their own:
    its children, or, when they are forked from a worker factory, its grandchildren.
    ``start_within`` allows for worker start-up and a cold compile; a worker polls
    for its parent once a second, so ``end_within`` is generous.
    """
    import signal
    import time

    tree: dict[int, set[int]] = {}
    deadline = time.monotonic() + start_within
    while time.monotonic() < deadline and proc.poll() is None and sum(not c for c in tree.values()) < workers:
        tree = descendants_of(proc.pid)
        time.sleep(0.2)
    assert proc.poll() is None and sum(not c for c in tree.values()) == workers, (proc.poll(), tree)
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    deadline = time.monotonic() + end_within
    while time.monotonic() < deadline and any(alive(p) for p in tree):
        time.sleep(0.2)
    assert not any(alive(p) for p in tree)


def inner_pytest_env(**extra: str) -> dict[str, str]:
    """The environment for a pytest run started by a test, with ``extra`` set.

    Without pytest-xdist's worker variables: pytest-benchmark reads them as "xdist is on"
    and refuses ``--benchmark-only`` in a run that has no workers of its own.
    """
    env = {k: v for k, v in os.environ.items() if not k.startswith("PYTEST_XDIST")}
    env.update(extra)
    return env
