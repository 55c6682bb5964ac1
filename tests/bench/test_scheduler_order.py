"""The order in which the scheduler hands out first warm-ups and references (``bench/scheduler.py``).

On a fresh install a worker that takes a task needing kernels another worker is compiling only waits
(each function compiles once per machine, behind a lock). So while the first reference runs, an idle
worker warms up a case of another integrator, and two workers do not take the first cases of one
integrator together while another integrator's case is queued. Checked here on the scheduler's own
state: real suite cases, slots with tasks in flight, no worker processes.
"""

from __future__ import annotations

from collections import deque

from nsbench.bench.execute import WarmResult
from nsbench.bench.scheduler import ANY, ReferenceTask, Scheduler, _CaseState, _Slot, compile_key
from nsbench.bench.suite import Suite


PROBLEMS = [{"name": "one-dof", "case": 1}, {"name": "two-dof", "cases": [1, 2]}]


def _scheduler(integrators: list[str], refs: int = 2, problems: list | None = None) -> tuple[Scheduler, list]:
    suite = Suite.from_dict(
        {
            "name": "order",
            "t_span": [0.0, 10.0],
            "reference": ["exact"],
            "problems": PROBLEMS if problems is None else problems,
            "integrators": {"only": integrators},
        }
    )
    cases = suite.cases()
    s = Scheduler.__new__(Scheduler)  # the dispatch state alone: no workers are started
    s.cases = {c.case_id: _CaseState(c) for c in cases}
    s.queue = deque(c.case_id for c in cases)
    s.slots = [_Slot(0), _Slot(1)]
    s._refs_total = s._refs_pending = refs
    return s, cases


def _warm_result() -> WarmResult:
    return WarmResult(setup_time=0.1, warmup_time=0.2)  # a finished warm-up's (no final row)


def _reference() -> ReferenceTask:
    return ReferenceTask("k", {"name": "one-dof", "case": 1}, [{"name": "exact", "options": {}}], 0.0, 10.0, 11)


def test_beside_the_first_reference_a_warm_up_of_another_integrator():
    s, cases = _scheduler(["exact", "henon-rk4"])
    s.slots[0].task = (1, "reference", _reference())
    picked = s._warm_up_beside_first_reference()
    assert picked is not None and picked.case.integrator == "henon-rk4"
    assert picked.case.case_id not in s.queue  # taken off the queue
    # once a reference has finished, exact's kernels are compiled: references go on
    s._refs_pending -= 1
    assert s._warm_up_beside_first_reference() is None


def test_beside_the_first_reference_with_only_the_reference_integrator_left_a_reference():
    s, cases = _scheduler(["exact"])
    s.slots[0].task = (1, "reference", _reference())
    assert s._warm_up_beside_first_reference() is None
    assert len(s.queue) == len(cases)  # nothing taken


def test_two_workers_do_not_start_one_integrator_together_while_another_is_queued():
    s, cases = _scheduler(["henon-rk4", "scipy-dop853"])
    first = s._next_warm_up()
    s.slots[0].task = (1, "warm-up", first)
    second = s._next_warm_up()
    assert {first.case.integrator, second.case.integrator} == {"henon-rk4", "scipy-dop853"}
    # once the first integrator is warm anywhere, its cases go to any worker again, in the queue's order
    first.warm = _warm_result()
    s.slots[1].task = (2, "warm-up", second)
    third = s._next_warm_up()
    assert third.case.integrator == first.case.integrator
    assert third is s.cases[[c.case_id for c in cases if c.integrator == first.case.integrator][1]]


def test_with_only_busy_integrators_queued_the_first_case_is_taken():
    s, cases = _scheduler(["henon-rk4"])
    first = s._next_warm_up()
    s.slots[0].task = (1, "warm-up", first)
    assert s._next_warm_up(only_free=True) is None
    assert s._next_warm_up() is s.cases[cases[1].case_id]


def test_cases_already_done_are_skipped():
    s, cases = _scheduler(["henon-rk4"])
    s.cases[cases[0].case_id].done = True
    assert s._next_warm_up() is s.cases[cases[1].case_id]


def test_ofapi_and_mcpi_share_their_kernels_so_are_not_started_together():
    # one compiled Picard arc function: the second would wait for the first's compilation (18 s measured)
    assert compile_key("ofapi", {"name": "one-dof"}) == compile_key("mcpi", {"name": "one-dof"})
    s, cases = _scheduler(["ofapi", "mcpi", "henon-rk4"])
    first = s._next_warm_up()
    s.slots[0].task = (1, "warm-up", first)
    second = s._next_warm_up()
    assert first.case.integrator in ("ofapi", "mcpi") and second.case.integrator == "henon-rk4"


def test_a_warm_group_is_still_busy_on_a_problem_it_has_not_compiled_for():
    # numba compiles a kernel again for another problem's types: once ofapi is warm on one-dof, ofapi on
    # the relay compiling keeps the group's other relay cases back while another case is queued
    problems = [{"name": "one-dof", "case": 1}, {"name": "relay-feedback"}]
    s, cases = _scheduler(["ofapi", "mcpi", "henon-rk4"], problems=problems)
    picard_on = {
        p["name"]: [
            s.cases[c.case_id] for c in cases if c.integrator in ("ofapi", "mcpi") and c.problem["name"] == p["name"]
        ]
        for p in problems
    }
    picard_on["one-dof"][0].warm = _warm_result()
    s.queue.remove(picard_on["one-dof"][0].case.case_id)
    running = picard_on["relay-feedback"][0]
    s.queue.remove(running.case.case_id)
    s.slots[0].task = (1, "warm-up", running)
    free = []
    while (picked := s._next_warm_up(only_free=True)) is not None:
        free.append(picked)
    held = picard_on["relay-feedback"][1:]
    assert len(free) == len(cases) - 2 - len(held) and not set(map(id, free)) & set(map(id, held))
    assert [s.cases[c] for c in s.queue] == held  # left for when the relay's kernel is compiled
    # a reference on a problem keeps its candidates' cases there back once the first has finished too
    s._refs_pending -= 1
    s.slots[0].task = (1, "reference", _reference())  # one-dof, exact
    assert ("exact", "one-dof") in s._busy_kernels() and ("exact", ANY) not in s._busy_kernels()


def test_a_plug_in_that_does_not_load_is_its_own_group():
    assert compile_key("no-such-integrator", {"name": "one-dof"}) == ("no-such-integrator", "one-dof")
