"""Running a sweep: chunks of parameter values on supervised local workers or a Dask cluster.

Only the values missing from the store are computed; each finished chunk is
written at once, so an interrupted run loses at most the values in flight.

Every value runs in a supervised process (:mod:`nsbench.workers.jobs`), locally and on
a Dask cluster alike (there each Dask worker keeps its own supervised process):
every value has a hard time limit (``point_limit``), and a value whose
integrator never returns or whose process dies (segfault, ``os._exit``, out of
memory) becomes one row with status ``time limit`` or ``crashed`` and the
reason; the process is replaced and the rest of its chunk goes on. A process
sets up the integrator once (compilation, under ``setup_limit``) and runs it
once, short, at its first value (under ``point_limit``), then keeps it for every
later chunk. A set-up that fails, hangs or crashes fails every value of the
sweep not yet computed with that reason (it would fail again for each).
"""

from __future__ import annotations

import json
import math
import os
import pickle
import sys
import threading
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable

from nsbench.bifurcation.sweep import (
    Columns,
    SweepSpec,
    failure_columns,
    first_index,
    join_columns,
    points_columns,
    rows_frame,
)
from nsbench.workers.jobs import SETUP_LIMIT
from nsbench.progress import Progress
from nsbench.status import OutcomeKind, Status

if TYPE_CHECKING:  # pandas and the store are the calling process's: a worker never imports them
    import pandas as pd

    from nsbench.bifurcation.storage import SweepStore

#: Default hard limit of one parameter value (seconds): generous, a hung integrator is what it stops.
POINT_LIMIT = 600.0
#: The stage of a sweep job in which the integrator is set up (compiled) for the worker.
SETUP_STAGE = "integrator set-up"
#: Ends the message of every value failed by its integrator's set-up.
SETUP_FAILED = "the integrator could not be set up; no value was run"


def compute_chunk(spec_dict: dict, indices: list[int]) -> pd.DataFrame:
    """Rows of several parameter values (the unit of work sent to a worker)."""
    from nsbench.integrators import get_integrator

    from nsbench.engine import batch_size

    spec = SweepSpec.from_dict(spec_dict)
    integ = get_integrator(spec.integrator, **spec.options)
    size = batch_size(integ)
    return rows_frame(
        [c for g in range(0, len(indices), size) for c in points_columns(spec, indices[g : g + size], integ)]
    )


def chunks(indices: list[int], workers: int, size: int | None = None) -> list[list[int]]:
    """Split ``indices`` into chunks: about six per worker, at most 16 values each."""
    if not indices:
        return []
    if size is None:
        size = max(1, min(16, math.ceil(len(indices) / (6 * max(workers, 1)))))
    return [indices[i : i + size] for i in range(0, len(indices), size)]


def default_workers() -> int:
    """Local workers by default: one per core this process may run on."""
    from nsbench.workers.jobs import default_workers as cores

    return cores()


