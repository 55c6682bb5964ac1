"""Supervised jobs (nsbench.workers.jobs): parts kept, hard limits, crashes cost only their job."""

from __future__ import annotations

import os
import signal
import time

import pytest

from nsbench.workers.jobs import Job, JobPool

TARGET = f"{__name__}:"


@pytest.fixture(autouse=True, params=["forked", "started"])
def how_workers_start(request, monkeypatch):
    """Every behaviour holds for workers forked from a factory and for workers started on their own."""
    from nsbench.workers.pool import can_fork

    if request.param == "forked" and not can_fork():
        pytest.skip("workers are forked on Linux only")
    monkeypatch.setenv("NSBENCH_FORK_WORKERS", "1" if request.param == "forked" else "0")
    return request.param


def squares(n, *, stage, emit):
    """Emit ``i * i`` for ``i < n``; return ``n``."""
    for i in range(n):
        stage(f"item {i}", 60.0)
        emit(i * i)
    return n


def hangs_at(n, bad, *, stage, emit):
    for i in range(n):
        stage(f"item {i}", 2.0)
        if i == bad:
            time.sleep(3600)
        emit(i)
    return n


def dies_at(n, bad, how, *, stage, emit):
    for i in range(n):
        stage(f"item {i}", 60.0)
        if i == bad:
            if how == "exit":
                os._exit(9)
            os.kill(os.getpid(), signal.SIGSEGV)
        emit(i)
    return n


def compiles_then_returns(seconds, *, stage, emit):
    """A stage of 1 s that compiles for ``seconds`` first (the notice told as numba's listener tells it)."""
    from nsbench.compiling import _NOTICE

    stage("run", 1.0)
    _NOTICE.on_start("a first-use compilation")
    try:
        time.sleep(seconds)
    finally:
        _NOTICE.on_end()
    return seconds


def sleeps_then_returns(seconds, *, stage, emit):
    stage("run", 1.0)
    time.sleep(seconds)
    return seconds


def raises(*, stage, emit):
    raise TypeError("a bug in the job")


def _run(jobs, workers=2):
    with JobPool(workers) as pool:
        for job in jobs:
            pool.submit(job)
        return list(pool.outcomes())


def test_parts_then_the_result_of_every_job():
    out = _run([Job(k, TARGET + "squares", (k + 2,)) for k in range(5)])
    for k in range(5):
        mine = [o for o in out if o.key == k]
        assert [o.value for o in mine if o.kind == "partial"] == [i * i for i in range(k + 2)]
        assert mine[-1].kind == "done" and mine[-1].value == k + 2


def test_the_next_job_is_sent_before_an_outcome_is_handed_on():
    # A caller that takes its time over an outcome (a sweep writes the chunk's table) must not
    # keep the worker idle: when the first job's result is handed on, the second already runs.
    with JobPool(1) as pool:
        pool.submit(Job("a", TARGET + "squares", (2,)))
        pool.submit(Job("b", TARGET + "squares", (3,)))
        running = {}
        for o in pool.outcomes():
            if o.kind == "done":
                running[o.key] = [s.job.key for s in pool._slots if s.job is not None]
    assert running == {"a": ["b"], "b": []}


def test_a_job_that_never_returns_is_stopped_and_the_others_finish():
    out = _run([Job("hang", TARGET + "hangs_at", (4, 2)), *(Job(k, TARGET + "squares", (3,)) for k in range(3))])
    hang = [o for o in out if o.key == "hang"]
    assert [o.value for o in hang if o.kind == "partial"] == [0, 1]  # what came before is kept
    assert hang[-1].kind == "time limit" and hang[-1].stage == "item 2" and "limit of 2 s" in hang[-1].reason
    assert sorted(o.key for o in out if o.kind == "done") == [0, 1, 2]


