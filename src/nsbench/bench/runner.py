"""The suite runner: expand a suite into cases, run the missing ones across processes,
append each row as it finishes.

Workers are fresh interpreters (``spawn``), so integrators with compiled state are
built inside them. At most one case per worker is in flight, so when a worker
dies (a crash in compiled code) the suspects are known: each is re-run alone and
recorded as ``crashed`` if it brings its worker down again. An interruption
keeps every finished row; the next run with ``resume`` computes only the rest.
"""

from __future__ import annotations

import multiprocessing
import os
import shutil
import sys
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, TextIO

import pandas as pd

from nsbench.bench import storage
from nsbench.bench.execute import base_row, run_case
from nsbench.bench.progress import Progress
from nsbench.bench.reference import Reference, candidates, compute_reference, load_reference, reference_key, save_reference
from nsbench.bench.suite import Case, Suite, load_suite


@dataclass
class RunSummary:
    """What a run did: how many cases the suite has, were already stored, were computed."""

    out: Path
    n_cases: int
    n_resumed: int
    n_computed: int
    results: pd.DataFrame


def _init_worker(runtime: dict[str, dict[str, Any]]) -> None:
    from nsbench import registry

    for kind, objs in runtime.items():
        for name, obj in objs.items():
            registry.register(kind, name, obj)  # in-process registrations follow the work


def _pool(workers: int) -> ProcessPoolExecutor:
    from nsbench import registry

    return ProcessPoolExecutor(max_workers=workers, mp_context=multiprocessing.get_context("spawn"),
                               initializer=_init_worker, initargs=(registry.runtime_components(),))


def _kill(pool: ProcessPoolExecutor) -> None:
    """Stop a pool now, running tasks included (an interrupt must not wait for them)."""
    for proc in list(getattr(pool, "_processes", {}).values()):
        if proc.is_alive():
            proc.terminate()
    pool.shutdown(wait=True, cancel_futures=True)


def _map(fn: Callable, tasks: list[tuple], workers: int, on_done: Callable[[tuple, Any], None],
         on_crash: Callable[[tuple], None]) -> None:
    """Run ``fn(*task)`` for every task with ``workers`` processes (in-process if 1).

    ``on_done(task, result)`` runs in this process as each task finishes.
    """
    if workers <= 1:
        for task in tasks:
            on_done(task, fn(*task))
        return
    queue = list(reversed(tasks))
    suspects: list[tuple] = []
    pool = _pool(workers)
    running: dict[Future, tuple] = {}
    try:
        while queue or running:
            while queue and len(running) < workers:
                task = queue.pop()
                running[pool.submit(fn, *task)] = task
            finished, _ = wait(running, return_when=FIRST_COMPLETED)
            for fut in finished:
                task = running.pop(fut)
                try:
                    result = fut.result()
                except BrokenProcessPool:
                    suspects.append(task)
                    continue
                on_done(task, result)
            if suspects:  # the pool is dead: every task in flight is a suspect
                suspects.extend(running.values())
                running.clear()
                pool.shutdown(wait=True, cancel_futures=True)
                for task in suspects:
                    _isolated(fn, task, on_done, on_crash)
                suspects = []
                pool = _pool(workers)
    except BaseException:
        # Keep what finished before the interrupt, then stop the workers at once.
        for fut, task in list(running.items()):
            if fut.done() and not fut.cancelled() and fut.exception() is None:
                on_done(task, fut.result())
        _kill(pool)
        raise
    pool.shutdown(wait=True)


def _isolated(fn: Callable, task: tuple, on_done, on_crash) -> None:
    pool = _pool(1)
    try:
        on_done(task, pool.submit(fn, *task).result())
    except BrokenProcessPool:
        on_crash(task)
    finally:
        pool.shutdown(wait=True)


def _references(suite: Suite, pending: list[Case], out: Path, workers: int) -> dict[str, Reference]:
    """The reference of every problem of ``pending``: from the cache, else computed (in parallel)."""
    cands = candidates(suite.reference)
    t0, t_end = suite.t_span
    refs: dict[str, Reference] = {}
    todo: dict[str, tuple] = {}
    for case in pending:
        key = reference_key(case.problem, cands, t0, t_end, suite.dense_points)
        if key in refs or key in todo:
            continue
        cached = load_reference(out / "references", key)
        if cached is not None:
            refs[key] = cached
        else:
            todo[key] = (case.problem, cands, t0, t_end, suite.dense_points)

    def done(task: tuple, ref: Reference) -> None:
        save_reference(out / "references", ref)
        refs[ref.key] = ref

    def crashed(task: tuple) -> None:
        key = reference_key(task[0], cands, t0, t_end, suite.dense_points)
        refs[key] = compute_reference(task[0], [], t0, t_end, suite.dense_points)
        refs[key].status = "no reference available: the reference run crashed its worker"
        refs[key].key = key

    _map(compute_reference, list(todo.values()), min(workers, len(todo)), done, crashed)
    return refs


def run_suite(suite: Suite | str | Path | dict, out: str | Path, *, workers: int | None = None,
              resume: bool = True, progress: bool = True, stream: TextIO | None = None,
              provenance_extra: dict[str, Any] | None = None) -> RunSummary:
    """Run every case of ``suite`` that ``out`` does not hold yet, and export the results.

    Parameters
    ----------
    suite
        A :class:`Suite`, a TOML path, a dict, or ``'default'``.
    out
        Output directory (see :mod:`nsbench.bench.storage` for its layout).
    workers
        Processes (default: all cores); 1 runs in this process.
    resume
        Keep the cases already stored in ``out`` (default); ``False`` discards them first.
    progress, stream
        Show a progress bar on ``stream`` (default stderr).
    """
    from nsbench.provenance import provenance

    suite = load_suite(suite)
    out = Path(out)
    if not resume and (out / "cases").exists():
        shutil.rmtree(out / "cases")
    out.mkdir(parents=True, exist_ok=True)
    cases = list({c.case_id: c for c in suite.cases()}.values())
    prov = {**provenance(), "suite": suite.to_dict(), **(provenance_extra or {})}
    unavailable = suite.unavailable()
    if unavailable:
        prov["unavailable_integrators"] = unavailable
        for name, reason in unavailable.items():
            print(f"nsbench: warning: integrator {name!r} left out: {reason}", file=stream or sys.stderr)
    done = storage.done_ids(out)
    pending = [c for c in cases if c.case_id not in done]
    pending.sort(key=lambda c: -c.level)  # tight (slow) levels first: better load balance
    workers = max(1, int(workers or os.cpu_count() or 1))
    refs = _references(suite, pending, out, workers)
    cands = candidates(suite.reference)
    bar = Progress(len(pending), stream=stream, enabled=progress)

    def ref_of(case: Case) -> Reference:
        return refs[reference_key(case.problem, cands, suite.t_span[0], suite.t_span[1], suite.dense_points)]

    def done_case(task: tuple, row: dict[str, Any]) -> None:
        storage.append_row(out, row, prov)
        bar.update(task[0].label)

    def crashed(task: tuple) -> None:
        row = base_row(task[0], suite.name)
        row.update(status="crashed", message="the worker process died while running this case")
        done_case(task, row)

    tasks = [(case, ref_of(case), suite.name) for case in pending]
    try:
        _map(run_case, tasks, min(workers, max(1, len(tasks))), done_case, crashed)
    finally:
        bar.close()
    results = storage.export(out, prov) if (out / "cases").exists() else storage.to_frame([])
    return RunSummary(out=out, n_cases=len(cases), n_resumed=len(cases) - len(pending),
                      n_computed=len(pending), results=results)