def run_sweep(
    spec: SweepSpec,
    out: str | os.PathLike,
    *,
    workers: int | None = None,
    dask: str | object | None = None,
    progress: bool = True,
    chunk_size: int | None = None,
    limit: int | None = None,
    point_limit: float | None = POINT_LIMIT,
    setup_limit: float | None = SETUP_LIMIT,
    fresh: bool = False,
) -> pd.DataFrame:
    """Compute every missing value of ``spec`` into the store at ``out``; return all rows.

    Parameters
    ----------
    workers
        Local worker processes, 0 to 1024 (default: every core). ``0`` computes in this
        process, without hard limits (for debugging and profiling).
    dask
        Address of a Dask scheduler (``tcp://host:port``) or a ``distributed.Client``;
        replaces local processes. Each Dask worker runs its chunks in a
        supervised process of its own, under the same limits.
    chunk_size
        Values per job, a whole number >= 1 (default: about six jobs per worker, at most 16 values each).
    limit
        Compute at most this many missing values (then stop; a rerun resumes).
    point_limit, setup_limit
        Hard limits in seconds of one value (the first short run included), and
        of a worker's integrator set-up (compilation); ``None``: no limit.
    fresh
        Discard what ``out`` holds first (it must be a sweep folder); by default
        a rerun resumes, computing only the missing values.
    """
    from nsbench.bifurcation.storage import SweepStore
    from nsbench.errors import ConfigError
    from nsbench.workers.jobs import check_count, check_limit

    if not isinstance(spec, SweepSpec):
        raise ConfigError(f"spec must be a SweepSpec, got {type(spec).__name__} {spec!r}"[:300])
    if isinstance(out, bool) or not isinstance(out, (str, os.PathLike)) or not str(out):
        raise ConfigError(f"out = {out!r} must be the path of a sweep folder (a str or os.PathLike)"[:300])
    check_count("workers", workers, 0)
    check_count("chunk_size", chunk_size, 1, 1_000_000)
    check_count("limit", limit, 0, 1_000_000)
    check_limit("point_limit", point_limit)
    check_limit("setup_limit", setup_limit)
    if dask is not None and workers is not None:
        from nsbench.errors import ConfigError

        raise ConfigError("give either workers or a Dask address, not both")
    spec.check()
    if fresh:
        from nsbench.bifurcation.storage import clear_sweep

        clear_sweep(out)
    try:
        store = SweepStore(out, spec)
    except OSError as exc:  # a read-only or virtual file system (/proc): the argument, not a crash
        raise ConfigError(f"out = {str(out)!r}: cannot create the sweep folder: {exc.strerror or exc}") from None
    store.discard_damaged()  # named on stderr, computed again below
    todo = store.missing()
    if limit is not None:
        todo = todo[:limit]
    n_workers = workers if workers is not None else default_workers()
    parts = chunks(todo, n_workers if dask is None else 8, chunk_size)
    bar = Progress(len(todo), label=f"{spec.name}", enabled=progress)
    from nsbench.workers.jobs import WORKER_LOG, WorkerLog

    log = WorkerLog(Path(out) / WORKER_LOG, f"the {spec.name} sweep with {spec.integrator}")
    try:
        if not parts:
            pass
        elif dask is not None:
            _run_dask(spec, parts, store, bar, dask, point_limit, setup_limit)
        elif n_workers == 0:
            for part in parts:
                store.write(compute_chunk(spec.to_dict(), part))
                bar.update(len(part))
        else:
            from nsbench.workers.jobs import drop_shared, shared_pool

            pool = shared_pool(n_workers)  # warm workers of an earlier sweep in this process are reused
            try:
                supervise(pool, spec, parts, point_limit, setup_limit, store.write, bar.update, log)
            except BaseException:
                drop_shared(pool)  # jobs were in flight: the next sweep starts with fresh workers
                raise
    finally:
        bar.close()
        log.report()
    return store.load()


def supervise(
    pool: Any,
    spec: SweepSpec,
    parts: list[list[int]],
    point_limit: float | None,
    setup_limit: float | None,
    write: Callable[[Columns], Any],
    advance: Callable[[int], Any] = lambda n: None,
    log: Any = None,
) -> None:
    """Run the chunks ``parts`` of ``spec`` on the :class:`~nsbench.workers.jobs.JobPool` ``pool``.

    ``write`` receives the rows of each chunk as it ends, as columns (and, after an
    interruption, every row received), ``advance`` the number of values done.
    A value that runs past ``point_limit``, crashes its process or raises is
    stored as one row with that status and reason, and the rest of its chunk
    goes on in a fresh process. A set-up that does so fails every value not yet
    computed: it would fail again for each of them. The traceback of a job that raised
    goes to ``log`` (a :class:`~nsbench.workers.jobs.WorkerLog`), or, without one, to stderr.
    """
    from nsbench.workers.jobs import Job

    spec_dict = spec.to_dict()
    left: dict[int, list[int]] = {}  # job -> its values not yet received, in computing order
    got: dict[int, list] = {}  # job -> the columns of each value received, written as one table when it ends

    def submit(indices: list[int]) -> None:
        key = len(left)
        left[key], got[key] = list(indices), []
        pool.submit(Job(key, f"{__name__}:sweep_job", (spec_dict, indices, point_limit, setup_limit)))

    for part in parts:
        submit(part)
    try:
        for o in pool.outcomes():
            if o.kind is OutcomeKind.PARTIAL:
                got[o.key].append(o.value)
                left[o.key].remove(first_index(o.value))
                advance(1)
                continue
            rest, rows = left[o.key], got.pop(o.key)
            left[o.key] = []
            if o.detail:
                which = f"value {rest[0]}" if len(rest) == 1 else f"values {rest[0]}..{rest[-1]}" if rest else "a job"
                label = f"{which} ({o.stage or 'start'})"
                if log is not None:
                    log.add(label, o.reason, o.detail)
                else:  # a Dask worker's own supervision: its log is its stderr
                    print(o.detail, file=sys.stderr, end="", flush=True)
            if o.kind is not OutcomeKind.DONE and rest:
                status = o.kind.status.value  # error, time limit or crashed
                if o.stage.startswith("value"):  # that value's result; the rest of its chunk goes on
                    rows.append(failure_columns(spec, rest[0], status, o.reason))
                    advance(1)
                    if rest[1:]:
                        submit(rest[1:])
                else:  # the set-up: it would fail again for every value, so it is the result of them all
                    for job in pool.drop_queued():
                        rest += left.pop(job.key)
                        got.pop(job.key)
                    reason = f"{o.reason} ({SETUP_FAILED})"
                    rows += [failure_columns(spec, i, status, reason) for i in rest]
                    advance(len(rest))
            if rows:
                write(join_columns(rows))
    finally:  # an interrupted run keeps every value received
        for rows in got.values():
            if rows:
                write(join_columns(rows))


