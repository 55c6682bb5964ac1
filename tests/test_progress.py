"""The progress bar: drawn on a terminal only, silent in logs and with enabled=False."""

from __future__ import annotations

import io

from nsbench.progress import Progress


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


def test_silent_in_a_log_and_when_disabled():
    for stream, enabled in ((io.StringIO(), True), (Terminal(), False)):
        with Progress(3, label="v0", stream=stream, enabled=enabled) as bar:
            bar.update(3)
        assert stream.getvalue() == "" and bar.done == 3
