"""Does the plan line hold for a suite with a plug-in of unmeasured cost? Runs one and prints plan against actual.

The plug-in is the tutorial's (``examples/plugin``, ``heun-bisect``), taken from the
source tree: its directory goes on ``PYTHONPATH`` (the workers inherit it) and the
integrator is registered in this process, so nothing is installed. The suite runs
through ``nsbench bench`` (the command a user types, its report included), timed from
the start of the command to its end; its stderr is echoed and the plan lines read
from it: the first one (a lower bound while cases are unmeasured) and the revised one
said as the timing starts (with the probes). Used for the measurements in
docs/explanation/measurements.md ("The plan line"); not collected by pytest.

    python benchmarks/plan_probe.py                    # a small suite, about a minute on 2 cores
    python benchmarks/plan_probe.py --suite tutorial   # the tutorial's my-suite.toml (5-10 min)
"""

from __future__ import annotations

import argparse
import contextlib
import io
import os
import re
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PLUGIN = ROOT / "examples" / "plugin" / "src"
TUTORIAL = ROOT / "docs" / "tutorials" / "compare-your-method.md"

#: A few minutes of heun-bisect (Python arcs, unmeasured) beside two measured methods.
SMALL = """
name = "plan-probe"
t_span = [0, 50]
repeats = 3
time_limit = 120

[[problems]]
name = "two-dof"
cases = [1]

[[problems]]
name = "bouncing-ball"

[integrators]
only = ["heun-bisect", "scipy-dop853", "henon-rk4"]

[integrators.grids.heun-bisect]
grid = { h = [0.004, 0.001] }
"""


def tutorial_suite() -> str:
    """The TOML block marked ``<!-- suite -->`` in the tutorial (the test of the docs loads it too)."""
    text = TUTORIAL.read_text()
    block = text.split("<!-- suite -->", 1)[1]
    return block.split("```toml", 1)[1].split("```", 1)[0]


def _seconds(text: str) -> float:
    number, unit = text.split()
    return float(number) * (60.0 if unit == "min" else 1.0)


def plan_figures(log: str) -> dict[str, float]:
    """Seconds the plan lines of a run's stderr said: ``first`` (and ``first_most``), ``revised``, ``revised_most``."""
    out: dict[str, float] = {}
    first = re.search(r"estimated (at least )?about (\d+ (?:s|min))(?:, up to about (\d+ (?:s|min)))?", log)
    if first:
        out["first"] = _seconds(first.group(2))
        if first.group(3):
            out["first_most"] = _seconds(first.group(3))
    revised = re.search(
        r"revised[^:]*: about (\d+ (?:s|min))(?: \(long\))? in all(?:, up to about (\d+ (?:s|min)))?", log
    )
    if revised:
        out["revised"] = _seconds(revised.group(1))
        if revised.group(2):
            out["revised_most"] = _seconds(revised.group(2))
    return out


class _Tee(io.StringIO):
    """Keeps what is written and echoes it to the real stderr."""

    def write(self, s: str) -> int:
        sys.__stderr__.write(s)
        return super().write(s)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--suite", choices=["small", "tutorial"], default="small")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--out", help="results folder (default: a temporary one)")
    args = parser.parse_args()
    os.environ["PYTHONPATH"] = os.pathsep.join([str(PLUGIN)] + [p for p in [os.environ.get("PYTHONPATH")] if p])
    sys.path.insert(0, str(PLUGIN))
    from nsbench_heun import HeunBisection

    from nsbench import registry
    from nsbench.cli import main as nsbench

    registry.register("integrators", "heun-bisect", HeunBisection)
    work = Path(tempfile.mkdtemp(prefix="plan-probe-"))
    suite = work / "suite.toml"
    suite.write_text(SMALL if args.suite == "small" else tutorial_suite())
    out = args.out or str(work / "results")
    log = _Tee()
    tic = time.monotonic()
    with contextlib.redirect_stderr(log):
        status = nsbench(["bench", str(suite), "--out", out, "--fresh", "--workers", str(args.workers)])
    took = time.monotonic() - tic
    said = plan_figures(log.getvalue())
    print(f"\nsuite {args.suite}: took {took:.0f} s (exit status {status}, load now {os.getloadavg()[0]:.1f})")
    for key in ("first", "first_most", "revised", "revised_most"):
        if key in said:
            print(f"  plan {key:13s} {said[key]:6.0f} s   actual / plan = {took / said[key]:.2f}")
    return status


if __name__ == "__main__":
    sys.exit(main())
