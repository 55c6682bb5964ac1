"""Jobs in supervised worker processes: a hard time limit per step, and crash isolation.

Sweeps (:mod:`nsbench.bifurcation.parallel`) and Lyapunov ensembles
(:mod:`nsbench.bifurcation.lyapunov`) hand their work here. A job is a call
``target(*args, stage=..., emit=...)`` (``target`` named ``'module:function'``)
that runs in a worker process of the suite runner (:mod:`nsbench.workers.worker`).
On Linux the workers are forked from a worker factory (:mod:`nsbench.workers.factory`),
itself started with :mod:`subprocess` (so neither ever imports the user's
``__main__``): the factory imports nsbench and runs the pool's preparation once,
and each worker starts with all of it loaded, instead of every worker importing
numba and the core again while the others do the same. Elsewhere, or with
``NSBENCH_FORK_WORKERS=0``, each worker is started on its own.
The job announces each step with ``stage(what, limit)`` and sends each finished
part of its result with ``emit(item)``.

Why a process per worker and not a ``ProcessPoolExecutor``: an integrator that
never returns (a hung plug-in, a step size that underflows) cannot be stopped
inside Python, and a worker that dies (segfault, ``os._exit``, the OOM killer)
breaks a whole executor. Here the parent stops a worker past its step's limit,
reports the job as ``time limit`` or ``crashed`` (with the signal or exit code)
together with the step that was running, starts a new worker, and goes on.
What the job emitted before is kept. Workers end themselves within a second
when the parent dies (killed or not), so no worker outlives its CLI.

:func:`shared_pool` keeps one pool for the life of the process, so that later
sweeps (a multi-integrator sweep, the paper's sweeps, a benchmark's rounds)
reuse warm workers instead of paying the start of new processes each time.
"""

from __future__ import annotations

import os
import time
from collections import deque
from dataclasses import dataclass
from typing import Any, Hashable, Iterator

from nsbench.workers import pool as wp
from nsbench.workers import protocol as msg
from nsbench.errors import NsbenchError
from nsbench.status import OutcomeKind

#: Seconds a new worker may take to import nsbench and answer.
START_LIMIT = 300.0
#: Default limit of an integrator's set-up in a worker (construction, ``setup``: compilation from a
#: cold cache included, minutes on a busy machine): generous, a set-up that never ends is what it stops.
SETUP_LIMIT = 1800.0


@dataclass(frozen=True)
class Job:
    """One unit of work: ``target(*args, stage=, emit=)`` in a worker, identified by ``key``."""

    key: Hashable
    target: str
    args: tuple = ()


@dataclass(frozen=True)
class Outcome:
    """What became of a job, or a part of its result.

    Attributes
    ----------
    key
        The job's key.
    kind
        ``partial`` (``value`` is an emitted item; more follow), ``done``
        (``value`` is the job's return value), ``failed`` (the job raised:
        ``reason``), ``time limit`` (its step ``stage`` ran past its limit; the
        worker was ended) or ``crashed`` (the worker died during ``stage``:
        ``reason`` names the signal or exit code).
    detail
        A failed job's traceback, for the caller's log file (never printed by the worker).
    """

    key: Hashable
    kind: OutcomeKind
    value: Any = None
    stage: str = ""
    reason: str = ""
    detail: str = ""

    @property
    def final(self) -> bool:
        return self.kind is not OutcomeKind.PARTIAL


class _Slot:
    """One worker and the job it runs."""

    def __init__(self) -> None:
        self.worker: wp.WorkerProcess | None = None
        self.ready = False
        self.job: Job | None = None
        self.preparing = False  # ``job`` is the preparation sent with the start (its outcome is not reported)
        self.task = 0
        self.stage = ""
        self.limit: float | None = None
        self.deadline: float | None = None
        self.held: float | None = None  # seconds the stage had left when a compilation began (msg.held)


