"""Progress bars of long runs (suites, sweeps), over tqdm.

One bar per run, on stderr. It is drawn only on a terminal: in CI logs, pipes
and files it stays silent (``enabled=False`` silences it everywhere; the CLI's
``--no-progress``). The estimate of the time left is tqdm's: the work left
times a smoothed rate of completed steps.
"""

from __future__ import annotations

import sys
from typing import TextIO


class Progress:
    """Counts finished steps out of ``total``; shows the rate, the elapsed time and the time left.

    Parameters
    ----------
    total
        Steps in all (a bar of 0 steps draws nothing).
    label
        What the bar counts (``'steps'``, the swept parameter's name).
    stream
        Where to draw (default stderr); nothing is drawn unless it is a terminal.
    enabled
        ``False``: never draw.
    """

    def __init__(self, total: int, label: str = "", stream: TextIO | None = None, enabled: bool = True) -> None:
        from tqdm import tqdm

        out = stream if stream is not None else sys.stderr
        tty = bool(getattr(out, "isatty", lambda: False)())
        self.total = max(int(total), 0)
        self.done = 0
        self._bar = tqdm(total=self.total, desc=label or None, file=out, unit="step",
                         disable=not (enabled and tty and self.total > 0), dynamic_ncols=True,
                         smoothing=0.1, leave=True)

    def update(self, steps: int = 1, note: str = "") -> None:
        """``steps`` more steps finished (``note``: what the last one was, shown beside the bar)."""
        self.done += steps
        if note:
            self._bar.set_postfix_str(note[:40], refresh=False)
        self._bar.update(steps)

    def close(self) -> None:
        self._bar.close()

    def __enter__(self) -> "Progress":
        return self

    def __exit__(self, *exc) -> None:
        self.close()
