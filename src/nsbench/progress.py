"""Progress of long runs (suites, sweeps), over tqdm.

One bar per run, on stderr, drawn on a terminal. Where no bar can be drawn (CI
logs, pipes, files) it prints one line per tenth of the work instead, with the
time elapsed and the time left; :meth:`Progress.phase` says in one line what the
run does next (above the bar, or as a line of the log); ``enabled=False``
silences it everywhere (the CLI's ``--no-progress``). The estimate of the time left is the work left over
the rate at which work got done so far, in the phase whose work counts (:meth:`Progress.hold`,
:meth:`Progress.begin`: a suite's warm-ups, mostly compilation, never set the rate of its timed
samples). Steps may carry weights (the expected seconds of each task,
:mod:`nsbench.bench.estimate`): then a long task counts for more than a short one, and the
estimate holds when they mix.
"""

from __future__ import annotations

import math
import sys
import time
from typing import Any, Callable, TextIO

#: Shown instead of tqdm's counts when the steps are weighted (their sum is no count anyone wants); the time
#: left is this module's (in the postfix), not tqdm's, which would extrapolate from every step alike.
_WEIGHTED_FORMAT = "{desc}: {percentage:3.0f}%|{bar}| [{elapsed}{postfix}]"


def clock(seconds: float) -> str:
    """``m:ss`` or ``h:mm:ss``."""
    s = int(round(max(0.0, seconds)))
    h, rest = divmod(s, 3600)
    return f"{h}:{rest // 60:02d}:{rest % 60:02d}" if h else f"{rest // 60}:{rest % 60:02d}"


class Progress:
    """Counts finished work out of ``total``; shows the elapsed time and the time left.

    A run whose first steps are not like the rest (warm-ups that compile, then timed samples) holds the
    time left in its first phase (:meth:`hold`: the bar shows the phase and its count instead) and starts
    counting with :meth:`begin`: the time left is then the work left at the rate of the work done since,
    which starts from a planned rate and moves to the measured one as the work gets done. Without
    :meth:`begin` (a sweep) the work counts from the start.

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
    clock
        Seconds of a monotonic clock (default :func:`time.monotonic`; a test passes its own).
    """

    def __init__(
        self,
        total: float,
        label: str = "",
        stream: TextIO | None = None,
        enabled: bool = True,
        weighted: bool = False,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        from tqdm import tqdm

        out = stream if stream is not None else sys.stderr
        tty = bool(getattr(out, "isatty", lambda: False)())
        self.total = max(float(total), 0.0) if weighted else max(int(total), 0)
        self.done = 0.0 if weighted else 0
        self.label = label
        self.enabled = enabled
        self._out = out
        self._clock = clock
        self._start = clock()
        self._weighted = weighted
        self._held: list[Any] | None = None  # [what, steps counted, of how many] while the time left is held
        self._counted = (self._start, 0.0)  # when the counted work began, and the work done by then
        self._planned: float | None = None  # seconds per step of the counted work, from a plan
        self._note = ""
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

    # ------------------------------------------------------------------ phases
    def hold(self, what: str, count: int) -> None:
        """A phase of ``count`` steps whose time says nothing of the rest (compilation, first use): the bar shows
        ``what`` and how many of its steps are done (:meth:`update` with ``tick``), no time left, until
        :meth:`begin`."""
        self._held = [what, 0, int(count)]
        self._postfix()

    def begin(self, seconds_per_step: float | None = None) -> None:
        """The counted work starts now: the time left is the work left at its rate since now, starting from
        ``seconds_per_step`` (a plan's; ``None``: measured only)."""
        self._held = None
        self._counted = (self._clock(), float(self.done))
        self._planned = seconds_per_step if seconds_per_step and seconds_per_step > 0 else None
        self._postfix()

    def reweigh(self, left: float) -> None:
        """The work left is ``left`` (weighted) steps, re-weighed (e.g. by costs measured since the start)."""
        if self.total > 0:
            self.total = self.done + max(0.0, float(left))
            self._bar.total = self.total
            self._bar.refresh()

    def left(self) -> float:
        """Seconds left (NaN while held or before anything was counted)."""
        if self._held is not None:
            return math.nan
        t0, d0 = self._counted
        todo, done = self.total - self.done, self.done - d0
        measured = (self._clock() - t0) / done if done > 0 else math.nan
        if self._planned is None:
            return todo * measured
        if not math.isfinite(measured):
            return todo * self._planned
        share = done / max(done + todo, 1e-12)  # from the plan's rate to the measured one as the work gets done
        return todo * ((1.0 - share) * self._planned + share * measured)

    # ------------------------------------------------------------------ steps
    def update(self, steps: float = 1, note: str = "", tick: bool = False) -> None:
        """``steps`` more (weighted) steps finished (``note``: what the last one was, shown beside the bar;
        ``tick``: one of the held phase's steps)."""
        self.done += steps
        if tick and self._held is not None:
            self._held[1] += 1
        if note:
            self._note = note[:40]
        self._postfix()
        self._bar.update(steps)
        if self._lines and self.done >= self._next_line * self.total:
            fraction = min(1.0, self.done / self.total)
            print(self._line(fraction), file=self._out, flush=True)
            while self._next_line <= fraction + 1e-12:
                self._next_line += 0.1

    def _line(self, fraction: float) -> str:
        what = f"nsbench: {self.label or 'work'} {100 * fraction:.0f}% done in {clock(self._clock() - self._start)}"
        if self._held is not None:
            return what + f" ({self._held[0]}: {self._held[1]} of {self._held[2]})"
        left = self.left()
        return what + (f", about {clock(left)} left" if fraction < 1 and math.isfinite(left) else "")

    def _postfix(self) -> None:
        """The text beside a weighted bar: the held phase or the time left, then the note."""
        if not self._weighted:
            if self._note:
                self._bar.set_postfix_str(self._note, refresh=False)
            return
        if self._held is not None:
            state = f"{self._held[0]} {self._held[1]}/{self._held[2]}"
        else:
            left = self.left()
            state = f"{clock(left)} left" if math.isfinite(left) and self.done < self.total else ""
        self._bar.set_postfix_str(", ".join(x for x in (state, self._note) if x), refresh=False)

    def phase(self, text: str) -> None:
        """Say in one line what the run does now: above the bar on a terminal, a plain line in a log."""
        if self.enabled:
            self.say(f"nsbench: {text}")

    def say(self, line: str) -> None:
        """Print ``line`` without breaking the bar (above it on a terminal), enabled or not: the caller decides
        (a plan line is said with ``--no-progress`` too)."""
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