class JobPool:
    """Run jobs on ``workers`` supervised worker processes.

    Parameters
    ----------
    workers
        Worker processes (at least 1).

    Use as a context manager; :meth:`submit` jobs (also while iterating), and
    iterate :meth:`outcomes` until every submitted job has ended.
    """

    def __init__(self, workers: int, hello: msg.Hello | None = None) -> None:
        if workers < 1:
            raise ValueError(f"workers = {workers} must be at least 1")
        if hello is None:
            hello = wp.hello(shareable(_components()), "", {})
        self._hello = hello
        self._slots = [_Slot() for _ in range(workers)]
        self._queue: deque[Job] = deque()
        self._tasks = 0
        self._factory: wp.WorkerFactory | None = None
        self._no_factory = False  # one could not be started

    def __enter__(self) -> "JobPool":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()

    def submit(self, job: Job) -> None:
        self._queue.append(job)

    def start(self, prepare: Job | None = None) -> bool:
        """Start every worker process now, before any job (they import nsbench meanwhile).

        Returns whether any was started (``False``: all were running already). A
        command that starts its workers first overlaps their start with its own
        preparation; :meth:`outcomes` then reads their ``Ready`` as usual.

        ``prepare``: a job each started worker runs first, sent with its start
        (imports its later jobs need, say), so that the worker does not wait idle for
        the caller's first job. Its outcome is not reported; a worker that dies or
        hangs in it is a worker that could not start. It runs under the start's limit.
        """
        started = False
        factory = self._usable_factory()
        if factory is not None and prepare is not None and any(s.worker is None for s in self._slots):
            try:  # run once, in the factory, before it forks the workers
                factory.prepare(prepare.target, prepare.args)
            except OSError:
                factory = None
        for slot in self._slots:
            if slot.worker is None:
                self._new_worker(slot)
                started = True
                if prepare is not None and not isinstance(slot.worker, wp.ForkedWorker):
                    self._tasks += 1
                    slot.job, slot.task, slot.preparing = prepare, self._tasks, True
                    try:  # read by the worker right after its Ready
                        slot.worker.send(msg.Call(slot.task, prepare.target, prepare.args))
                    except (BrokenPipeError, OSError):
                        pass  # the worker is gone: its end of file is read next
        return started

    def _usable_factory(self) -> wp.WorkerFactory | None:
        """The worker factory (started now if there is none, or a new one if it has ended); ``None`` where
        workers are not forked (:func:`nsbench.workers.pool.can_fork`) or a factory could not be started."""
        if not wp.can_fork() or self._no_factory:
            return None
        if self._factory is not None and not self._factory.alive():
            self._factory.close()
            self._factory = None
        if self._factory is None:
            try:
                self._factory = wp.WorkerFactory(self._hello)
            except OSError:  # it would fail again: this pool starts its workers alone
                self._no_factory = True
                return None
        return self._factory

    def _new_worker(self, slot: _Slot) -> None:
        """A worker for ``slot``: forked from the factory, else started on its own."""
        factory = self._usable_factory()
        worker: wp.WorkerProcess | wp.ForkedWorker | None = None
        if factory is not None:
            try:
                worker = factory.fork()
            except OSError:  # the factory ended meanwhile: a worker of its own
                worker = None
        slot.worker, slot.ready = worker or wp.WorkerProcess(self._hello), False
        slot.stage, slot.limit = "worker start", START_LIMIT
        slot.deadline = time.monotonic() + START_LIMIT

    def drop_queued(self) -> list[Job]:
        """Remove the jobs not started yet from the queue and return them (they will not run)."""
        jobs = list(self._queue)
        self._queue.clear()
        return jobs

    def close(self) -> None:
        """End every worker (idle ones are asked to stop, busy ones are killed) and forget queued jobs.

        The pool stays usable: the next :meth:`submit` starts new workers.
        """
        self._queue.clear()
        idle = [s.worker for s in self._slots if s.worker is not None and s.job is None and s.ready]
        for worker in idle:  # every idle worker asked first, so that they end together
            worker.ask_to_stop()
        for slot in self._slots:
            if slot.worker is not None:
                if slot.worker in idle:
                    slot.worker.stop(timeout=2.0)
                else:
                    slot.worker.kill()
            slot.worker, slot.ready, slot.job, slot.deadline = None, False, None, None
            slot.preparing = False
        if self._factory is not None:
            self._factory.close()
            self._factory = None

    def abort(self) -> None:
        """End the pool at once: its factory process killed first, so that no worker is asked and waited
        for (input refused before any job ran: the command's one line should not wait on a worker that is
        still importing). Its workers then find the factory gone and leave; :meth:`close` collects them."""
        if self._factory is not None and self._factory.proc.poll() is None:
            self._factory.proc.kill()
            self._factory.proc.wait()
        self.close()

    # -------------------------------------------------------------------------------------------
    def outcomes(self) -> Iterator[Outcome]:
        """Outcomes in the order they happen, until no job is queued or running."""
        while self._queue or any(s.job is not None and not s.preparing for s in self._slots):
            self._dispatch()
            busy = [s for s in self._slots if s.worker is not None and (s.job is not None or not s.ready)]
            deadlines = [s.deadline for s in busy if s.deadline is not None]
            wait = max(0.0, min(deadlines) - time.monotonic()) if deadlines else None
            ready = wp.readable([s.worker for s in busy], wait)
            for slot in busy:
                if slot.worker in ready:
                    yield from self._read(slot)
            now = time.monotonic()
            for slot in self._slots:
                if slot.worker is not None and slot.deadline is not None and now >= slot.deadline:
                    yield from self._expire(slot)

    def _dispatch(self) -> None:
        for slot in self._slots:
            if not self._queue:
                return
            if slot.worker is None:
                self._new_worker(slot)
            if slot.ready and slot.job is None:
                self._tasks += 1
                slot.job, slot.task = self._queue.popleft(), self._tasks
                slot.stage, slot.limit, slot.deadline, slot.held = "", None, None, None
                try:
                    slot.worker.send(msg.Call(slot.task, slot.job.target, slot.job.args))
                except (BrokenPipeError, OSError):
                    pass  # the worker is gone: its end of file is read next

    def _read(self, slot: _Slot) -> Iterator[Outcome]:
        try:
            m = slot.worker.receive()
        except EOFError:
            yield from self._lost(slot)
            return
        if isinstance(m, msg.Ready):
            slot.ready = True
            if not slot.preparing:  # a preparation stays under the start's limit
                slot.stage, slot.deadline = "", None
        elif isinstance(m, msg.InitFailed):
            self.close()
            raise NsbenchError(f"a worker process could not start: {m.error}")
        elif slot.preparing:  # its end (or a stray message): the worker is now free for jobs
            if isinstance(m, (msg.Done, msg.Failed)):
                slot.job, slot.preparing, slot.stage, slot.deadline = None, False, "", None
        elif isinstance(m, msg.Stage):
            slot.stage, slot.limit, slot.held = m.what, m.limit, None
            slot.deadline = time.monotonic() + m.limit if m.limit is not None else None
        elif isinstance(m, msg.Compiling):  # nsbench's first-use cost: not the stage's time
            slot.deadline, slot.held = msg.held(slot.deadline, slot.held, m, time.monotonic())
        elif isinstance(m, msg.Partial):
            yield Outcome(slot.job.key, OutcomeKind.PARTIAL, m.item, slot.stage)
        elif isinstance(m, msg.Interrupted):
            raise KeyboardInterrupt
        elif isinstance(m, (msg.Done, msg.Failed)):
            job, stage = slot.job, slot.stage
            slot.job, slot.stage, slot.deadline = None, "", None
            # the worker's next job goes out before this outcome is handed on: what the caller does
            # with it (a sweep writes the chunk's table, a few ms) would otherwise leave the worker idle
            self._dispatch()
            if isinstance(m, msg.Done):
                yield Outcome(job.key, OutcomeKind.DONE, m.result, stage)
            else:
                yield Outcome(job.key, OutcomeKind.FAILED, None, stage, m.error, m.detail)

    def _lost(self, slot: _Slot) -> Iterator[Outcome]:
        job, stage = (None, "") if slot.preparing else (slot.job, slot.stage)
        slot.preparing = False
        reason = slot.worker.exit_reason()
        slot.worker.kill()
        slot.worker, slot.ready, slot.job, slot.deadline = None, False, None, None
        if job is None:  # died before its first job: nothing to attribute it to
            raise NsbenchError(f"a worker process ended while starting ({reason})")
        yield Outcome(
            job.key, OutcomeKind.CRASHED, None, stage, f"worker process ended ({reason}) during {stage or 'start'}"
        )

    def _expire(self, slot: _Slot) -> Iterator[Outcome]:
        job, stage, limit = (None, "", None) if slot.preparing else (slot.job, slot.stage, slot.limit)
        slot.preparing = False
        slot.worker.kill()
        slot.worker, slot.ready, slot.job, slot.deadline = None, False, None, None
        if job is None:
            raise NsbenchError(f"a worker process did not start within {START_LIMIT:g} s")
        yield Outcome(
            job.key,
            OutcomeKind.TIME_LIMIT,
            None,
            stage,
            f"{stage or 'the job'} ran past its limit of {limit:g} s (worker ended)",
        )


