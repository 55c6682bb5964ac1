"""Progress of long runs (suites, sweeps), over tqdm.

One bar per run, on stderr, drawn on a terminal. Where no bar can be drawn (CI
logs, pipes, files) it prints one line per tenth of the work instead, with the
time elapsed and the time left; :meth:`Progress.phase` says in one line what the
run does next (above the bar, or as a line of the log); ``enabled=False``
silences it everywhere (the CLI's ``--no-progress``). The estimate of the time left is the work left over
the rate at which work got done so far. Steps may carry weights (the
expected seconds of each task, :mod:`nsbench.bench.estimate`): then a long
task counts for more than a short one, and the estimate holds when they mix.
"""

from __future__ import annotations

import sys
import time
from typing import TextIO

#: Shown instead of tqdm's counts when the steps are weighted (their sum is no count anyone wants).
_WEIGHTED_FORMAT = "{desc}: {percentage:3.0f}%|{bar}| [{elapsed}<{remaining}]{postfix}"


def clock(seconds: float) -> str:
    """``m:ss`` or ``h:mm:ss``."""
    s = int(round(max(0.0, seconds)))
    h, rest = divmod(s, 3600)
    return f"{h}:{rest // 60:02d}:{rest % 60:02d}" if h else f"{rest // 60}:{rest % 60:02d}"


class Progress:
    """Counts finished work out of ``total``; shows the elapsed time and the time left.

    Parameters
    ----------
    total
        Work in all: a number of steps, or of weighted steps (a bar of 0 draws nothing).
    label
        What the bar counts (``'steps'``, the swept parameter's name).
    stream
        Where to draw (default stderr).
    enabled
        ``False``: never draw, never print.
    weighted
        The steps carry weights: show a percentage, not counts.
    """

    def __init__(
        self, total: float, label: str = "", stream: TextIO | None = None, enabled: bool = True, weighted: bool = False
    ) -> None:
        from tqdm import tqdm

        out = stream if stream is not None else sys.stderr
        tty = bool(getattr(out, "isatty", lambda: False)())
        self.total = max(float(total), 0.0) if weighted else max(int(total), 0)
        self.done = 0.0 if weighted else 0
        self.label = label
        self.enabled = enabled
        self._out = out
        self._start = time.monotonic()
        self._lines = enabled and not tty and self.total > 0
        self._next_line = 0.1
        self._bar = tqdm(
            total=self.total,
            desc=label or None,
            file=out,
            unit="step",
            disable=not (enabled and tty and self.total > 0),
            dynamic_ncols=True,
            smoothing=0.05,
            leave=True,
            bar_format=_WEIGHTED_FORMAT if weighted else None,
        )

    def update(self, steps: float = 1, note: str = "") -> None:
        """``steps`` more (weighted) steps finished (``note``: what the last one was, shown beside the bar)."""
        self.done += steps
        if note:
            self._bar.set_postfix_str(note[:40], refresh=False)
        self._bar.update(steps)
        if self._lines and self.done >= self._next_line * self.total:
            fraction = min(1.0, self.done / self.total)
            elapsed = time.monotonic() - self._start
            left = elapsed * (1.0 - fraction) / fraction if fraction > 0 else float("nan")
            what = f"nsbench: {self.label or 'work'} {100 * fraction:.0f}% done in {clock(elapsed)}"
            print(what + (f", about {clock(left)} left" if fraction < 1 else ""), file=self._out, flush=True)
            while self._next_line <= fraction + 1e-12:
                self._next_line += 0.1

    def phase(self, text: str) -> None:
        """Say in one line what the run does now: above the bar on a terminal, a plain line in a log."""
        if not self.enabled:
            return
        line = f"nsbench: {text}"
        if self._bar.disable:
            print(line, file=self._out, flush=True)
        else:
            self._bar.write(line, file=self._out)

    def grow(self, steps: float) -> None:
        """``steps`` more (weighted) steps of work than announced (e.g. a noisy case's extra samples)."""
        if steps > 0 and self.total > 0:
            self.total += steps
            self._bar.total = self.total
            self._bar.refresh()

    def close(self) -> None:
        self._bar.close()

    def __enter__(self) -> "Progress":
        return self

    def __exit__(self, *exc) -> None:
        self.close()
