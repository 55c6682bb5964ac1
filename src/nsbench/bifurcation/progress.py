"""A dependency-free progress bar with rate and ETA, on stderr."""

from __future__ import annotations

import sys
import time


class Progress:
    """Counts finished items; redraws one line on a terminal, prints every ~10% otherwise."""

    def __init__(self, total: int, label: str = "", stream=None, enabled: bool = True) -> None:
        self.total = max(int(total), 0)
        self.label = label
        self.stream = stream if stream is not None else sys.stderr
        self.enabled = enabled and self.total > 0
        self.done = 0
        self.start = time.perf_counter()
        self._last_pct = -10
        self._tty = bool(getattr(self.stream, "isatty", lambda: False)())

    def update(self, n: int = 1) -> None:
        self.done += n
        if not self.enabled:
            return
        pct = 100 * self.done // self.total
        if self._tty or pct >= self._last_pct + 10 or self.done == self.total:
            self._last_pct = pct
            self._draw()

    def _draw(self) -> None:
        elapsed = time.perf_counter() - self.start
        rate = self.done / elapsed if elapsed > 0 else 0.0
        eta = (self.total - self.done) / rate if rate > 0 else float("nan")
        width = 28
        filled = int(width * self.done / self.total)
        bar = "#" * filled + "." * (width - filled)
        line = (f"{self.label} [{bar}] {self.done}/{self.total} "
                f"{elapsed:6.1f}s elapsed, ETA {_fmt(eta)} ({rate:.1f}/s)")
        end = "\r" if self._tty and self.done < self.total else "\n"
        self.stream.write(line + end)
        self.stream.flush()

    def close(self) -> None:
        if self.enabled and self._tty and self.done < self.total:
            self.stream.write("\n")


def _fmt(seconds: float) -> str:
    if seconds != seconds:  # NaN
        return "?"
    m, s = divmod(int(round(seconds)), 60)
    return f"{m}m{s:02d}s" if m else f"{s}s"
