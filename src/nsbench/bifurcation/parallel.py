"""Running a sweep: chunks of parameter values on supervised local workers or a Dask cluster.

Only the values missing from the store are computed; each finished chunk is
written at once, so an interrupted run loses at most the values in flight.

Local workers are supervised processes (:mod:`nsbench.jobs`): every value has
a hard time limit (``point_limit``), and a value whose integrator never returns
or whose worker dies (segfault, ``os._exit``, out of memory) becomes one row
with status ``time limit`` or ``crashed`` and the reason; the worker is
replaced and the rest of its chunk goes on. A worker sets up the integrator
once and runs it once, short, before its first value (compilation and first
use, under ``setup_limit``), then keeps it for every later chunk.
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import replace
from typing import Any, Callable

import pandas as pd

from nsbench.bifurcation.storage import SweepStore
from nsbench.bifurcation.sweep import SweepSpec, compute_point, failure_rows
from nsbench.progress import Progress

#: Default hard limit of one parameter value (seconds): generous, a hung integrator is what it stops.
POINT_LIMIT = 600.0
#: Default limit of a worker's set-up and first short run (compilation from a cold cache included).
SETUP_LIMIT = 1800.0

def compute_chunk(spec_dict: dict, indices: list[int]) -> pd.DataFrame:
    """Rows of several parameter values (the unit of work sent to a worker)."""
    from nsbench.integrators import get_integrator

    spec = SweepSpec.from_dict(spec_dict)
    integ = get_integrator(spec.integrator, **spec.options)
    return pd.concat([compute_point(spec, i, integ) for i in indices], ignore_index=True)


def chunks(indices: list[int], workers: int, size: int | None = None) -> list[list[int]]:
    """Split ``indices`` into chunks: about six per worker, at most 16 values each."""
    if not indices:
        return []
    if size is None:
        size = max(1, min(16, math.ceil(len(indices) / (6 * max(workers, 1)))))
    return [indices[i:i + size] for i in range(0, len(indices), size)]


def default_workers() -> int:
    return max(1, len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1))


def run_sweep(spec: SweepSpec, out: str | os.PathLike, *, workers: int | None = None,
              dask: str | object | None = None, progress: bool = True, chunk_size: int | None = None,
              limit: int | None = None, point_limit: float | None = POINT_LIMIT,
              setup_limit: float | None = SETUP_LIMIT, fresh: bool = False) -> pd.DataFrame:
    """Compute every missing value of ``spec`` into the store at ``out``; return all rows.

    Parameters
    ----------
    workers
        Local worker processes (default: every core). ``0`` computes in this
        process, without hard limits (for debugging and profiling).
    dask
        Address of a Dask scheduler (``tcp://host:port``) or a ``distributed.Client``;
        replaces local processes.
    limit
        Compute at most this many missing values (then stop; a rerun resumes).
    point_limit, setup_limit
        Hard limits in seconds (local workers) of one value, and of a worker's
        integrator set-up with its first short run; ``None``: no limit.
    fresh
        Discard what ``out`` holds first (it must be a sweep folder); by default
        a rerun resumes, computing only the missing values.
    """
    spec.check()
    if fresh:
        from nsbench.bifurcation.storage import clear_sweep

        clear_sweep(out)
    store = SweepStore(out, spec)
    store.discard_damaged()  # named on stderr, computed again below
    todo = store.missing()
    if limit is not None:
        todo = todo[:limit]
    n_workers = workers if workers is not None else default_workers()
    from nsbench.jobs import check_limit

    check_limit("point_limit", point_limit)
    check_limit("setup_limit", setup_limit)
    if dask is not None and workers is not None:
        from nsbench.errors import ConfigError

        raise ConfigError("give either workers or a Dask address, not both")
    parts = chunks(todo, n_workers if dask is None else 8, chunk_size)
    bar = Progress(len(todo), label=f"{spec.name}", enabled=progress)
    try:
        if not parts:
            pass
        elif dask is not None:
            _run_dask(spec, parts, store, bar, dask)
        elif n_workers == 0:
            for part in parts:
                store.write(compute_chunk(spec.to_dict(), part))
                bar.update(len(part))
        else:
            _run_local(spec, parts, store, bar, n_workers, point_limit, setup_limit)
    finally:
        bar.close()
    return store.load()


def _run_local(spec: SweepSpec, parts: list[list[int]], store: SweepStore, bar: Progress, workers: int,
               point_limit: float | None, setup_limit: float | None) -> None:
    from nsbench.jobs import Job, JobPool, drop_shared, shared_pool

    spec_dict = spec.to_dict()
    left: dict[int, list[int]] = {}  # job -> its values not yet received, in computing order
    got: dict[int, list[pd.DataFrame]] = {}  # job -> rows received, written when it ends

    def submit(pool: JobPool, indices: list[int]) -> None:
        key = len(left)
        left[key], got[key] = list(indices), []
        pool.submit(Job(key, f"{__name__}:sweep_job", (spec_dict, indices, point_limit, setup_limit)))

    pool = shared_pool(workers)  # warm workers of an earlier sweep in this process are reused
    for part in parts:
        submit(pool, part)
    try:
        for o in pool.outcomes():
            if o.kind == "partial":
                got[o.key].append(o.value)
                left[o.key].remove(int(o.value["index"].iloc[0]))
                bar.update(1)
                continue
            rest, rows = left[o.key], got.pop(o.key)
            left[o.key] = []
            if o.kind != "done" and rest:
                status = {"failed": "failure"}.get(o.kind, o.kind)
                # a value running when its job stopped is that value's result; a set-up that
                # fails would fail again for every value, so it is the result of them all
                blamed = rest[:1] if o.stage.startswith("value") else rest
                rows += [failure_rows(spec, i, status, o.reason) for i in blamed]
                bar.update(len(blamed))
                if len(blamed) < len(rest):
                    submit(pool, rest[1:])
            if rows:
                store.write(pd.concat(rows, ignore_index=True))
    except BaseException:
        drop_shared(pool)  # jobs were in flight: the next sweep starts with fresh workers
        raise
    finally:  # an interrupted run keeps every value received
        for rows in got.values():
            if rows:
                store.write(pd.concat(rows, ignore_index=True))


#: Per worker process: the integrator of the last sweep, set up and run once (compiled code loaded).
_WARM: dict[str, Any] = {}


def sweep_job(spec_dict: dict, indices: list[int], point_limit: float | None, setup_limit: float | None, *,
              stage: Callable[[str, float | None], None], emit: Callable[[Any], None]) -> int:
    """A chunk of values in a supervised worker (:mod:`nsbench.jobs`): each value's rows emitted at once."""
    from nsbench.integrators import get_integrator

    spec = SweepSpec.from_dict(spec_dict)
    key = json.dumps([spec.integrator, spec.options], sort_keys=True, default=str)
    integ = _WARM.get(key)
    if integ is None:
        stage("integrator set-up and a first short run", setup_limit)
        integ = get_integrator(spec.integrator, **spec.options)
        compute_point(replace(spec, transient=0.0, record=1, window=None), 0, integ)  # compiles, loads
        _WARM.clear()
        _WARM[key] = integ
    for i in indices:
        stage(f"value {i} ({spec.name} = {spec.values[i]:.10g})", point_limit)
        emit(compute_point(spec, i, integ))
    return len(indices)


#: Seconds a Dask cluster may have no worker while chunks are pending before the sweep stops.
NO_WORKER_LIMIT = 60.0


def _run_dask(spec: SweepSpec, parts: list[list[int]], store: SweepStore, bar: Progress, dask,
              no_worker_limit: float = NO_WORKER_LIMIT) -> None:
    import time

    from distributed import Client, wait

    from nsbench.errors import NsbenchError

    own = not isinstance(dask, Client)
    client = Client(dask) if own else dask
    futures: list = []
    try:
        futures = [client.submit(compute_chunk, spec.to_dict(), part, pure=False) for part in parts]
        sizes = {f.key: len(p) for f, p in zip(futures, parts)}
        pending, alone_since = set(futures), None
        while pending:
            try:
                done, pending = wait(pending, timeout=2.0, return_when="FIRST_COMPLETED")
            except TimeoutError:  # nothing finished in 2 s (distributed raises instead of returning)
                done = set()
            for fut in done:
                store.write(fut.result())
                bar.update(sizes[fut.key])
            # a cluster whose last worker is gone would leave the futures waiting forever
            if done or client.scheduler_info().get("workers"):
                alone_since = None
            elif alone_since is None:
                alone_since = time.monotonic()
            elif time.monotonic() - alone_since > no_worker_limit:
                raise NsbenchError(f"the Dask cluster at {client.scheduler.address} has had no worker for "
                                   f"{no_worker_limit:g} s with {len(pending)} chunk(s) pending; the finished "
                                   "values are stored: rerun to compute the rest")
    except BaseException:
        client.cancel(futures)
        raise
    finally:
        if own:
            client.close()
