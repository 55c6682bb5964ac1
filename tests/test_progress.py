"""Progress: a bar on a terminal, a line per tenth of the work in a log, silent with enabled=False."""

from __future__ import annotations

import io
import math

import pytest

from nsbench.progress import Progress, clock


class Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_drawn_on_a_terminal_with_count_and_note():
    out = Terminal()
    with Progress(4, label="steps", stream=out) as bar:
        bar.update(1, "one-dof/1 exact")
        bar.update(3)
    text = out.getvalue()
    assert "steps" in text and "4/4" in text and "one-dof/1 exact" in text
    assert bar.done == 4


def test_weighted_steps_show_a_percentage_not_counts():
    out = Terminal()
    with Progress(10.0, label="cases", stream=out, weighted=True) as bar:
        bar.update(2.5, "slow case")
        bar.update(7.5)
    text = out.getvalue()
    assert "100%" in text and "10.0/10.0" not in text and "slow case" in text


def test_a_line_per_tenth_in_a_log_and_silent_when_disabled():
    log = io.StringIO()
    with Progress(20, label="v0", stream=log) as bar:
        for _ in range(20):
            bar.update(1)
    lines = log.getvalue().splitlines()
    assert len(lines) == 10 and lines[0].startswith("nsbench: v0 10% done in 0:00, about")
    assert lines[-1] == "nsbench: v0 100% done in 0:00"
    # one big step crosses several tenths at once: one line
    log = io.StringIO()
    with Progress(10.0, label="cases", stream=log, weighted=True) as bar:
        bar.update(7.0)
        bar.update(3.0)
    assert [line.split(" done")[0] for line in log.getvalue().splitlines()] == [
        "nsbench: cases 70%",
        "nsbench: cases 100%",
    ]
    off = Terminal()
    with Progress(3, label="v0", stream=off, enabled=False) as bar:
        bar.update(3)
    assert off.getvalue() == "" and bar.done == 3


def test_a_phase_is_one_line_in_a_log_above_the_bar_on_a_terminal_and_silent_when_disabled():
    log = io.StringIO()
    with Progress(4, label="cases", stream=log) as bar:
        bar.phase("timing: every worker is warm")
        bar.update(4)
    lines = log.getvalue().splitlines()
    assert lines[0] == "nsbench: timing: every worker is warm" and lines[-1].startswith("nsbench: cases 100%")
    term = Terminal()
    with Progress(4, label="cases", stream=term) as bar:
        bar.update(1)
        bar.phase("timing: every worker is warm")
        bar.update(3)
    assert "nsbench: timing: every worker is warm\n" in term.getvalue() and "4/4" in term.getvalue()
    off = Terminal()
    with Progress(4, stream=off, enabled=False) as bar:
        bar.phase("timing")
    assert off.getvalue() == ""


def test_clock():
    assert clock(0) == "0:00" and clock(61.4) == "1:01" and clock(3725) == "1:02:05"


class FakeClock:
    """Seconds that pass only when a test says so."""

    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


def _prepared(compile_seconds: float) -> tuple[Progress, FakeClock, io.StringIO]:
    """A bar of 10 weighted steps whose first 2 (a warm-up that compiles) took ``compile_seconds``."""
    log, now = io.StringIO(), FakeClock()
    bar = Progress(10.0, label="cases", stream=log, weighted=True, clock=now)
    bar.hold("preparing", 1)
    now.now = compile_seconds
    bar.update(2.0, "a warm-up", tick=True)
    return bar, now, log


def test_no_time_left_while_held_and_the_compile_phase_never_sets_the_rate():
    bar, now, log = _prepared(compile_seconds=300.0)
    assert log.getvalue() == "nsbench: cases 20% done in 5:00 (preparing: 1 of 1)\n" and math.isnan(bar.left())
    bar.begin(seconds_per_step=0.5)  # the plan: 0.5 s of the run per weighted step
    assert bar.left() == pytest.approx(8 * 0.5)  # the plan's, not 300 s per 2 steps
    now.now += 1.0
    bar.update(2.0)  # the counted work: 2 steps in 1 s, from the plan's rate towards the measured one
    share = 2 / 8
    assert bar.left() == pytest.approx(6 * ((1 - share) * 0.5 + share * 0.5))
    now.now += 3.0
    bar.update(2.0)  # slower than planned: 4 steps in 4 s
    assert bar.left() == pytest.approx(4 * ((1 - 0.5) * 0.5 + 0.5 * 1.0))
    assert log.getvalue().splitlines()[-1] == "nsbench: cases 60% done in 5:04, about 0:03 left"
    # the same work after a compilation of 1 s: the same time left
    quick, clock2, _ = _prepared(compile_seconds=1.0)
    quick.begin(seconds_per_step=0.5)
    clock2.now += 1.0
    quick.update(2.0)
    clock2.now += 3.0
    quick.update(2.0)
    assert quick.left() == pytest.approx(bar.left())


def test_without_a_plan_the_counted_rate_is_the_measured_one_and_reweigh_sets_the_work_left():
    bar, now, _ = _prepared(compile_seconds=100.0)
    bar.begin()
    assert math.isnan(bar.left())  # nothing counted yet, no plan: no time left rather than a wrong one
    now.now += 2.0
    bar.update(1.0)
    assert bar.left() == pytest.approx(7 * 2.0)
    bar.reweigh(21.0)  # the probes say the work left is three times the planned
    assert bar.total == pytest.approx(3.0 + 21.0) and bar.left() == pytest.approx(21 * 2.0)


def test_a_held_bar_on_a_terminal_shows_the_phase_and_its_count_then_the_time_left():
    out, now = Terminal(), FakeClock()
    bar = Progress(10.0, label="cases", stream=out, weighted=True, clock=now)
    bar.hold("preparing", 3)
    bar.update(1.0, "one-dof/1 exact", tick=True)
    bar._bar.refresh()
    assert "preparing 1/3, one-dof/1 exact" in out.getvalue() and "left" not in out.getvalue()
    bar.begin(seconds_per_step=1.0)
    now.now += 1.0  # as planned: 1 s a step
    bar.update(1.0, "one-dof/1 exact")
    bar._bar.refresh()
    assert "0:08 left, one-dof/1 exact" in out.getvalue()
    bar.say("nsbench: revised: about 10 s in all")
    bar.close()
    assert "nsbench: revised: about 10 s in all\n" in out.getvalue()
    off = Terminal()
    with Progress(3, stream=off, enabled=False) as quiet:
        quiet.say("nsbench: the plan")  # said though the bar is off: the caller decides
    assert off.getvalue() == "nsbench: the plan\n"