def prepare_job(*, stage: Callable[[str, float | None], None], emit: Callable[[Any], None]) -> None:
    """What every sweep worker loads before its first value, run as it starts (see
    :meth:`nsbench.workers.jobs.JobPool.start`), while the command is still preparing the sweep:
    the hybrid core with numba, the integrators, and numba's own start (its registries of
    compiled operations, read on the first use of any compiled function). About 0.8 s of
    a worker's 1 s set-up, otherwise spent after the command sends the first chunk."""
    import nsbench.engine  # noqa: F401 - numba and the core's modules
    from nsbench.integrators import get_integrator  # noqa: F401

    try:  # numba's internals: without them, the first compiled call does this instead
        from numba.core.registry import cpu_target

        cpu_target.target_context.refresh()
    except (ImportError, AttributeError):  # pragma: no cover - another numba
        pass


#: Per worker process: the integrator of the last sweep, set up and run once (compiled code loaded).
_WARM: dict[str, Any] = {}


def sweep_job(
    spec_dict: dict,
    indices: list[int],
    point_limit: float | None,
    setup_limit: float | None,
    *,
    stage: Callable[[str, float | None], None],
    emit: Callable[[Any], None],
) -> int:
    """A chunk of values in a supervised worker (:mod:`nsbench.workers.jobs`): each value's rows emitted at once.

    The integrator's set-up (construction, ``setup``, loading or compiling the
    core) runs under ``setup_limit``; everything that runs the integrator (the
    first short run, then each value) under ``point_limit``.
    """
    from nsbench.engine import prepare
    from nsbench.integrators import get_integrator

    from nsbench.engine import batch_size

    spec = SweepSpec.from_dict(spec_dict)
    key = json.dumps([spec.integrator, spec.options], sort_keys=True, default=str)
    integ = _WARM.get(key)
    if integ is None and indices:
        i = indices[0]
        stage(SETUP_STAGE, setup_limit)
        integ = get_integrator(spec.integrator, **spec.options)
        problem = spec.problem_at(spec.values[i])
        prepare(problem, integ)  # the compiled core, loaded or compiled: set-up, not the value's time
        stage(f"value {i} ({spec.name} = {spec.values[i]:.10g}), a first short run", point_limit)
        first = replace(spec, transient=0.0, record=1, window=None)
        points_columns(first, indices[: batch_size(integ)][:2], integ)  # first use (of the batch mode too)
        _WARM.clear()
        _WARM[key] = integ
    # a batch integrator runs its lanes' values together: the group's limit is theirs summed
    size = batch_size(integ) if integ is not None else 1
    for g in range(0, len(indices), size):
        group = indices[g : g + size]
        label = f"value {group[0]} ({spec.name} = {spec.values[group[0]]:.10g})"
        if len(group) > 1:
            label = f"values {group[0]} to {group[-1]} ({spec.name} = {spec.values[group[0]]:.10g} to {spec.values[group[-1]]:.10g})"
        stage(label, None if point_limit is None else point_limit * len(group))
        for columns in points_columns(spec, group, integ):
            emit(columns)
    return len(indices)


