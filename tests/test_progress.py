"""Progress: a bar on a terminal, a line per tenth of the work in a log, silent with enabled=False."""

from __future__ import annotations

import io

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
