"""What the per-step missed-crossing check costs the per-arc adapters. Measured, not asserted.

Each adapter (``scipy-*``, ``cvode-*``, ``ida``) runs 2-DOF case 2 over [0, 300]
with ``check_points=0`` twice per round: as registered (every accepted step
checked, :mod:`nsbench.integrators._step_check`) and as a subclass with
``check_steps = False`` (only the signs at the step ends, as ``solve_ivp`` and
SUNDIALS' root finding see them). The pairs are interleaved in one process, the
order of the two alternating between rounds; the figure is the ratio of the best
CPU times (``time.process_time``) and of the best wall times over the rounds.
The events, the function evaluations and the steps of the two runs are printed
too: where no step is flagged they are the same. The last column is steadier than
the ratios on a busy machine: the share of the checked run's wall time spent
inside the check's calls (``_step_check.checked``, one per arc, reruns included),
best round.

    python benchmarks/step_check_cost.py --rounds 5
"""

from __future__ import annotations

import argparse
import os
import subprocess
import time

import nsbench
from nsbench.integrators import _step_check, integrator_class

_inside = [0.0]  # seconds spent in _step_check.checked since the last reset
_checked = _step_check.checked


def _timed_check(*args, **kwargs):
    tic = time.perf_counter()
    try:
        return _checked(*args, **kwargs)
    finally:
        _inside[0] += time.perf_counter() - tic


_step_check.checked = _timed_check  # the adapters call it through the module: every call is timed

ADAPTERS = (
    "scipy-rk45",
    "scipy-dop853",
    "scipy-radau",
    "scipy-bdf",
    "scipy-lsoda",
    "cvode-adams",
    "cvode-bdf",
    "ida",
)


def _unchecked(name: str):
    """The adapter ``name`` with its per-step check switched off."""
    base = integrator_class(name)
    return type(f"Unchecked{base.__name__}", (base,), {"name": f"{name}-unchecked", "check_steps": False})


def _timed(problem, integ, t_end: float):
    _inside[0] = 0.0
    cpu, wall = time.process_time(), time.perf_counter()
    res = nsbench.simulate(problem, integ, t_end, check_points=0)
    return time.process_time() - cpu, time.perf_counter() - wall, res


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--t-end", type=float, default=300.0)
    parser.add_argument("--only", nargs="*", default=list(ADAPTERS))
    args = parser.parse_args()
    problem = nsbench.get_problem("two-dof", case=2)
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True).stdout.strip()
    print(f"commit {commit}, load average {os.getloadavg()[0]:.1f}, {args.rounds} rounds")
    print(
        "| integrator | events (on / off) | nfev (on / off) | steps (on / off) | reruns | CPU on / off | wall on / off | in the check |"
    )
    print("|---|---|---|---|---|---|---|---|")
    for name in args.only:
        on, off = nsbench.get_integrator(name), _unchecked(name)()
        _timed(problem, on, args.t_end)  # first use of the modes' data, untimed
        _timed(problem, off, args.t_end)
        best = {"on": [float("inf"), float("inf")], "off": [float("inf"), float("inf")]}
        runs = {}
        share = float("inf")
        for k in range(args.rounds):
            order = (("on", on), ("off", off)) if k % 2 == 0 else (("off", off), ("on", on))
            for label, integ in order:
                cpu, wall, res = _timed(problem, integ, args.t_end)
                best[label] = [min(best[label][0], cpu), min(best[label][1], wall)]
                runs[label] = res
                if label == "on":
                    share = min(share, _inside[0] / wall)
        a, b = runs["on"], runs["off"]
        print(
            f"| `{name}` | {len(a.events)} / {len(b.events)} | {a.counters.nfev} / {b.counters.nfev} "
            f"| {a.counters.nsteps} / {b.counters.nsteps} | {a.counters.extra.get('check_reruns', 0)} "
            f"| {best['on'][0] / best['off'][0]:.2f} | {best['on'][1] / best['off'][1]:.2f} | {100 * share:.1f}% |",
            flush=True,
        )
    print(f"load average at the end {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
