"""``heun-bisect``: Heun's method (explicit trapezoidal rule, order 2) at a fixed step, events by bisection.

An example of an out-of-tree nsbench integrator. It implements the
:class:`nsbench.integrators.Integrator` contract: it advances one frozen mode
(``request.rhs``), tests every guard against its expected sign at each step
end, and locates a crossing by bisection on Heun sub-steps from the start of
the step. It is registered through the ``nsbench.integrators`` entry point in
this package's ``pyproject.toml`` and checked with ``nsbench check heun-bisect``.
"""

from __future__ import annotations

import math

import numpy as np

from nsbench.integrators import ArcRequest, ArcResult, Capabilities, Integrator, SectionHit
from nsbench.integrators.base import Option
from nsbench.results import Status

__all__ = ["HeunBisection"]


def heun_step(f, t: float, y: np.ndarray, h: float, fy: np.ndarray) -> np.ndarray:
    """One step of Heun's method from ``(t, y)`` with ``fy = f(t, y)`` known."""
    predictor = y + h * fy
    return y + 0.5 * h * (fy + f(t + h, predictor))


class HeunBisection(Integrator):
    """Heun's method (order 2) at a fixed step ``h``; guard crossings located by bisection."""

    name = "heun-bisect"
    capabilities = Capabilities(
        event_location="bisection",
        order=2,
        adaptive=False,
        needs_jacobian=False,
        supports_nonlinear=True,
        precision="double",
        step_option="h",
    )
    options = {"h": Option(0.001, float, lower=0.0, doc="step size (time units)")}
    accuracy_levels = ({"h": 0.004}, {"h": 0.001}, {"h": 0.00025})

    def advance(self, request: ArcRequest) -> ArcResult:
        n = request.problem.n_states
        counts = {"nfev": 0, "bisections": 0}

        def f(t, y):
            counts["nfev"] += 1
            return request.rhs(t, y)

        h, t0, t_end = self.settings["h"], request.t0, request.t_end
        t, y = t0, np.array(request.y0, dtype=float)
        fy = f(t, y)
        sections = [float(s.value(t, y)) for s in request.sections]
        dense, hits, steps, n_done = [], [], 0, 0
        n_steps = max(1, math.ceil((t_end - t0) / h - 1e-9))
        while steps < n_steps:
            if steps >= request.max_steps:
                return self._result(
                    t,
                    y,
                    None,
                    dense,
                    n,
                    hits,
                    steps,
                    counts,
                    Status.BUDGET_EXHAUSTED,
                    f"step budget exhausted at t = {t:.6g}",
                )
            t1 = t_end if steps + 1 == n_steps else t0 + (steps + 1) * h
            y1 = heun_step(f, t, y, t1 - t, fy)
            steps += 1
            if not np.all(np.isfinite(y1)):
                return self._result(
                    t,
                    y,
                    None,
                    dense,
                    n,
                    hits,
                    steps,
                    counts,
                    Status.INTEGRATOR_FAILURE,
                    f"non-finite state after t = {t:.6g}",
                )
            crossed = [(q, g) for q, g in enumerate(request.guards) if g.expected_sign * float(g.value(t1, y1)) <= 0.0]
            t_stop, fired, y_stop = t1, None, y1
            for q, g in crossed:  # earliest crossing; ties go to the lowest index
                signed = lambda tt, yy, g=g: g.expected_sign * float(g.value(tt, yy))  # noqa: E731
                tq, yq = self._bisect(f, t, y, fy, t1, signed, counts)
                if fired is None or tq < t_stop:
                    t_stop, fired, y_stop = tq, q, yq
            f_stop = f(t_stop, y_stop)
            self._record_sections(f, request, sections, t, y, fy, t_stop, y_stop, hits, counts)
            n_done = self._dense(request.t_eval, n_done, t, y, fy, t_stop, y_stop, f_stop, dense)
            t, y, fy = t_stop, y_stop, f_stop
            if fired is not None:
                return self._result(t, y, fired, dense, n, hits, steps, counts, Status.SUCCESS, "")
        return self._result(t_end, y, None, dense, n, hits, steps, counts, Status.SUCCESS, "")

    @staticmethod
    def _bisect(f, t, y, fy, t1, phi, counts, iterations=60):
        """First time in ``(t, t1]`` where ``phi`` (positive at ``t``'s side) reaches 0, by bisection."""
        counts["bisections"] += 1
        lo, hi = t, t1
        y_hi = heun_step(f, t, y, t1 - t, fy)
        for _ in range(iterations):
            mid = 0.5 * (lo + hi)
            if not lo < mid < hi:
                break
            y_mid = heun_step(f, t, y, mid - t, fy)
            if phi(mid, y_mid) > 0.0:
                lo = mid
            else:
                hi, y_hi = mid, y_mid
        return hi, y_hi

    def _record_sections(self, f, request, values, ta, ya, fa, tb, yb, hits, counts) -> None:
        for k, sec in enumerate(request.sections):
            vb = float(sec.value(tb, yb))
            if sec.crossed(values[k], vb):
                sign = 1.0 if values[k] > 0 else -1.0
                th, yh = (
                    (tb, yb)
                    if vb == 0.0
                    else self._bisect(f, ta, ya, fa, tb, lambda tt, yy: sign * float(sec.value(tt, yy)), counts)
                )
                hits.append(SectionHit(k, th, np.array(yh)))
            values[k] = vb

    @staticmethod
    def _dense(t_eval, n_done, ta, ya, fa, tb, yb, fb, dense) -> int:
        """Cubic Hermite interpolation between step ends (more than order 2 needs)."""
        n_new = int(np.searchsorted(t_eval, tb, side="right"))
        if n_new > n_done:
            s = (t_eval[n_done:n_new] - ta) / (tb - ta) if tb > ta else np.ones(n_new - n_done)
            h = tb - ta
            h00, h10 = (1 + 2 * s) * (1 - s) ** 2, s * (1 - s) ** 2
            h01, h11 = s * s * (3 - 2 * s), s * s * (s - 1)
            dense.append(np.outer(ya, h00) + h * np.outer(fa, h10) + np.outer(yb, h01) + h * np.outer(fb, h11))
        return max(n_done, n_new)

    @staticmethod
    def _result(t, y, fired, dense, n, hits, steps, counts, status, message) -> ArcResult:
        return ArcResult(
            t=float(t),
            y=np.array(y, dtype=float),
            fired=fired,
            y_eval=np.hstack(dense) if dense else np.empty((n, 0)),
            section_hits=sorted(hits, key=lambda hit: hit.t),
            nfev=counts["nfev"],
            nsteps=steps,
            extra={"bisections": counts["bisections"]},
            status=status,
            message=message,
        )
