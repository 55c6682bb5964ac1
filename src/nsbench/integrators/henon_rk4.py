"""``henon-rk4``: fixed-step classical RK4 with Henon's trick on every surface (METHODS.md section 7).

After a step that crosses a guard ``S``, one RK4 step of size ``-S`` in the
independent variable ``sigma = S`` (field ``(f, 1) / dS/dt`` over ``(y, t)``, with
the *old* mode's field) lands on the surface; ``t`` is carried as a state so the
forced cases are handled. This keeps RK4's order 4 for event times. A guard
that dips across and back within one step is caught from the cubic Hermite
interpolant of the guard (values and rates at the step ends), and located by
bisection on RK4 sub-steps, as is any Henon point outside its step (near-grazing).
Sections use the same Henon step; dense output is the cubic Hermite
interpolant, consistent with order 4.

For the friction oscillator the whole arc runs in compiled code
(:mod:`nsbench.integrators._henon_kernel`); the Python loop below is the same
algorithm for any other problem that implements the problem interface, and
the reference the compiled arc is tested against.
"""

from __future__ import annotations

import math
from typing import Callable

import numpy as np

from nsbench.integrators.base import ArcRequest, ArcResult, Capabilities, Integrator, Option, SectionHit
from nsbench.problems.oscillator import FrictionOscillator
from nsbench.results import Status

Field = Callable[[float, np.ndarray], np.ndarray]


def rk4_step(f: Field, t: float, y: np.ndarray, h: float, fy: np.ndarray) -> np.ndarray:
    """One classical RK4 step from ``(t, y)`` with ``fy = f(t, y)`` known (3 new evaluations)."""
    k2 = f(t + 0.5 * h, y + 0.5 * h * fy)
    k3 = f(t + 0.5 * h, y + 0.5 * h * k2)
    k4 = f(t + h, y + h * k3)
    return y + (h / 6.0) * (fy + 2.0 * k2 + 2.0 * k3 + k4)