_SHARED: dict[tuple[int, bytes], JobPool] = {}


def _components() -> dict[str, dict[str, Any]]:
    import sys

    # a registry never imported holds no runtime registration; importing it (it reads the metadata
    # of every installed package) would only delay the start of a command's workers
    registry = sys.modules.get("nsbench.registry")
    return registry.runtime_components() if registry is not None else {}


def shared_pool(workers: int) -> JobPool:
    """A pool of ``workers`` kept for the life of this process (ended at exit).

    Use it without ``with``; after an exception during :meth:`JobPool.outcomes`
    (an interrupt, a worker that would not start), call :func:`drop_shared`, so
    that the next use starts clean. A pool is kept per set of runtime
    registrations: workers know the components registered when they started.
    """
    import atexit

    hello = wp.hello(shareable(_components()), "", {})
    key = (workers, hello.components)
    pool = _SHARED.get(key)
    if pool is None:
        for other in list(_SHARED.values()):  # one kept pool at a time: idle workers hold memory
            drop_shared(other)
        pool = _SHARED[key] = JobPool(workers, hello)
        atexit.register(pool.close)
    return pool


def default_workers() -> int:
    """One worker per core this process may run on (here, not with the sweeps: a command that starts
    its workers first imports no more than this module before they run)."""
    return max(1, len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1))