def _set_up(spec: SweepSpec, value: float, setup_limit: float | None, stage: Callable) -> Any:
    """The sweep's integrator, set up at ``value`` with the compiled core loaded, under ``setup_limit``."""
    from nsbench.engine import prepare
    from nsbench.integrators import get_integrator

    stage(SETUP_STAGE, setup_limit)
    integ = get_integrator(spec.integrator, **spec.options)
    prepare(spec.problem_at(value), integ)
    return integ


def refine_job(
    spec_dict: dict,
    left: float,
    right: float,
    kind: str,
    point_limit: float | None,
    setup_limit: float | None = SETUP_LIMIT,
    *,
    stage: Callable[[str, float | None], None],
    emit: Callable[[Any], None],
) -> dict:
    """:func:`nsbench.bifurcation.detect.refine` in a supervised worker, each value under ``point_limit``."""
    from nsbench.bifurcation.detect import refine

    spec = SweepSpec.from_dict(spec_dict)
    _set_up(spec, left, setup_limit, stage)  # compiled code loaded in this process: not a value's time
    found = refine(
        spec,
        left,
        right,
        kind,
        before=lambda v: stage(f"refining a {kind} change at {spec.name} = {v:.10g}", point_limit),
    )
    return {"left": found.left, "right": found.right, "value": found.value}


def locus_job(
    spec_dict: dict,
    value: float,
    pair: tuple[int, int],
    point_limit: float | None,
    setup_limit: float | None = SETUP_LIMIT,
    *,
    stage: Callable[[str, float | None], None],
    emit: Callable[[Any], None],
) -> Any:
    """The locus-of-sticking run of a portrait (:func:`nsbench.bifurcation.locus.locus_run`), supervised."""
    from nsbench.bifurcation.locus import locus_run

    spec = SweepSpec.from_dict(spec_dict)
    integ = _set_up(spec, value, setup_limit, stage)
    stage(f"the locus run at {spec.name} = {value:.10g}", point_limit)
    return locus_run(
        spec.problem_at(value),
        integ,
        transient=spec.transient,
        duration=min(300.0, spec.record_window),
        value=value,
        pair=pair,
    )


def supervised(target: str, args: tuple, workers: int = 1, log: Any = None) -> tuple[Any, str]:
    """``(result, '')`` of the job ``target(*args)`` on the kept pool, or ``(None, reason)`` if it raised,
    ran past a limit it announced, or its worker died: a plug-in's fault costs that result only.
    The traceback of a job that raised goes to ``log`` (a :class:`~nsbench.workers.jobs.WorkerLog`)."""
    from nsbench.workers.jobs import Job, drop_shared, shared_pool

    pool = shared_pool(max(1, workers))
    pool.submit(Job("call", f"{__name__}:{target}", args))
    result, reason = None, ""
    try:
        for o in pool.outcomes():
            if o.kind is OutcomeKind.DONE:
                result = o.value
            elif o.final:
                reason = f"{o.kind}: {o.reason}"
                if o.detail and log is not None:
                    log.add(target, o.reason, o.detail)
    except BaseException:
        drop_shared(pool)
        raise
    return result, reason


#: Seconds a Dask cluster may have no worker while chunks are pending before the sweep stops.
NO_WORKER_LIMIT = 60.0