def test_a_compilation_holds_the_stages_clock_and_a_run_does_not():
    # compiling is nsbench's first-use cost: the parent holds a stage's limit while the worker says it
    # compiles (nsbench.workers.protocol.Compiling) and gives the stage back what it had left after it
    out = _run(
        [
            Job("compiles", TARGET + "compiles_then_returns", (2.0,)),
            Job("sleeps", TARGET + "sleeps_then_returns", (2.0,)),
        ]
    )
    ends = {o.key: o for o in out if o.final}
    assert ends["compiles"].kind == "done" and ends["compiles"].value == 2.0
    assert ends["sleeps"].kind == "time limit" and "limit of 1 s" in ends["sleeps"].reason


@pytest.mark.parametrize("how, reason", [("exit", "exit code 9"), ("segv", "signal 11 (SIGSEGV)")])
@pytest.mark.parametrize("workers", [1, 2])
def test_a_worker_that_dies_costs_only_its_job(how, reason, workers):
    out = _run(
        [Job("bad", TARGET + "dies_at", (3, 1, how)), *(Job(k, TARGET + "squares", (2,)) for k in range(4))], workers
    )
    bad = [o for o in out if o.key == "bad"]
    assert [o.value for o in bad if o.kind == "partial"] == [0]
    assert bad[-1].kind == "crashed" and bad[-1].stage == "item 1" and reason in bad[-1].reason
    assert sorted(o.key for o in out if o.kind == "done") == [0, 1, 2, 3]


def test_an_exception_in_a_job_is_its_failure():
    out = _run([Job("x", TARGET + "raises"), Job("ok", TARGET + "squares", (1,))], workers=1)
    assert [(o.key, o.kind) for o in out if o.final] == [("x", "failed"), ("ok", "done")]
    assert "TypeError: a bug in the job" in out[0].reason


def pid(*, stage, emit):
    return os.getpid()


def test_the_kept_pool_reuses_its_warm_worker_and_starts_clean_after_a_drop():
    from nsbench.workers.jobs import drop_shared, shared_pool

    def one(pool):
        pool.submit(Job("p", TARGET + "pid"))
        (out,) = [o for o in pool.outcomes() if o.final]
        return out.value

    pool = shared_pool(1)
    first = one(pool)
    assert shared_pool(1) is pool and one(pool) == first  # same process: no new start
    drop_shared(pool)
    again = shared_pool(1)
    assert again is not pool and one(again) != first
    drop_shared(again)


_PREPARED: list[int] = []


def prepare(*, stage, emit):
    _PREPARED.append(os.getpid())
    return "not reported"


def prepared(*, stage, emit):
    return os.getpid(), list(_PREPARED)


@pytest.mark.parametrize("workers", [1, 2])
def test_a_preparation_sent_with_the_start_runs_before_every_job_and_is_not_reported(workers, how_workers_start):
    with JobPool(workers) as pool:
        assert pool.start(Job("prep", TARGET + "prepare"))
        assert not pool.start(Job("prep", TARGET + "prepare"))  # running already: nothing sent again
        for k in range(2 * workers):
            pool.submit(Job(k, TARGET + "prepared"))
        out = list(pool.outcomes())
    assert sorted(o.key for o in out) == list(range(2 * workers))  # the preparation's Done is not among them
    assert all(o.kind == "done" for o in out)
    if how_workers_start == "started":  # each job ran after its own worker's preparation, which ran once there
        assert all(o.value[1] == [o.value[0]] for o in out)
    else:  # it ran once, in the factory, and every worker forked from it has its effects
        (prepared_in,) = {tuple(o.value[1]) for o in out}
        assert len(prepared_in) == 1 and prepared_in[0] not in {o.value[0] for o in out}
        assert len({o.value[0] for o in out}) <= workers


def dies_preparing(*, stage, emit):
    os._exit(5)


def test_a_worker_that_dies_in_its_preparation_could_not_start():
    from nsbench.errors import NsbenchError

    with JobPool(1) as pool:
        pool.start(Job("prep", TARGET + "dies_preparing"))
        pool.submit(Job("x", TARGET + "pid"))
        with pytest.raises(NsbenchError, match=r"ended while starting \((its factory process ended \()?exit code 5\)"):
            list(pool.outcomes())