def check_limit(what: str, seconds: float | None) -> None:
    """A hard limit must be a finite number of seconds > 0, or ``None`` (no limit); ``ConfigError`` otherwise."""
    import math

    from nsbench.errors import ConfigError

    if seconds is not None and not (isinstance(seconds, (int, float)) and math.isfinite(seconds) and seconds > 0):
        raise ConfigError(f"{what} = {seconds!r} must be a finite number of seconds > 0, or None")


#: Name of the log of worker tracebacks in an output folder.
WORKER_LOG = "worker-errors.log"


class WorkerLog:
    """Tracebacks of the jobs that raised, appended to a log file; one line on stderr at the end.

    A worker prints nothing on the terminal it shares with the command: a plug-in whose ``setup``
    raises in every worker gave one traceback per worker before the command's clean outcome. The
    log is ``path`` (in the output folder), or, when the command has no output folder, a new
    temporary file named in the line.
    """

    def __init__(self, path: str | os.PathLike | None, what: str) -> None:
        self.path = None if path is None else os.fspath(path)
        self.what = what
        self.count = 0
        self.first = ""

    def add(self, label: str, reason: str, detail: str) -> None:
        """Record one failure (``label`` names the job, ``reason`` is its one-line error)."""
        import tempfile

        if not detail:
            return
        if self.path is None:
            fd, self.path = tempfile.mkstemp(prefix="nsbench-worker-errors-", suffix=".log")
            os.close(fd)
        self.count += 1
        self.first = self.first or reason
        text = f"--- {time.strftime('%Y-%m-%d %H:%M:%S')} {self.what}, {label}: {reason}\n{detail}\n"
        try:  # never through a link (the rule of every file nsbench writes in an output folder)
            fd = os.open(self.path, os.O_WRONLY | os.O_APPEND | os.O_CREAT | getattr(os, "O_NOFOLLOW", 0), 0o644)
            with os.fdopen(fd, "a", encoding="utf-8") as f:
                f.write(text)
        except OSError as exc:  # the log is an aid: its failure must not end the command
            self.first += f" (log {self.path} not written: {exc.strerror or exc})"

    def report(self, stream: Any = None) -> None:
        """One line on ``stream`` (stderr) if anything was logged."""
        import sys

        if self.count:
            print(
                f"nsbench: warning: {self.count} worker job(s) of {self.what} raised ({self.first}); "
                f"tracebacks in {self.path}",
                file=stream or sys.stderr,
                flush=True,
            )


