"""Workers forked from a worker factory (nsbench.workers.factory): loaded once, isolated as workers started alone."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time
import types

import pytest

from nsbench.workers.pool import can_fork
from nsbench.workers.jobs import Job, JobPool

pytestmark = pytest.mark.skipif(not can_fork(), reason="workers are forked on Linux only")

TARGET = f"{__name__}:"

_LOADED: list[int] = []


def load(*, stage, emit):
    """A preparation: what it leaves in the process (here, its pid) every forked worker has."""
    _LOADED.append(os.getpid())


def family(*, stage, emit):
    return os.getpid(), os.getppid(), list(_LOADED)


def kills_its_factory(*, stage, emit):
    stage("waiting for the end", 60.0)
    os.kill(os.getppid(), signal.SIGKILL)
    time.sleep(30)  # a worker leaves within a second once its parent is gone


def test_every_worker_is_forked_from_the_one_factory_that_ran_the_preparation(monkeypatch):
    monkeypatch.setenv("NSBENCH_FORK_WORKERS", "1")
    with JobPool(2) as pool:
        pool.start(Job("prep", TARGET + "load"))
        for k in range(6):
            pool.submit(Job(k, TARGET + "family"))
        out = [o.value for o in pool.outcomes()]
        factory = pool._factory.proc.pid
    assert {ppid for _, ppid, _ in out} == {factory}  # each worker is the factory's child
    assert {tuple(loaded) for _, _, loaded in out} == {(factory,)}  # prepared there, once
    assert factory not in {pid for pid, _, _ in out}


def test_a_factory_that_dies_costs_its_running_jobs_and_the_pool_goes_on_with_a_new_one(monkeypatch):
    monkeypatch.setenv("NSBENCH_FORK_WORKERS", "1")
    with JobPool(1) as pool:
        pool.submit(Job("bad", TARGET + "kills_its_factory"))
        for k in range(2):
            pool.submit(Job(k, TARGET + "family"))
        out = {o.key: o for o in pool.outcomes()}
    assert out["bad"].kind == "crashed" and out["bad"].stage == "waiting for the end"
    assert "factory process ended (signal 9 (SIGKILL))" in out["bad"].reason
    assert out[0].kind == out[1].kind == "done"
    (new_factory,) = {out[k].value[1] for k in (0, 1)}
    assert new_factory != os.getpid()


def test_a_factory_that_cannot_take_the_runners_registrations_says_so(monkeypatch):
    from nsbench.workers import pool as wp
    from nsbench.errors import NsbenchError

    monkeypatch.setenv("NSBENCH_FORK_WORKERS", "1")
    ghost = types.ModuleType("nsbench_test_ghost_module")  # importable here, not in a worker
    exec("class Ghost:\n    pass", ghost.__dict__)
    monkeypatch.setitem(sys.modules, ghost.__name__, ghost)
    ghost.Ghost.__module__ = ghost.__name__
    hello = wp.hello({"integrators": {"ghost": ghost.Ghost}}, "", {})
    with JobPool(1, hello) as pool:
        pool.submit(Job("x", TARGET + "family"))
        with pytest.raises(NsbenchError, match="could not start: ModuleNotFoundError.*nsbench_test_ghost_module"):
            list(pool.outcomes())


def _alive(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat") as fh:
            return fh.read().rsplit(")", 1)[1].split()[0] != "Z"  # a zombie has ended
    except OSError:
        return False


def test_the_factory_and_its_workers_leave_when_the_runner_is_killed(tmp_path):
    script = tmp_path / "runner.py"
    script.write_text(
        textwrap.dedent(
            f"""
            import os, signal, sys
            sys.path.insert(0, {os.path.dirname(__file__)!r})
            from nsbench.workers.jobs import Job, JobPool
            pool = JobPool(2)
            pool.start()
            for k in range(2):
                pool.submit(Job(k, "test_factory:family_then_wait"))
            seen = set()
            for o in pool.outcomes():
                seen.add(o.value[1])
                print(o.value[1], o.value[0], flush=True)
                if len(seen) == 2:
                    os.kill(os.getpid(), signal.SIGKILL)
            """
        )
    )
    env = dict(os.environ, NSBENCH_FORK_WORKERS="1")
    proc = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, env=env, timeout=120)
    assert proc.returncode == -signal.SIGKILL, proc.stderr
    pids = {int(p) for line in proc.stdout.split() for p in [line] if p}
    assert len(pids) == 3  # the factory and its two workers
    deadline = time.monotonic() + 30  # the factory sees its runner gone at once, a worker its factory within a second
    while any(_alive(p) for p in pids) and time.monotonic() < deadline:
        time.sleep(0.2)
    assert not any(_alive(p) for p in pids)


def family_then_wait(*, stage, emit):
    stage("waiting", 120.0)
    emit((os.getppid(), os.getpid()))
    time.sleep(120)


def test_a_pool_whose_factory_cannot_start_starts_its_workers_alone(monkeypatch):
    from nsbench.workers import pool as wp

    monkeypatch.setenv("NSBENCH_FORK_WORKERS", "1")
    # provenance too large for one record of the factory's socket: the factory is refused at once
    hello = wp.hello({}, "", {"notes": "x" * 8_000_000})
    with JobPool(1, hello) as pool:
        for k in range(2):
            pool.submit(Job(k, TARGET + "family"))
        out = [o for o in pool.outcomes()]
        assert pool._factory is None and isinstance(pool._slots[0].worker, wp.WorkerProcess)
    assert [o.kind for o in out] == ["done", "done"]
    assert out[0].value[1] == os.getpid()  # the worker is this process's own child
