"""A worker answers any task message that brings its own ``perform``: the floor knows no app."""

from __future__ import annotations

import io
import pickle
from dataclasses import dataclass

from nsbench.workers import protocol as msg
from nsbench.workers.worker import serve_tasks


@dataclass(frozen=True)
class Square:
    """An app's task: announces a stage, sends a part, returns ``value ** 2``."""

    task: int
    value: float

    def perform(self, context: msg.Context) -> float:
        context.stage("squaring", 5.0)
        context.emit(("half", self.value / 2))
        return self.value**2


@dataclass(frozen=True)
class NoPerform:
    task: int


def _answers(*tasks) -> list:
    inp = io.BytesIO()
    for task in (*tasks, msg.Stop()):
        msg.write_message(inp, task)
    inp.seek(0)
    out = io.BytesIO()
    serve_tasks(inp, out, msg.Hello([], pickle.dumps({}), "", {}))
    out.seek(0)
    found = []
    while True:
        try:
            found.append(msg.read_message(out))
        except EOFError:
            return found


def test_a_task_with_perform_gets_its_stages_parts_and_result_back_in_order():
    assert _answers(Square(7, 3.0)) == [
        msg.Stage(7, "squaring", 5.0),
        msg.Partial(7, ("half", 1.5)),
        msg.Done(7, 9.0),
    ]


def test_a_message_that_is_no_task_fails_with_its_reason_and_the_worker_serves_on():
    answers = _answers(NoPerform(1), Square(2, 2.0))
    failed, done = answers[0], answers[-1]
    assert isinstance(failed, msg.Failed) and failed.task == 1
    assert "neither a Call nor a message with perform(context)" in failed.error
    assert done == msg.Done(2, 4.0)
