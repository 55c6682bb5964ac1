"""Henon-Heiles at heyoka's event benchmark settings: heyoka on its own beside nsbench's integrators.

heyoka's ``benchmark/hh_event.cpp`` (github.com/bluescarni/heyoka) propagates the
Henon-Heiles system from a fixed start to ``t = 2000`` at tolerance 1e-15 with an
event on ``x`` increasing through 0. This script times the same propagation
written directly with heyoka.py (best of 5 warm runs), then nsbench's
``henon-heiles`` problem (the same start, every crossing of ``x = 0`` an event)
with a few integrators (best of 3 warm runs, set-up excluded), and prints each
one's number of section points, its largest difference from the quad-precision
reference and its time::

    python benchmarks/henon_heiles_section.py
"""

from __future__ import annotations

import copy
import time

import numpy as np

import nsbench
from nsbench.problems.henon_heiles import HEYOKA_T_END, HEYOKA_TOL


def heyoka_alone() -> tuple[np.ndarray, float]:
    """heyoka's benchmark in heyoka.py: the section times and the best of 5 propagation times."""
    import heyoka as hy

    vx, vy, x, y = hy.make_vars("vx", "vy", "x", "y")
    times: list[float] = []
    event = hy.nt_event(x, lambda ta, t, d_sgn: times.append(t), direction=hy.event_direction.positive)
    ta = hy.taylor_adaptive(
        [(vx, -x - 2.0 * x * y), (vy, y * y - y - x * x), (x, vx), (y, vy)],
        [-0.2525875586263492, -0.2178423952983717, 0.0, 0.2587703282931232],
        tol=HEYOKA_TOL,
        nt_events=[event],
    )
    best = np.inf
    for _ in range(5):
        run = copy.deepcopy(ta)
        times.clear()
        tic = time.perf_counter()
        run.propagate_until(HEYOKA_T_END)
        best = min(best, time.perf_counter() - tic)
    return np.array(times), best


def main() -> None:
    problem = nsbench.get_problem("henon-heiles")
    ref = nsbench.simulate(problem, "reference", HEYOKA_T_END).events
    ref_sections = ref[ref["kind"] == "section"]["t"].to_numpy()
    times, best = heyoka_alone()
    print(f"{'who':34s} {'sections':>8s} {'max |t - t_ref|':>16s} {'seconds':>10s}")
    print(f"{'heyoka.py alone, tol 1e-15':34s} {len(times):8d} {np.abs(times - ref_sections).max():16.2e} {best:10.4f}")
    for name, options in (
        ("heyoka", {"tol": HEYOKA_TOL}),
        ("ofapi", {}),
        ("henon-rk4", {"h": 0.01}),
        ("scipy-dop853", {}),
        ("reference", {}),
    ):
        integ = nsbench.get_integrator(name, **options)
        runs = [nsbench.simulate(problem, integ, HEYOKA_T_END) for _ in range(3)]
        ev = runs[-1].events
        same = list(ev["kind"]) == list(ref["kind"])
        err = np.abs(ev["t"].to_numpy() - ref["t"].to_numpy()).max() if same else float("nan")
        label = f"nsbench {name} {options or ''}".strip()
        print(
            f"{label:34s} {int((ev['kind'] == 'section').sum()):8d} {err:16.2e} {min(r.wall_time for r in runs):10.4f}"
        )


if __name__ == "__main__":
    main()
