"""Largest Lyapunov exponent of the mapping-point return map (Benettin's two-trajectory method).

A mapping point is a slip event: the state where the locus of sticking phase
leaves a sliding region. The return map takes one mapping point to the next.
From a mapping point on the attractor, a copy is displaced by ``d0`` (in the
coordinates that are free there: velocities pinned at the belt speed are left
alone; for forced problems the forcing phase ``Omega t`` counts as a
coordinate), both are integrated to their next mapping point, the separation
``d`` is measured there, ``log(d / d0)`` is accumulated, and the copy is put
back at distance ``d0`` along the new separation. The mean over the
iterations is the exponent per mapping point; divided by the mean return time
it is per unit time. The convergence check asks for a small standard error
(from the spread of 10 block means, which accounts for correlation between
iterations) and for the estimates from the two halves of the iterations to agree.

This uses the compiled hybrid loop, which can start in a given mode
(``exact-jit`` for linear problems, ``henon-rk4-jit`` for any).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from nsbench.errors import ConfigError


@dataclass
class LyapunovResult:
    """Estimate of the largest Lyapunov exponent of the mapping-point return map.

    Attributes
    ----------
    exponent
        Per mapping point (mean of ``log(d_k / d0)``).
    exponent_per_time
        Per unit time (sum of logs over the elapsed time).
    first_half, second_half
        Estimates from each half of the iterations.
    standard_error
        Standard error of ``exponent`` from 10 block means.
    converged
        ``standard_error <= max(0.05 |exponent|, tol / 2)`` and the halves agree
        within ``max(0.1 |exponent|, tol)``.
    iterations, mean_return_time, block_mismatches
        Map iterations done, mean time between mapping points, and the
        iterations where the two copies reached their next mapping point on
        different blocks (near a border-collision).
    logs
        ``log(d_k / d0)`` per iteration.
    """

    exponent: float
    exponent_per_time: float
    first_half: float
    second_half: float
    standard_error: float
    converged: bool
    iterations: int
    mean_return_time: float
    block_mismatches: int
    status: str = "success"
    message: str = ""
    logs: np.ndarray = field(default_factory=lambda: np.empty(0), repr=False)

    def summary(self) -> str:
        verdict = "converged" if self.converged else "NOT converged"
        return (f"largest Lyapunov exponent {self.exponent:+.5f} per mapping point, "
                f"{self.exponent_per_time:+.5f} per unit time, standard error {self.standard_error:.2g} "
                f"({verdict}: halves "
                f"{self.first_half:+.5f} / {self.second_half:+.5f}; {self.iterations} iterations, "
                f"mean return time {self.mean_return_time:.4g}, block mismatches {self.block_mismatches})")


def _next_mapping(integ, problem, t, y, mode, window):
    run = integ.run(problem, t_end=t + window, section="mapping", t_rec=t, n_rec=1, t0=t, y0=y, mode=mode)
    if run.n < 1:
        return None, run
    return (float(run.rec_t[0]), np.array(run.rec_y[0]), run.mode.copy(), int(run.rec_block[0])), run


def largest_exponent(problem, integrator: str = "exact-jit", *, options: dict | None = None,
                     transient: float = 1000.0, iterations: int = 10000, d0: float = 1e-8,
                     window: float = 2000.0, seed: int = 0, tol: float = 0.01) -> LyapunovResult:
    """Benettin estimate of the largest Lyapunov exponent of the mapping points of ``problem``.

    Parameters
    ----------
    integrator
        A compiled integrator (``exact-jit`` or ``henon-rk4-jit``).
    transient
        Time integrated from rest before the first mapping point used.
    iterations
        Return-map iterations averaged.
    d0
        Separation the copy is renormalised to at each mapping point.
    window
        Longest time allowed between two mapping points.
    seed
        Seed of the random initial direction.
    tol
        Absolute tolerance of the convergence check.
    """
    from nsbench.integrators import get_integrator

    integ = get_integrator(integrator, **(options or {}))
    if not hasattr(integ, "run"):
        raise ConfigError(f"lyapunov needs a compiled integrator (exact-jit, henon-rk4-jit), not {integrator!r}")
    if iterations < 4:
        raise ConfigError(f"iterations = {iterations} must be at least 4")
    if not (0.0 < d0 < 1e-2):
        raise ConfigError(f"d0 = {d0!r} must be in (0, 0.01)")
    integ.setup(problem)
    forced = problem.is_forced and problem.coefficients.w > 0
    w = problem.coefficients.w if forced else 0.0
    v0 = problem.v0
    n = problem.n_states
    start = integ.run(problem, t_end=transient + window, section="mapping", t_rec=transient, n_rec=1)
    if start.n < 1:
        return _failed(f"no mapping point within {window:g} after the transient ({start.status}): "
                       "the motion has no slip events (pure sliding or permanent sticking)")
    ref = (float(start.rec_t[0]), np.array(start.rec_y[0]), start.mode.copy(), int(start.rec_block[0]))
    rng = np.random.default_rng(seed)
    u = rng.normal(size=n + 1)

    def project(vec, y):
        vec = vec.copy()
        pinned = [2 * i + 1 for i in range(problem.n_blocks) if y[2 * i + 1] == v0]
        vec[pinned] = 0.0
        if not forced:
            vec[n] = 0.0
        norm = math.sqrt(float(vec @ vec))
        return vec / norm if norm > 0 else None

    u = project(u, ref[1])
    logs, times, mismatches = [], [], 0
    t_first = ref[0]
    for _ in range(iterations):
        if u is None:  # every free direction collapsed: restart from a random one
            u = project(rng.normal(size=n + 1), ref[1])
        t, y, mode, _ = ref
        pert_y = y + d0 * u[:n]
        pert_t = t + d0 * u[n] / w if forced else t
        nxt, run = _next_mapping(integ, problem, t, y, mode, window)
        pnx, prun = _next_mapping(integ, problem, pert_t, pert_y, mode.copy(), window)
        if nxt is None or pnx is None:
            bad = run if nxt is None else prun
            return _failed(f"no next mapping point within {window:g} ({bad.status})", logs, times, t_first,
                           mismatches)
        mismatches += int(nxt[3] != pnx[3])
        diff = np.append(pnx[1] - nxt[1], w * (pnx[0] - nxt[0]))
        d = math.sqrt(float(diff @ diff))
        logs.append(math.log(max(d, d0 * 1e-16) / d0))
        times.append(nxt[0])
        ref = nxt
        u = project(diff, nxt[1]) if d > 0 else None
    return _result(np.array(logs), np.array(times), t_first, mismatches, tol)


def _result(logs, times, t_first, mismatches, tol, status="success", message=""):
    k = len(logs)
    lam = float(logs.mean()) if k else np.nan
    half = k // 2
    a = float(logs[:half].mean()) if half else np.nan
    b = float(logs[half:].mean()) if k - half else np.nan
    elapsed = float(times[-1] - t_first) if k else np.nan
    per_time = float(logs.sum() / elapsed) if k and elapsed > 0 else np.nan
    if k >= 20:
        blocks = logs[: k // 10 * 10].reshape(10, -1).mean(axis=1)
        se = float(blocks.std(ddof=1) / math.sqrt(10))
    else:
        se = np.nan
    converged = bool(k >= 20 and se <= max(0.05 * abs(lam), tol / 2)
                     and abs(a - b) <= max(0.1 * abs(lam), tol))
    return LyapunovResult(lam, per_time, a, b, se, converged, k, elapsed / k if k else np.nan, mismatches,
                          status, message, logs)


def _failed(message, logs=(), times=(), t_first=0.0, mismatches=0):
    res = _result(np.array(logs, dtype=float), np.array(times, dtype=float), t_first, mismatches, 0.01,
                  status="failure", message=message)
    res.converged = False
    return res
