"""A small progress bar for suite runs (no dependency): redraws one line on a
terminal, prints a line every few percent otherwise (logs, CI)."""

from __future__ import annotations

import sys
import time
from typing import TextIO


def _clock(seconds: float) -> str:
    seconds = int(round(seconds))
    return f"{seconds // 60}:{seconds % 60:02d}"


class Progress:
    """Counts finished cases out of ``total`` and shows elapsed time and an estimate."""

    def __init__(self, total: int, label: str = "cases", stream: TextIO | None = None,
                 enabled: bool = True, width: int = 28) -> None:
        self.total = max(total, 0)
        self.label = label
        self.stream = stream if stream is not None else sys.stderr
        self.enabled = enabled and self.total > 0
        self.tty = bool(getattr(self.stream, "isatty", lambda: False)())
        self.width = width
        self.done = 0
        self.start = time.perf_counter()
        self._last_pct = -100.0

    def update(self, note: str = "", steps: int = 1) -> None:
        """``steps`` more steps finished (``note``: what they were)."""
        self.done += steps
        if not self.enabled:
            return
        elapsed = time.perf_counter() - self.start
        left = elapsed / self.done * (self.total - self.done) if self.done else 0.0
        frac = self.done / self.total
        bar = "#" * int(frac * self.width) + "." * (self.width - int(frac * self.width))
        text = (f"[{bar}] {self.done}/{self.total} {self.label}  {_clock(elapsed)} elapsed, "
                f"~{_clock(left)} left")
        if self.tty:
            tail = f"  {note}"[: 60]
            self.stream.write("\r" + text + tail + "\033[K")
            if self.done == self.total:
                self.stream.write("\n")
        elif 100 * frac - self._last_pct >= 10 or self.done == self.total:
            self._last_pct = 100 * frac
            self.stream.write(text + "\n")
        self.stream.flush()

    def close(self) -> None:
        if self.enabled and self.tty and self.done < self.total:
            self.stream.write("\n")
            self.stream.flush()