def _run_dask(
    spec: SweepSpec,
    parts: list[list[int]],
    store: SweepStore,
    bar: Progress,
    dask,
    point_limit: float | None,
    setup_limit: float | None,
) -> None:
    import time

    from distributed import Client, wait

    from nsbench import registry
    from nsbench.errors import NsbenchError
    from nsbench.workers.jobs import shareable

    own = not isinstance(dask, Client)
    client = Client(dask, set_as_default=False) if own else dask
    # components registered in this process (from importable modules) are registered on the workers too
    components = pickle.dumps(shareable(registry.runtime_components()))
    futures: list = []
    try:
        futures = [
            client.submit(dask_chunk, spec.to_dict(), part, point_limit, setup_limit, components, pure=False)
            for part in parts
        ]
        part_of = {f.key: p for f, p in zip(futures, parts)}
        pending, alone_since = set(futures), None
        with client.as_current():  # distributed.wait() uses the current client, and ours may not be the default
            while pending:
                try:
                    done, pending = wait(pending, timeout=2.0, return_when="FIRST_COMPLETED")
                except TimeoutError:  # nothing finished in 2 s (distributed raises instead of returning)
                    done = set()
                failed_setup = None
                for fut in done:
                    rows = _dask_rows(spec, fut, part_of[fut.key])
                    store.write(rows)
                    bar.update(len(part_of[fut.key]))
                    hit = rows[rows["message"].str.endswith(f"({SETUP_FAILED})")]
                    if len(hit) and failed_setup is None:
                        failed_setup = hit.iloc[0]
                if failed_setup is not None and pending:  # every other chunk would fail the same way
                    client.cancel(list(pending))
                    indices = [i for f in pending for i in part_of[f.key]]
                    store.write(
                        rows_frame(
                            [failure_columns(spec, i, failed_setup["status"], failed_setup["message"]) for i in indices]
                        )
                    )
                    bar.update(len(indices))
                    pending = set()
                # a cluster whose last worker is gone would leave the futures waiting forever
                if done or not pending or client.scheduler_info().get("workers"):
                    alone_since = None
                elif alone_since is None:
                    alone_since = time.monotonic()
                elif time.monotonic() - alone_since > NO_WORKER_LIMIT:
                    raise NsbenchError(
                        f"the Dask cluster at {client.scheduler.address} has had no worker for "
                        f"{NO_WORKER_LIMIT:g} s with {len(pending)} chunk(s) pending; the "
                        "finished values are stored: rerun to compute the rest"
                    )
    except BaseException:
        client.cancel(futures)
        raise
    finally:
        if own:
            client.close()


def _dask_rows(spec: SweepSpec, future: Any, indices: list[int]) -> pd.DataFrame:
    """The rows a Dask task returned; if the task itself failed (its Dask worker lost, say), one
    ``failure`` row per value with the reason."""
    try:
        return future.result()
    except Exception as exc:  # noqa: BLE001 - KilledWorker, a worker without nsbench...: the values' result
        reason = f"the Dask task failed: {type(exc).__name__}: {' '.join(str(exc).split())}"
        return rows_frame([failure_columns(spec, i, Status.ERROR.value, reason) for i in indices])


#: Per thread of a Dask worker: its supervised process pool (a pool serves one caller at a time).
_DASK_POOLS = threading.local()


def dask_chunk(
    spec_dict: dict, indices: list[int], point_limit: float | None, setup_limit: float | None, components: bytes = b""
) -> pd.DataFrame:
    """The rows of a chunk, computed on a Dask worker in a supervised process of its own.

    A value that hangs or kills its process costs that value (a ``time limit``
    or ``crashed`` row), never the Dask worker: Dask would otherwise retry the
    chunk on other workers and give up with ``KilledWorker``, or wait forever.
    ``components`` (a pickle) are the runtime registrations of the submitting
    process, registered here first.
    """
    import atexit

    from nsbench import registry
    from nsbench.workers.jobs import JobPool

    for kind, objs in (pickle.loads(components) if components else {}).items():
        for name, obj in objs.items():
            registry.register(kind, name, obj)
    pool = getattr(_DASK_POOLS, "pool", None)
    if pool is not None and _DASK_POOLS.components != components:  # its process knows other components
        pool.close()
        pool = None
    if pool is None:
        pool = _DASK_POOLS.pool = JobPool(1)
        _DASK_POOLS.components = components
        atexit.register(pool.close)
    rows: list[Columns] = []
    spec = SweepSpec.from_dict(spec_dict)
    try:
        supervise(pool, spec, [list(indices)], point_limit, setup_limit, rows.append)
    except BaseException:
        pool.close()  # the next chunk on this thread starts a fresh process
        raise
    return rows_frame(rows).sort_values(["index", "k"], kind="stable", ignore_index=True)