def hermite(t0: float, y0: np.ndarray, f0: np.ndarray, t1: float, y1: np.ndarray,
            f1: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Cubic Hermite interpolant at times ``t`` (shape ``(k,)``): shape ``(n, k)``."""
    h = t1 - t0
    th = (np.asarray(t, dtype=float) - t0) / h
    h00 = (1 + 2 * th) * (1 - th) ** 2
    h10 = th * (1 - th) ** 2
    h01 = th * th * (3 - 2 * th)
    h11 = th * th * (th - 1)
    return (np.outer(y0, h00) + h * np.outer(f0, h10) + np.outer(y1, h01) + h * np.outer(f1, h11))


def hermite_dips(p0: float, p1: float, d0: float, d1: float, skip_start: bool) -> bool:
    """Whether the cubic with ends ``p0, p1 > 0`` and slopes ``d0, d1`` (per unit step) dips to <= 0."""
    # p(s) = a s^3 + b s^2 + d0 s + p0 on [0, 1]
    a = 2 * p0 - 2 * p1 + d0 + d1
    b = -3 * p0 + 3 * p1 - 2 * d0 - d1
    roots = np.roots([3 * a, 2 * b, d0]) if (a != 0 or b != 0) else np.array([])
    for r in roots:
        if abs(r.imag) > 1e-12:
            continue
        s = r.real
        if 0.0 < s < 1.0 and 6 * a * s + 2 * b > 0:
            if skip_start and s < 1e-6:
                continue
            if ((a * s + b) * s + d0) * s + p0 <= 0.0:
                return True
    return False


class HenonRK4(Integrator):
    """Classical RK4 at fixed step ``h`` with Henon's method for every guard and section."""

    name = "henon-rk4"
    capabilities = Capabilities(
        event_location="henon", order=4, adaptive=False, needs_jacobian=False,
        supports_nonlinear=True, precision="double", step_option="h",
    )
    options = {"h": Option(0.01, float, lower=0.0, doc="step size (time units)")}
    accuracy_levels = ({"h": 0.04}, {"h": 0.01}, {"h": 0.0025}, {"h": 0.000625})

    def setup(self, problem) -> None:
        super().setup(problem)
        self._packed = None
        if isinstance(problem, FrictionOscillator):
            from nsbench.problems import kernels

            self._packed = (problem, kernels.pack(problem))
            _compiled_arc(self, ArcRequest(problem, problem.modes[0], 0.0, problem.initial_state(),
                                           self.settings["h"], problem.guards(problem.modes[0])))

    def advance(self, request: ArcRequest) -> ArcResult:
        packed = getattr(self, "_packed", None)
        if packed is not None and packed[0] is request.problem:
            return _compiled_arc(self, request)
        return self.advance_python(request)

    def advance_python(self, request: ArcRequest) -> ArcResult:
        """The generic (uncompiled) arc: any problem with ``rhs`` and guard objects."""
        problem, mode = request.problem, request.mode
        counts = {"nfev": 0, "henon_steps": 0, "bisections": 0}

        def f(t: float, y: np.ndarray) -> np.ndarray:
            counts["nfev"] += 1
            return problem.rhs(mode, t, y)

        h = self.settings["h"]
        t0, t_end = request.t0, request.t_end
        t, y = t0, np.array(request.y0, dtype=float)
        fy = f(t, y)
        guards, sections = request.guards, request.sections
        phi = [g.expected_sign * float(g.value(t, y)) for g in guards]
        psi = [g.expected_sign * float(g.rate(t, y, fy)) for g in guards]
        sec_val = [float(s.value(t, y)) for s in sections]
        t_eval = request.t_eval
        dense: list[np.ndarray] = []
        n_done = 0
        hits: list[SectionHit] = []
        steps = 0
        fired = None
        n_left = max(1, math.ceil((t_end - t0) / h - 1e-9))
        while t < t_end:
            if steps >= request.max_steps:
                return self._result(t, y, None, dense, problem, hits, steps, counts,
                                    Status.BUDGET_EXHAUSTED, f"step budget exhausted at t = {t:.6g}")
            last = n_left <= 1
            t1 = t_end if last else t0 + (steps + 1) * h
            hk = t1 - t
            y1 = rk4_step(f, t, y, hk, fy)
            f1 = f(t1, y1)
            steps += 1
            n_left -= 1
            if not np.all(np.isfinite(y1)):
                return self._result(t, y, None, dense, problem, hits, steps, counts,
                                    Status.INTEGRATOR_FAILURE, f"non-finite state after t = {t:.6g}")
            start = t == t0
            candidates = []
            phi1, psi1 = [], []
            for q, g in enumerate(guards):
                p1 = g.expected_sign * float(g.value(t1, y1))
                d1 = g.expected_sign * float(g.rate(t1, y1, f1))
                phi1.append(p1)
                psi1.append(d1)
                crossed = p1 <= 0.0 or (
                    (phi[q] > 0.0 or start) and hermite_dips(phi[q], p1, hk * psi[q], hk * d1, start))
                if crossed:
                    located = self._locate(f, g, g.expected_sign, t, y, fy, t1, y1, f1, p1 <= 0.0,
                                           start, counts)
                    if located is not None:
                        candidates.append((located[0], q, located[1]))
            if candidates:
                t_star, fired, y_star = min(candidates, key=lambda c: (c[0], c[1]))
                f_star = f(t_star, y_star)
                self._sections(f, sections, sec_val, t, y, t_star, y_star, f_star, hits, counts)
                n_done = self._dense(t_eval, n_done, t, y, fy, t_star, y_star, f_star, dense)
                t, y = t_star, y_star
                break
            self._sections(f, sections, sec_val, t, y, t1, y1, f1, hits, counts)
            n_done = self._dense(t_eval, n_done, t, y, fy, t1, y1, f1, dense)
            t, y, fy, phi, psi = t1, y1, f1, phi1, psi1
        return self._result(t, y, fired, dense, problem, hits, steps, counts, Status.SUCCESS, "")

    # ------------------------------------------------------------------ pieces
    @staticmethod
    def _result(t, y, fired, dense, problem, hits, steps, counts, status, message) -> ArcResult:
        y_eval = np.hstack(dense) if dense else np.empty((problem.n_states, 0))
        return ArcResult(
            t=float(t), y=np.array(y, dtype=float), fired=fired, y_eval=y_eval,
            section_hits=sorted(hits, key=lambda hit: hit.t), nfev=counts["nfev"], njev=0,
            nsteps=steps, extra={"henon_steps": counts["henon_steps"], "bisections": counts["bisections"]},
            status=status, message=message,
        )

    @staticmethod
    def _dense(t_eval, n_done, ta, ya, fa, tb, yb, fb, dense) -> int:
        n_new = int(np.searchsorted(t_eval, tb, side="right"))
        if n_new > n_done:
            dense.append(hermite(ta, ya, fa, tb, yb, fb, t_eval[n_done:n_new]))
        return max(n_new, n_done)

    def _henon(self, f, fn, ta: float, tb: float, y1: np.ndarray, t1: float,
               counts) -> tuple[float, np.ndarray] | None:
        """One RK4 step in sigma = fn from ``(t1, y1)`` back to ``fn = 0``; ``None`` if unusable."""
        counts["henon_steps"] += 1

        def field(t: float, y: np.ndarray):
            fy = f(t, y)
            rate = float(fn.rate(t, y, fy))
            if rate == 0.0 or not math.isfinite(rate):
                raise ZeroDivisionError
            return fy / rate, 1.0 / rate

        ds = -float(fn.value(t1, y1))
        try:
            k1y, k1t = field(t1, y1)
            k2y, k2t = field(t1 + 0.5 * ds * k1t, y1 + 0.5 * ds * k1y)
            k3y, k3t = field(t1 + 0.5 * ds * k2t, y1 + 0.5 * ds * k2y)
            k4y, k4t = field(t1 + ds * k3t, y1 + ds * k3y)
        except ZeroDivisionError:
            return None
        t_star = t1 + ds / 6.0 * (k1t + 2 * k2t + 2 * k3t + k4t)
        y_star = y1 + ds / 6.0 * (k1y + 2 * k2y + 2 * k3y + k4y)
        if not (ta < t_star <= tb) or not np.all(np.isfinite(y_star)):
            return None
        return t_star, y_star

    def _locate(self, f, fn, sign, t, y, fy, t1, y1, f1, end_crossed: bool, start: bool,
                counts) -> tuple[float, np.ndarray] | None:
        """Event time and state of ``fn`` in ``(t, t1]``: Henon first, bisection as fallback."""
        if end_crossed:
            found = self._henon(f, fn, t, t1, y1, t1, counts)
            if found is not None:
                return found
        return self._bisect(f, fn, sign, t, y, fy, t1, start, counts)

    def _bisect(self, f, fn, sign, t, y, fy, t1, start: bool, counts) -> tuple[float, np.ndarray] | None:
        """First zero of ``sign * fn`` in ``(t, t1]`` from RK4 sub-steps of ``(t, y)``."""
        counts["bisections"] += 1

        def signed(tau: float) -> tuple[float, np.ndarray]:
            ys = rk4_step(f, t, y, tau - t, fy)
            return sign * float(fn.value(tau, ys)), ys

        grid = np.linspace(t, t1, 9)
        lo = t
        hi = None
        positive_seen = not start
        for tau in grid[1:]:
            value, ys = signed(float(tau))
            if value > 0.0:
                positive_seen = True
                lo = float(tau)
            elif positive_seen:
                hi, y_hi = float(tau), ys
                break
        if hi is None:
            return None
        for _ in range(80):
            mid = 0.5 * (lo + hi)
            if mid <= lo or mid >= hi:
                break
            value, ys = signed(mid)
            if value > 0.0:
                lo = mid
            else:
                hi, y_hi = mid, ys
        return hi, y_hi

    def _sections(self, f, sections, values, ta, ya, tb, yb, fb, hits, counts) -> None:
        """Record section crossings between two states; update ``values`` to ``tb``."""
        for k, sec in enumerate(sections):
            vb = float(sec.value(tb, yb))
            if sec.crossed(values[k], vb):
                if vb == 0.0:
                    hits.append(SectionHit(k, tb, np.array(yb)))
                else:
                    found = self._henon(f, sec, ta, tb, yb, tb, counts)
                    if found is None:
                        sign = 1.0 if values[k] > 0 else -1.0
                        fa = f(ta, ya)
                        found = self._bisect(f, sec, sign, ta, ya, fa, tb, False, counts)
                    if found is not None:
                        hits.append(SectionHit(k, found[0], found[1]))
            values[k] = vb


_HIT_BUFFER = 256


def _compiled_arc(integ: HenonRK4, request: ArcRequest) -> ArcResult:
    """Run the arc in the compiled kernel, resuming on the same grid when the hit buffer fills."""
    from nsbench.integrators import _henon_kernel as kernel
    from nsbench.problems import kernels

    problem = request.problem
    p = integ._packed[1]
    n = problem.n_states
    mode = kernels.mode_array(request.mode)
    kinds, blocks, signs = kernels.guard_codes(request.guards)
    ns = len(request.sections)
    sec_c = np.array([s.coeffs for s in request.sections], dtype=float).reshape(ns, n)
    sec_l = np.array([s.level for s in request.sections], dtype=float)
    sec_dir = np.array([s.direction for s in request.sections], dtype=np.int64)
    t_eval = np.ascontiguousarray(request.t_eval, dtype=float)
    y_eval = np.empty((n, t_eval.size))
    h = integ.settings["h"]
    t0, t_end = request.t0, request.t_end
    n_total = max(1, math.ceil((t_end - t0) / h - 1e-9))
    hit_idx = np.empty(_HIT_BUFFER, dtype=np.int64)
    hit_t = np.empty(_HIT_BUFFER)
    hit_y = np.empty((_HIT_BUFFER, n))
    y_stop = np.empty(n)
    counters = np.zeros(6, dtype=np.int64)
    totals = np.zeros(4, dtype=np.int64)
    hits: list[SectionHit] = []
    t, y, step, n_done = t0, np.array(request.y0, dtype=float), 0, 0
    while True:
        status, t, fired, step = kernel.henon_arc(
            p, mode, t0, step, t, y, t_end, h, n_total, kinds, blocks, signs, sec_c, sec_l, sec_dir,
            t_eval, n_done, request.max_steps - int(totals[0]), y_eval, hit_idx, hit_t, hit_y, y_stop,
            counters)
        totals += counters[:4]
        n_done = int(counters[4])
        hits.extend(SectionHit(int(hit_idx[k]), float(hit_t[k]), hit_y[k].copy())
                    for k in range(int(counters[5])))
        y = y_stop.copy()
        if status != kernel.BUFFER_FULL:
            break
    extra = {"henon_steps": int(totals[2]), "bisections": int(totals[3])}
    statuses = {kernel.SUCCESS: (Status.SUCCESS, ""),
                kernel.BUDGET: (Status.BUDGET_EXHAUSTED, f"step budget exhausted at t = {t:.6g}"),
                kernel.FAILURE: (Status.INTEGRATOR_FAILURE, f"non-finite state after t = {t:.6g}")}
    code, message = statuses[status]
    return ArcResult(t=float(t), y=y, fired=None if fired < 0 else int(fired), y_eval=y_eval[:, :n_done],
                     section_hits=hits, nfev=int(totals[1]), njev=0, nsteps=int(totals[0]), extra=extra,
                     status=code, message=message)
