"""The phases of a suite run across worker processes: no compilation while anyone is timing.

1. **Prepare.** References first, then every case is warmed up once
   (:func:`nsbench.bench.execute.warm_up`: setup, i.e. compilation, and a short
   untimed run) by whichever worker is free; that worker is the case's *home*.
   Then every other worker warms up the cases whose setup is cheap (under
   :data:`STICKY_SETUP` seconds), so that any worker can time them; a case with
   an expensive setup (a long compilation) is *sticky*: only its home times it.
2. **Barrier.** Timing starts when every worker is idle and warm for every case it may time.
3. **Time, in rounds.** A case's ``repeats`` timed samples are taken one per
   round (a noisy case more, up to ``max_repeats``): every case gets its first
   sample before any gets its second, and so on
   (:func:`nsbench.bench.execute.time_case`, joined by
   :func:`~nsbench.bench.execute.merge_runs`). On a shared or virtual machine
   whose speed drifts over seconds to minutes, consecutive runs all see the
   same state, so their spread says nothing and the median can be off by the
   drift; runs spread over the timing phase sample it, and the spread shows it.
   Within a round each free worker times the longest remaining case it is warm
   for, one case per worker at a time; cases whose warm-up predicts a run near
   the time limit come last, so that the worker their limit ends has few cases
   left to warm up again. The row is stored after every round (the first round
   stores it with the metrics), so an interruption keeps every finished run.

A worker that dies (a crash) or is ended (its run passed the time limit) takes
its case with it: the case becomes a ``crashed`` or ``time limit`` row with the
exit code or signal, and a fresh process replaces the worker. In the timing
phase dispatch is held until no case is being timed; the replacement then
starts and warms up before timing resumes. Every task is recorded in a
timeline (:class:`TaskRecord`), which the tests use to check the phases.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import os
import time
from collections import deque
from dataclasses import dataclass, field
from typing import Any, Callable

from nsbench.bench import tasks
from nsbench.workers import protocol as msg
from nsbench.bench.execute import WARMUP_FRACTION, WarmResult, base_row, complete_row, merge_runs
from nsbench.bench.timing import needs_more
from nsbench.workers.pool import WorkerProcess, readable
from nsbench.bench.reference import Reference
from nsbench.bench.suite import Case
from nsbench.errors import ConfigError
from nsbench.status import ReferenceStatus, Status

#: Seconds of setup (and more than its timing) above which a case is timed only where it
#: was compiled (its home). The first case of a kind in a process pays the loading of
#: shared compiled code too, so a setup under a second is not worth keeping in one place.
STICKY_SETUP = 1.0
#: A case whose warm-up predicts a run longer than this share of the time limit is timed
#: last: the prediction (a tenth of the span, scaled up) is off by up to a few times.
RISKY_SHARE = 0.5
#: Consecutive failed starts of a worker after which the run gives up.
MAX_FAILED_STARTS = 3
#: The problem part of a :func:`compile_key` that stands for every problem.
ANY = "*"


@functools.lru_cache(maxsize=None)
def _kernel_group(integrator: str) -> str:
    from nsbench.integrators import integrator_class

    try:
        return integrator_class(integrator).kernel_group or integrator
    except Exception:  # a plug-in that does not load: its own group (its case's row says why)
        return integrator


def compile_key(integrator: str, problem: dict[str, Any]) -> tuple[str, str]:
    """What a case's first warm-up compiles, as far as the scheduler can tell before it runs: the
    integrator's kernel group (:attr:`nsbench.integrators.base.Integrator.kernel_group`, else its name)
    and the problem's registry name (numba compiles a kernel again for another problem's types)."""
    return _kernel_group(integrator), str(problem.get("name", ""))


@dataclass
class ReferenceTask:
    """A reference to compute: its cache key and the arguments of ``compute_reference``."""

    key: str
    problem: dict[str, Any]
    candidates: list[dict[str, Any]]
    t0: float
    t_end: float
    dense_points: int


@dataclass
class TaskRecord:
    """One task in the timeline: which worker slot, what, when (monotonic seconds), how it ended."""

    slot: int
    pid: int
    kind: str  # 'start', 'reference', 'warm-up', 'time'
    label: str
    start: float
    end: float = math.nan
    outcome: str = ""


@dataclass
class _CaseState:
    case: Case
    warm: WarmResult | None = None
    home: int | None = None
    estimate: float = 0.0  # expected seconds of its timed runs
    done: bool = False
    rounds: int = 0  # timing rounds finished
    row: dict[str, Any] | None = None  # its row so far (from the first timing round on)

    @property
    def loops(self) -> int | None:
        """Runs per sample, set by the calibration run of the first round (``None`` before it)."""
        if self.row is None or self.row.get("loops") is None:
            return None
        return int(self.row["loops"])

    @property
    def risky(self) -> bool:
        """Its warm-up predicts a run near or past the time limit (its worker may be ended)."""
        return self.estimate / self.case.repeats > RISKY_SHARE * self.case.time_limit

    @property
    def order(self) -> tuple[bool, float]:
        """Timing order (largest first): likely to finish, then longest."""
        return (not self.risky, self.estimate)

    @property
    def sticky(self) -> bool:
        """Its setup (a compilation) costs more than :data:`STICKY_SETUP` and than its timing:
        warming it up elsewhere would cost more than the balance gains."""
        return self.warm is not None and self.warm.setup_time >= max(STICKY_SETUP, self.estimate)


@dataclass
class _Slot:
    index: int
    worker: WorkerProcess | None = None
    ready: bool = False
    warm: set[str] = field(default_factory=set)
    task: tuple[int, str, Any] | None = None  # (task id, kind, payload)
    record: TaskRecord | None = None
    stage: str = ""
    limit: float | None = None
    deadline: float = math.inf
    held: float | None = None  # seconds the stage had left when a compilation began (msg.held)
    failed_starts: int = 0

    @property
    def alive(self) -> bool:
        return self.worker is not None

    @property
    def idle(self) -> bool:
        return self.alive and self.ready and self.task is None


class Scheduler:
    """Runs the references and cases of a suite on ``workers`` worker processes.

    Parameters
    ----------
    cases
        Cases to run (none of them stored yet, or stored short of their rounds: ``resumed``).
    references
        References to compute first.
    reference_of
        The reference of a case (called once references are computed).
    on_extra
        Called with a case that gets a timing round beyond its planned ``repeats``
        (its samples spread widely), before the row of the round that decided it.
    on_reference, on_row
        Called in this process with each computed reference and each row, as
        it grows round by round (``on_row(row, stored=..., steps=...)``: a worker
        stores the first round's row itself; ``steps`` is the progress this row
        accounts for, one per warm-up or timing round, the rounds a case will
        not need counted at its last call).
    hello
        The first message of every worker (:func:`nsbench.workers.pool.hello`).
    suite
        Suite name stored in the rows.
    resumed
        Stored rows (by case id) of cases an interrupted run timed in fewer rounds than planned: such a
        case starts from its row (its samples, metrics and runs per sample) and is timed only in the
        rounds it lacks, after its warm-up.
    probe
        Case ids whose first warm-up also probes the case's cost (:func:`nsbench.bench.execute.probe_run`):
        the cases the plan has no measured cost for.
    on_timing
        Called once as the timing starts (every warm-up and probe done), with the first warm-up of every
        case still to time (case id -> :class:`~nsbench.bench.execute.WarmResult`).
    """

    def __init__(
        self,
        cases: list[Case],
        references: list[ReferenceTask],
        reference_of: Callable[[Case], Reference],
        on_reference: Callable[[str, Reference], None],
        on_row: Callable[..., None],
        hello: msg.Hello,
        workers: int,
        suite: str = "suite",
        on_warm: Callable[[Case], None] | None = None,
        on_phase: Callable[[str], None] | None = None,
        on_extra: Callable[[Case], None] | None = None,
        resumed: dict[str, dict[str, Any]] | None = None,
        probe: set[str] | frozenset[str] = frozenset(),
        on_timing: Callable[[dict[str, WarmResult]], None] | None = None,
    ) -> None:
        self.cases = {c.case_id: _CaseState(c) for c in cases}
        self.probe = set(probe)
        self.on_timing = on_timing or (lambda warm: None)
        for case_id, row in (resumed or {}).items():
            if case_id in self.cases:  # one sample per round: its rounds are its samples
                self.cases[case_id].row, self.cases[case_id].rounds = dict(row), int(row["n_repeats"])
        self.ref_queue = deque(references)
        self.queue = deque(c.case_id for c in cases)  # first warm-ups, in the runner's order
        self.reference_of, self.on_reference, self.on_row = reference_of, on_reference, on_row
        self.on_warm = on_warm or (lambda case: None)
        self.on_phase = on_phase or (lambda text: None)
        self.on_extra = on_extra or (lambda case: None)
        self.hello, self.suite = hello, suite
        from nsbench.workers.jobs import WORKER_LOG, WorkerLog

        #: the tracebacks of tasks that raised, in the output folder (a worker prints nothing itself)
        self.log = WorkerLog(os.path.join(hello.out, WORKER_LOG), f"suite {suite}")
        self.slots = [_Slot(i) for i in range(max(1, workers))]
        self.timing = False  # the phase: False while preparing
        self.timeline: list[TaskRecord] = []
        #: the 1-minute load average each time a sample was sent (the report's line on the machine's noise)
        self.loads: list[float] = []
        self._refs_pending = self._refs_total = len(references)
        self._next_task = 0
        #: rows of timing rounds that came back, stored once the idle workers have their next task
        #: (:meth:`_flush`): writing a row takes the parent 20-30 ms, which the workers would otherwise wait
        #: out between every two samples (measured: 35 ms a task, 20 s of the default run's 55 s of cases)
        self._unsaved: list[tuple[dict[str, Any], bool, int]] = []

    # ------------------------------------------------------------------ the loop
    def run(self) -> None:
        """Run everything; on any exception (Ctrl-C included) keep what finished, end the workers."""
        n_refs = len(self.ref_queue)
        self.on_phase(
            f"preparing: {n_refs} reference run(s), then a warm-up of each of {len(self.cases)} case(s) "
            "(set-up and compilation, a short untimed run)"
            if n_refs
            else f"preparing: a warm-up of each of {len(self.cases)} case(s) (set-up and compilation, a short "
            "untimed run)"
        )
        try:
            while not self._finished():
                self._dispatch()
                self._flush()
                self._check_progress()
                self._wait()
            self._flush()
        except BaseException:
            try:
                self._drain()
                self._flush()  # every round that came back is stored before the interruption goes on
            finally:
                self._end_all()  # the workers end even when storing a row fails
            raise
        finally:
            self.log.report()
        for slot in self.slots:  # every worker asked first, so that they end together
            if slot.worker is not None:
                slot.worker.ask_to_stop()
        for slot in self.slots:
            if slot.worker is not None:
                slot.worker.stop()
                slot.worker = None

    def _finished(self) -> bool:
        return self._refs_pending == 0 and all(s.done for s in self.cases.values())

    def _dispatch(self) -> None:
        if not self.timing and self._prepared():
            self.timing = True
            runs = sum(s.case.repeats - s.rounds for s in self.cases.values() if not s.done)
            rounds = max((s.case.repeats - s.rounds for s in self.cases.values() if not s.done), default=0)
            self.on_phase(f"timing: every worker is warm; {runs} timed sample(s) in {rounds} round(s)")
            self.on_timing({i: s.warm for i, s in self.cases.items() if not s.done and s.warm is not None})
        for slot in self.slots:
            if self._finished():
                return
            if not slot.alive and (not self.timing or self._quiet()):
                self._start(slot)  # a process start is first-use work too: never while timing
            elif slot.idle:
                self._give_work(slot)

    def _give_work(self, slot: _Slot) -> None:
        if not self.timing:
            if self.ref_queue:
                early = self._warm_up_beside_first_reference()
                if early is not None:
                    return self._send_warm(slot, early)
                ref = self.ref_queue.popleft()
                return self._send(
                    slot,
                    "reference",
                    ref,
                    tasks.ComputeReference(0, ref.problem, ref.candidates, ref.t0, ref.t_end, ref.dense_points),
                    ref.key,
                )
            state = self._next_warm_up()
            if state is not None:
                return self._send_warm(slot, state)
            self.queue.clear()  # only cases that are done were left
        elif self._holding():
            if not self._quiet():
                return  # hold: nothing compiles or warms up while a case is timed
        else:
            pending = [s for s in self.cases.values() if not s.done]
            # rounds started by the case furthest behind: no case starts round k + 1 before every case has
            # started round k (a slow round in flight would otherwise let the others run two rounds ahead)
            floor = min((s.rounds + self._in_flight(s.case.case_id) for s in pending), default=0)
            free = [
                s
                for s in pending
                if s.case.case_id in slot.warm and not self._in_flight(s.case.case_id) and s.rounds <= floor
            ]
            if free:
                # earliest round first (runs interleaved in time), then longest first: the best balance
                state = max(free, key=lambda s: (-s.rounds, s.order))
                message = tasks.TimeCase(
                    0,
                    state.case,
                    self.suite,
                    self.reference_of(state.case),
                    state.warm,
                    round=state.rounds,
                    loops=state.loops,
                )
                self._sample_load()
                return self._send(slot, "time", state, message, state.case.label)
            return
        need = self._needs(slot)
        if need:
            self._send_warm(slot, max(need, key=lambda s: s.estimate))

    def _warm_up_beside_first_reference(self) -> _CaseState | None:
        """A case to warm up now rather than a reference, or ``None``.

        While the first reference runs and none has finished, its worker compiles the reference
        integrator's kernels (on a fresh install, a minute or more), which every other reference needs:
        a second worker given a reference would only wait for that compilation (each function compiles
        once per machine, :func:`nsbench.model.compile.compiled_once`). It warms up a case of another
        integrator instead (:meth:`_next_warm_up`). Warm-ups need no reference, and the timing still
        starts only after every reference and warm-up (the barrier).
        """
        running = any(s.task is not None and s.task[1] == "reference" for s in self.slots)
        if running and self._no_reference_finished:
            return self._next_warm_up(only_free=True)
        return None

    @property
    def _no_reference_finished(self) -> bool:
        return self._refs_total == self._refs_pending  # pending: queued or running

    def _busy_kernels(self) -> set[tuple[str, str]]:
        """What another worker may be compiling, as :func:`compile_key` pairs (``(group, ANY)``: every
        problem of the group): the candidates of a running reference (every problem while no reference
        has finished, its own problem after), and the running warm-ups' (every problem while their group
        has no warm case, their own problem while it has none on that problem; a finished warm-up has
        compiled its kernels for that problem on this machine)."""
        warm = {compile_key(s.case.integrator, s.case.problem) for s in self.cases.values() if s.warm is not None}
        warm_groups = {group for group, _ in warm}
        busy: set[tuple[str, str]] = set()
        for s in self.slots:
            if s.task is None:
                continue
            if s.task[1] == "reference":
                for c in s.task[2].candidates:
                    group, problem = compile_key(str(c.get("name", "")), s.task[2].problem)
                    busy.add((group, ANY if self._no_reference_finished else problem))
            elif s.task[1] == "warm-up":
                key = compile_key(s.task[2].case.integrator, s.task[2].case.problem)
                if key[0] not in warm_groups:
                    busy.add((key[0], ANY))
                elif key not in warm:
                    busy.add(key)
        return busy

    def _next_warm_up(self, only_free: bool = False) -> _CaseState | None:
        """The next first warm-up: the first queued case whose kernels no other worker may be compiling
        (:meth:`_busy_kernels`), else (unless ``only_free``) the first queued case; taken off the queue.

        The queue keeps the runner's order, in which one integrator's cases follow each other: two
        workers taking them in turn would compile the same kernels, one waiting for the other's lock
        (on a fresh install: both workers on ``henon-rk4`` for 41 s, then on OFAPI's and MCPI's
        Picard kernels for 25 s). Taking another integrator's case compiles its kernels meanwhile. Two
        integrators of one kernel group (``ofapi`` and ``mcpi``) count as one, and a kernel compiles again
        for each kind of problem (a run on 2 idle cores had both on the relay's Picard kernel for 7 s and
        on Henon-Heiles's for 7 s, after the first problem's 18 s).
        """
        busy = self._busy_kernels()
        first = None
        for case_id in self.queue:
            state = self.cases[case_id]
            if state.done:
                continue
            group, problem = compile_key(state.case.integrator, state.case.problem)
            if (group, ANY) not in busy and (group, problem) not in busy:
                self.queue.remove(case_id)
                return state
            if first is None:
                first = state
        if only_free or first is None:
            return None
        self.queue.remove(first.case.case_id)
        return first

    def _sample_load(self) -> None:
        try:
            self.loads.append(float(os.getloadavg()[0]))
        except (AttributeError, OSError):  # pragma: no cover - platforms without a load average
            pass

    def _check_progress(self) -> None:
        """Fail loudly rather than wait forever if a rule above leaves work unassigned."""
        if all(s.alive and s.ready and s.task is None for s in self.slots) and not self._finished():
            raise RuntimeError("nsbench scheduler: work remains but no worker was given any (a bug)")

    # ------------------------------------------------------------------ phase rules
    def _needs(self, slot: _Slot) -> list[_CaseState]:
        """Cases ``slot`` must still warm up: warm elsewhere, not done, not sticky to another home."""
        if self.queue and not self.timing:
            return []  # first every case gets a home
        return [
            s
            for s in self.cases.values()
            if not s.done
            and s.warm is not None
            and s.case.case_id not in slot.warm
            and (not s.sticky or s.home == slot.index)
            and not self._in_flight(s.case.case_id, slot)
        ]

    def _prepared(self) -> bool:
        """The barrier: references and first warm-ups done, every worker idle and warm."""
        return self._refs_pending == 0 and not self.queue and all(s.idle and not self._needs(s) for s in self.slots)

    def _holding(self) -> bool:
        """Timing must pause: a worker is dead, starting, warming up, or not warm for its cases."""
        return any(
            not s.alive or not s.ready or (s.task is not None and s.task[1] != "time") or self._needs(s)
            for s in self.slots
        )

    def _quiet(self) -> bool:
        return not any(s.task is not None and s.task[1] == "time" for s in self.slots)

    def _in_flight(self, case_id: str, on: _Slot | None = None) -> bool:
        """Whether ``case_id`` is being warmed up or timed (on ``on`` only, if given)."""
        return any(
            s.task is not None and s.task[1] in ("warm-up", "time") and s.task[2].case.case_id == case_id
            for s in self.slots
            if on is None or s is on
        )

    # ------------------------------------------------------------------ sending
    def _start(self, slot: _Slot) -> None:
        slot.worker = WorkerProcess(self.hello)
        slot.ready, slot.warm, slot.task = False, set(), None
        slot.record = self._record(slot, "start", "worker start")

    def _send_warm(self, slot: _Slot, state: _CaseState) -> None:
        probe = state.warm is None and state.case.case_id in self.probe  # its first warm-up only
        self._send(slot, "warm-up", state, tasks.WarmUp(0, state.case, self.suite, probe), state.case.label)

    def _send(self, slot: _Slot, kind: str, payload: Any, message: Any, label: str) -> None:
        self._next_task += 1
        task = self._next_task
        message = dataclasses.replace(message, task=task)
        slot.task, slot.stage, slot.limit, slot.deadline, slot.held = (task, kind, payload), "", None, math.inf, None
        slot.record = self._record(slot, kind, label)
        try:
            slot.worker.send(message)
        except (BrokenPipeError, OSError):
            self._lost(slot)

    def _record(self, slot: _Slot, kind: str, label: str) -> TaskRecord:
        rec = TaskRecord(slot.index, slot.worker.pid if slot.worker else -1, kind, label, time.monotonic())
        self.timeline.append(rec)
        return rec

    def _close_record(self, slot: _Slot, outcome: str) -> None:
        if slot.record is not None:
            slot.record.end, slot.record.outcome = time.monotonic(), outcome
            slot.record = None

    # ------------------------------------------------------------------ receiving
    def _wait(self) -> None:
        live = [s for s in self.slots if s.worker is not None]
        if not live:
            return
        deadline = min(s.deadline for s in live)
        timeout = None if deadline == math.inf else max(0.0, deadline - time.monotonic())
        by_worker = {id(s.worker): s for s in live}
        for worker in readable([s.worker for s in live], timeout):
            self._receive(by_worker[id(worker)])
        now = time.monotonic()
        for slot in live:
            if slot.worker is not None and slot.task is not None and now > slot.deadline:
                self._time_out(slot)

    def _receive(self, slot: _Slot) -> None:
        try:
            message = slot.worker.receive()
        except (EOFError, OSError):
            return self._lost(slot)
        if isinstance(message, msg.Ready):
            slot.ready, slot.failed_starts = True, 0
            self._close_record(slot, "ready")
        elif isinstance(message, msg.InitFailed):
            raise ConfigError(
                "a worker process cannot load the components registered in this process: "
                f"{message.error}; register components defined in an importable module"
            )
        elif isinstance(message, msg.Stage):
            slot.stage, slot.limit, slot.held = message.what, message.limit, None
            slot.deadline = math.inf if message.limit is None else time.monotonic() + message.limit
        elif isinstance(message, msg.Compiling):  # nsbench's first-use cost: not the case's time
            deadline, slot.held = msg.held(slot.deadline, slot.held, message, time.monotonic())
            slot.deadline = math.inf if deadline is None else deadline
        elif isinstance(message, msg.Interrupted):
            raise KeyboardInterrupt
        elif isinstance(message, (msg.Done, msg.Failed)):
            self._finish(slot, message)

    def _finish(self, slot: _Slot, message: msg.Done | msg.Failed) -> None:
        _, kind, payload = slot.task
        slot.task, slot.deadline = None, math.inf
        failed = isinstance(message, msg.Failed)
        self._close_record(slot, "failed" if failed else "done")
        if isinstance(message, msg.Failed):
            self.log.add(f"{kind} task", message.error, message.detail)
        if kind == "reference":
            self._refs_pending -= 1
            ref = _failed_reference(payload, f"its run raised {message.error}") if failed else message.result
            self.on_reference(payload.key, ref)
        elif failed:
            self._final(payload, "error", message.error)
        elif kind == "warm-up":
            self._warmed(slot, payload, message.result)
        else:
            self._timed(payload, message.result)

    def _timed(self, state: _CaseState, result: dict[str, Any]) -> None:
        """A timing round of ``state`` came back: join it to the row, store, finish after the last.

        After its planned ``repeats`` rounds a case whose samples spread widely
        gets more, one per round, up to ``max_repeats``
        (:func:`nsbench.bench.timing.needs_more`); ``on_extra`` is told of each.
        """
        first = state.row is None
        before = state.row
        state.row = result if first else merge_runs(state.row, result)
        state.rounds += 1
        broken = not first and state.row["n_repeats"] == before["n_repeats"]  # the round added no run
        case = state.case
        planned = state.rounds >= case.repeats
        more = planned and not broken and needs_more(state.row, case.max_repeats or case.repeats)
        state.done = state.row["status"] != Status.SUCCESS or broken or (planned and not more)
        if more:
            self.on_extra(case)
        steps = 1 + (max(0, case.repeats - state.rounds) if state.done else 0)
        self._unsaved.append((state.row, first, steps))

    def _flush(self) -> None:
        """Store the rows of the timing rounds that came back (see ``_unsaved``)."""
        while self._unsaved:
            row, first, steps = self._unsaved.pop(0)
            self.on_row(row, stored=first, steps=steps)

    def _warmed(self, slot: _Slot, state: _CaseState, warm: WarmResult) -> None:
        if state.done:  # its row is written already (a late copy of a warm-up)
            return
        if state.warm is None:
            self.on_warm(state.case)
        if warm.row is not None:  # unsupported or error: the row is final
            state.done = True
            self.on_row(warm.row, steps=state.case.repeats)
            return
        slot.warm.add(state.case.case_id)
        if state.warm is None:
            state.warm, state.home = warm, slot.index
            # a probe's warm run, where there is one, over the warm-up's (which may hold first-use costs)
            run = warm.probe_wall / warm.probe_span if warm.probe_span > 0 else warm.warmup_time / WARMUP_FRACTION
            state.estimate = state.case.repeats * run

    # ------------------------------------------------------------------ losses
    def _time_out(self, slot: _Slot) -> None:
        limit, stage = slot.limit, slot.stage
        slot.worker.kill()
        self._lose(
            slot,
            "time limit",
            f"wall-clock limit of {limit:g} s per run reached in the {stage}; the worker process was stopped",
        )

    def _lost(self, slot: _Slot) -> None:
        reason = slot.worker.exit_reason()
        slot.worker.kill()
        what = f" during the {slot.stage}" if slot.stage else ""
        self._lose(slot, "crashed", f"the worker process died ({reason}){what}")

    def _lose(self, slot: _Slot, status: str, message: str) -> None:
        """The worker of ``slot`` is gone: its task becomes a row, the slot waits for a fresh worker."""
        task, was_ready = slot.task, slot.ready
        self._close_record(slot, status)
        slot.worker, slot.ready, slot.warm, slot.task, slot.deadline = None, False, set(), None, math.inf
        if not was_ready:
            slot.failed_starts += 1
            if slot.failed_starts >= MAX_FAILED_STARTS:
                raise RuntimeError(f"worker processes die as they start ({message}); see the errors above")
        if task is None:
            return
        _, kind, payload = task
        if kind == "reference":
            self._refs_pending -= 1
            self.on_reference(payload.key, _failed_reference(payload, f"{status}: {message}"))
        else:
            self._final(payload, status, message)

    def _final(self, state: _CaseState, status: str, message: str) -> None:
        if state.done:  # never overwrite a finished row
            return
        if state.row is not None:  # a later timing round was lost: the earlier rounds stand
            state.done = True
            self.on_row(
                merge_runs(state.row, {"status": status, "message": message}),
                stored=False,
                steps=max(0, state.case.repeats - state.rounds),
            )
            return
        if state.warm is None:  # its first warm-up ended here
            self.on_warm(state.case)
        row = base_row(state.case, self.suite)
        row.update(status=status, message=message)
        if state.warm is not None:
            complete_row(row, state.warm)
        state.done = True
        self.on_row(row, steps=state.case.repeats)

    # ------------------------------------------------------------------ interruption
    def _drain(self) -> None:
        """Keep every row already sent back (an interrupt must not lose a finished case)."""
        for slot in self.slots:
            while slot.worker is not None and slot.task is not None:
                try:
                    if not readable([slot.worker], 0):
                        break
                    message = slot.worker.receive()
                except Exception:  # a dead worker, or a message cut by the interrupt
                    break
                if isinstance(message, msg.Done) and slot.task[1] == "time":
                    _, _, state = slot.task
                    slot.task = None
                    self._timed(state, message.result)

    def _end_all(self) -> None:
        for slot in self.slots:
            if slot.worker is not None:
                slot.worker.kill()
                self._close_record(slot, "interrupted")
                slot.worker = None


def _failed_reference(task: ReferenceTask, reason: str) -> Reference:
    """A reference that could not be computed (not cached: the next run tries again)."""
    import numpy as np
    import pandas as pd

    grid = np.linspace(task.t0, task.t_end, task.dense_points)
    return Reference(
        task.key,
        None,
        None,
        ReferenceStatus.failed(reason),
        pd.DataFrame(columns=["t", "kind", "block"]),
        grid,
        np.empty((0, 0)),
        np.empty(0),
        failed=True,
    )