#: Most worker processes an API call takes (the command line's ``--workers`` bound).
MAX_WORKERS = 1024


def check_count(what: str, value: object, low: int, high: int = MAX_WORKERS, none: bool = True) -> None:
    """A count argument of the API (workers, chunk size, limit) must be a whole number in ``[low, high]``
    (or ``None`` when ``none``); ``ConfigError`` naming it otherwise, where ``-1`` was silently read as 1
    and ``0`` ended in a ``ValueError`` from deep inside."""
    import numbers

    from nsbench.errors import ConfigError

    if value is None and none:
        return
    if isinstance(value, bool) or not isinstance(value, numbers.Integral) or not low <= value <= high:
        allowed = f"a whole number from {low} to {high}" + (", or None" if none else "")
        raise ConfigError(f"{what} = {value!r} must be {allowed}"[:300])


def worker_cpu_seconds() -> float:
    """CPU seconds used so far by the live workers of the kept pool and its worker factory (with the
    factory's workers that have ended) (Linux ``/proc``; 0 elsewhere).

    Ended workers started on their own are reaped by this process, so
    ``resource.getrusage(RUSAGE_CHILDREN)`` counts them; the kept pool's workers
    and factory are alive, so a caller measuring the CPU cost of its sweeps adds
    this (before and after).
    """
    total = 0.0
    for pool in _SHARED.values():
        if pool._factory is not None:  # its own time and that of the workers it forked that have ended
            total += pool._factory.cpu_seconds()
        for slot in pool._slots:
            if slot.worker is not None:
                total += wp.process_cpu_seconds(slot.worker.pid)
    return total


def drop_shared(pool: JobPool, at_once: bool = False) -> None:
    """End ``pool``'s workers and forget it (after an exception left it mid-job); ``at_once`` when nothing
    ran on it (:meth:`JobPool.abort`)."""
    if at_once:
        pool.abort()
    else:
        pool.close()
    for key, other in list(_SHARED.items()):
        if other is pool:
            del _SHARED[key]


def shareable(components: dict[str, dict[str, Any]]) -> dict[str, dict[str, Any]]:
    """The runtime registrations a worker can import (by kind; kinds without any left out, so that
    "nothing registered" has one form, whether the registry was imported or not)."""
    kept = {kind: {name: obj for name, obj in objs.items() if wp.importable(obj)} for kind, objs in components.items()}
    return {kind: objs for kind, objs in kept.items() if objs}
