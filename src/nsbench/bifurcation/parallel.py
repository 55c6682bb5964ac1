"""Running a sweep: chunks of parameter values on local processes or a Dask cluster.

Only the values missing from the store are computed; each finished chunk is
written at once, so an interrupted run loses at most the chunks in flight.
Workers rebuild the integrator once per chunk (compiled code comes from
numba's on-disk cache).
"""

from __future__ import annotations

import math
import os
from typing import Iterable

import pandas as pd

from nsbench.bifurcation.progress import Progress
from nsbench.bifurcation.storage import SweepStore
from nsbench.bifurcation.sweep import SweepSpec, compute_point


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
              limit: int | None = None) -> pd.DataFrame:
    """Compute every missing value of ``spec`` into the store at ``out``; return all rows.

    Parameters
    ----------
    workers
        Local processes (default: every core); 1 computes in this process.
    dask
        Address of a Dask scheduler (``tcp://host:port``) or a ``distributed.Client``;
        replaces local processes.
    limit
        Compute at most this many missing values (then stop; a rerun resumes).
    """
    spec.check()
    store = SweepStore(out, spec)
    todo = store.missing()
    if limit is not None:
        todo = todo[:limit]
    n_workers = workers if workers is not None else default_workers()
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
        elif n_workers <= 1 or len(parts) == 1:
            for part in parts:
                store.write(compute_chunk(spec.to_dict(), part))
                bar.update(len(part))
        else:
            _run_local(spec, parts, store, bar, n_workers)
    finally:
        bar.close()
    return store.load()


def _run_local(spec: SweepSpec, parts: Iterable[list[int]], store: SweepStore, bar: Progress,
               workers: int) -> None:
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor, as_completed

    # fork shares the parent's imports (fast start, no __main__ guard needed);
    # the parent runs no threads of its own, so forking it is safe
    methods = multiprocessing.get_all_start_methods()
    ctx = multiprocessing.get_context("fork" if "fork" in methods else "spawn")
    pool = ProcessPoolExecutor(max_workers=workers, mp_context=ctx)
    try:
        futures = {pool.submit(compute_chunk, spec.to_dict(), part): part for part in parts}
        for fut in as_completed(futures):
            store.write(fut.result())
            bar.update(len(futures[fut]))
    except BaseException:
        pool.shutdown(wait=False, cancel_futures=True)
        raise
    pool.shutdown()


def _run_dask(spec: SweepSpec, parts: list[list[int]], store: SweepStore, bar: Progress, dask) -> None:
    from distributed import Client, as_completed

    own = not isinstance(dask, Client)
    client = Client(dask) if own else dask
    futures: list = []
    try:
        futures = [client.submit(compute_chunk, spec.to_dict(), part, pure=False) for part in parts]
        sizes = {f.key: len(p) for f, p in zip(futures, parts)}
        for fut in as_completed(futures):
            store.write(fut.result())
            bar.update(sizes[fut.key])
    except BaseException:
        client.cancel(futures)
        raise
    finally:
        if own:
            client.close()
