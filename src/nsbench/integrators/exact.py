"""``exact``: the closed-form flow of each mode of a linear problem, the reference.

With ``h = 0`` every mode is affine with constant, linear-in-time (a stuck
neighbour moving with the belt) and harmonic forcing (MODEL.md section 5).
Stuck blocks move as ``x = x0 + v0 s``; the slipping blocks obey
``u' = A u + forcing`` and are solved as a particular solution (polynomial plus
harmonic) plus ``V exp(Lambda s) V^-1`` times the initial offset. The flow is
evaluated directly at any ``s`` from the arc's start, never chained step by
step, so no error accumulates inside an arc (``scipy.linalg.expm`` chained over
many periods drifts by ~1e-13 per period, MODEL.md section 6). Guards are
bracketed by a scan at a fraction of the shortest time scale, with the
derivative's sign change catching tangential touches, and refined by Brent's
method to a few ulps. The root that ends the arc is then polished by Newton's
method in extended precision on the augmented flow ``expm(M s) z0`` (long
double; a scaled Taylor series), and returned with the state there and the
event time in compensated form (``ArcResult.t_lo``): double-precision flow
errors of a few ulps per arc, amplified by the stick durations (``1/v0``),
otherwise add up to ~2e-13 by ``tau = 300`` in the unforced 2-DOF case. If a
mode is defective or resonant (critical damping, undamped resonance) its flow
falls back to the matrix exponential of the augmented system.
"""

from __future__ import annotations

import math

import numpy as np
import scipy.linalg

from nsbench.integrators._extended import EXTENDED, expm_extended, guard_row, two_sum
from nsbench.integrators._roots import bracketed_root, first_zero
from nsbench.integrators.base import ArcRequest, ArcResult, Capabilities, Integrator, Option, SectionHit
from nsbench.problems.modes import STICK, Mode
from nsbench.problems.oscillator import FrictionOscillator

_CHUNK = 64  # samples evaluated per vectorised scan


class ModeFlow:
    """Closed-form solution of one mode of a linear friction oscillator."""

    def __init__(self, problem: FrictionOscillator, mode: Mode, max_condition: float = 1e4) -> None:
        self.problem = problem
        self.mode = mode
        a, b0, bc, bs = problem.linear_form(mode)
        n = problem.n_states
        self.n = n
        self.w = problem.coefficients.w
        self.v0 = problem.v0
        self.forced = problem.is_forced and self.w != 0.0
        if problem.is_forced and self.w == 0.0:
            b0 = b0 + bc  # cos(0 t) = 1: a constant force
            bc = np.zeros(n)
        self.a, self.b0, self.bc, self.bs = a, b0, bc, bs
        slip = [j for i, p in enumerate(mode) if p != STICK for j in (2 * i, 2 * i + 1)]
        stuck = [j for i, p in enumerate(mode) if p == STICK for j in (2 * i, 2 * i + 1)]
        self.slip = np.array(slip, dtype=int)
        self.stuck = np.array(stuck, dtype=int)
        self.stuck_x = np.array(stuck[0::2], dtype=int)
        self.rates = [0.0]
        self.use_expm = False
        if slip:
            a_ss = a[np.ix_(slip, slip)]
            self.a_sk = a[np.ix_(slip, stuck)]
            lam, vec = np.linalg.eig(a_ss)
            cond = np.linalg.cond(vec)
            self.lam, self.vec = lam, vec
            self.rates.extend(np.abs(lam))
            ok = math.isfinite(cond) and cond < max_condition
            if ok:
                self.vec_inv = np.linalg.inv(vec)
                self.a_inv = np.linalg.inv(a_ss)
                # slope of the particular solution, from the stuck blocks moving at v0
                c1 = self.a_sk @ b0[stuck] if stuck else np.zeros(len(slip))
                self.p1 = -self.a_inv @ c1
                if self.forced:
                    shifted = 1j * self.w * np.eye(len(slip)) - a_ss
                    if np.linalg.cond(shifted) < 1e8:
                        self.z = np.linalg.solve(shifted, bc[slip] - 1j * bs[slip])
                    else:
                        ok = False
            self.use_expm = not ok
        if self.forced:
            self.rates.append(self.w)
        self._augmented = self._augmented_matrix()
        self.augmented_extended = self._augmented.astype(EXTENDED)

    # -------------------------------------------------------------- set-up per arc
    def start(self, t0: float, y0: np.ndarray, t0_lo: float = 0.0) -> "ArcFlow":
        return ArcFlow(self, t0, y0, t0_lo)

    @property
    def fastest_rate(self) -> float:
        return float(max(self.rates))

    def _augmented_matrix(self) -> np.ndarray:
        n = self.n
        m = np.zeros((n + 3, n + 3))
        m[:n, :n] = self.a
        m[:n, n] = self.b0
        m[:n, n + 1] = self.bc
        m[:n, n + 2] = self.bs
        m[n + 1, n + 2] = -self.w
        m[n + 2, n + 1] = self.w
        return m


class ArcFlow:
    """The flow of one mode from a given start ``(t0, y0)``, evaluated at any offsets ``s``."""

    def __init__(self, mf: ModeFlow, t0: float, y0: np.ndarray, t0_lo: float = 0.0) -> None:
        self.mf = mf
        self.t0 = t0
        self.t0_lo = t0_lo
        self.y0 = np.array(y0, dtype=float)
        phase = mf.w * t0 + mf.w * t0_lo  # the arc starts at t0 + t0_lo
        if mf.use_expm:
            self.z0 = np.concatenate([self.y0, [1.0, math.cos(phase), math.sin(phase)]])
            return
        if mf.slip.size:
            c0 = mf.b0[mf.slip] + (mf.a_sk @ self.y0[mf.stuck] if mf.stuck.size else 0.0)
            self.p0 = mf.a_inv @ (mf.p1 - c0)
            up0 = self.p0.copy()
            if mf.forced:
                # The harmonic part is advanced from the arc start, exp(i w (t0 + s)) =
                # exp(i w t0) exp(i w s), never from the rounded absolute time t0 + s: near
                # resonance |z| >> F and a phase error of one ulp of t costs |z| ulp(t).
                self.zt0 = mf.z * np.exp(1j * phase)
                up0 = up0 + self.zt0.real
            self.coef = mf.vec_inv @ (self.y0[mf.slip] - up0)

    def refine_root(self, row: np.ndarray, s: float) -> tuple[float, float, np.ndarray, int] | None:
        """Polish a guard root ``s`` in extended precision on the augmented flow.

        Newton on ``q . expm(M s) z0`` from the double root. Returns the event
        time as ``(hi, lo)`` with ``hi + lo = t0 + t0_lo + s``, the state there
        and the number of flow evaluations, or ``None`` if Newton is not usable
        (tangency, or it moves far away).
        """
        mf = self.mf
        m = mf.augmented_extended
        phase = EXTENDED(mf.w) * (EXTENDED(self.t0) + EXTENDED(self.t0_lo))
        z0 = np.concatenate([self.y0.astype(EXTENDED), np.array([1.0], dtype=EXTENDED),
                             np.array([np.cos(phase), np.sin(phase)])])
        q = row.astype(EXTENDED)
        s_x = EXTENDED(s)
        evaluations = 1
        for _ in range(4):
            evaluations += 1
            z = expm_extended(m * s_x) @ z0
            rate = q @ (m @ z)
            if not np.isfinite(rate) or rate == 0:
                return None
            step = (q @ z) / rate
            if abs(float(step)) > 1e-9 * max(1.0, abs(s)):
                return None
            s_x = s_x - step
            if abs(step) <= 4 * np.finfo(EXTENDED).eps * abs(s_x):
                break
        z = expm_extended(m * s_x) @ z0
        total = EXTENDED(self.t0) + EXTENDED(self.t0_lo) + s_x
        hi = float(total)
        return hi, float(total - EXTENDED(hi)), z[: mf.n].astype(float), evaluations

    def states(self, s: np.ndarray) -> np.ndarray:
        """States at offsets ``s`` (shape ``(k,)``) from the arc start: shape ``(n, k)``."""
        mf = self.mf
        s = np.asarray(s, dtype=float)
        if mf.use_expm:
            out = np.empty((mf.n, s.size))
            for j, sj in enumerate(s):
                out[:, j] = self.y0 if sj == 0.0 else (scipy.linalg.expm(mf._augmented * sj) @ self.z0)[: mf.n]
            return out
        out = np.empty((mf.n, s.size))
        if mf.stuck.size:
            out[mf.stuck_x] = self.y0[mf.stuck_x, None] + mf.v0 * s
            out[mf.stuck_x + 1] = mf.v0
        if mf.slip.size:
            u = self.p0[:, None] + mf.p1[:, None] * s
            if mf.forced:
                u = u + (self.zt0[:, None] * np.exp(1j * mf.w * s)).real
            u = u + (mf.vec @ (self.coef[:, None] * np.exp(mf.lam[:, None] * s))).real
            out[mf.slip] = u
        # The arc starts exactly at y0: a phase that starts on its own surface must
        # see its guard exactly zero there, not the closed form's few-ulp offset
        # (with a rate at rounding level that offset reads as a crossing).
        out[:, s == 0.0] = self.y0[:, None]
        return out


class ExactIntegrator(Integrator):
    """Exact event times for linear problems: closed-form flow plus bracketing root finding."""

    name = "exact"
    capabilities = Capabilities(
        event_location="exact-root", order=None, adaptive=False, needs_jacobian=False,
        supports_nonlinear=False, precision="double", step_option=None,
    )
    options = {
        "scan": Option(0.25, float, lower=0.0, upper=1.0,
                       doc="scan step as a fraction of the shortest time scale of the mode"),
        "max_scan": Option(1.0, float, lower=0.0, doc="longest scan step (time units)"),
    }

    def setup(self, problem: FrictionOscillator) -> None:
        super().setup(problem)
        self._problem = problem
        self._flows = {mode: ModeFlow(problem, mode) for mode in problem.modes}

    def _flow(self, problem: FrictionOscillator, mode: Mode) -> ModeFlow:
        if getattr(self, "_problem", None) is not problem:
            self.setup(problem)
        return self._flows[mode]

    def advance(self, request: ArcRequest) -> ArcResult:
        problem, mode = request.problem, request.mode
        mf = self._flow(problem, mode)
        t0, t0_lo = request.t0, request.t0_lo
        flow = mf.start(t0, request.y0, t0_lo)
        # Offsets s are measured from the exact start t0 + t0_lo; absolute times
        # t0 + s (rounded) only feed the forcing term of the guards.
        span = (request.t_end - t0) - t0_lo
        ds = min(self.settings["max_scan"], self.settings["scan"] / max(mf.fastest_rate, 1e-300))
        guards = request.guards
        sections = request.sections
        counts = {"nfev": 0, "nsteps": 0, "roots": 0}

        def state(s: float) -> np.ndarray:
            counts["nfev"] += 1
            return flow.states(np.array([s]))[:, 0]

        def signed(fn, sign):
            def phi(s: float) -> float:
                t = t0 + s
                return sign * float(fn.value(t, state(s)))

            def psi(s: float) -> float:
                t = t0 + s
                y = state(s)
                return sign * float(fn.rate(t, y, problem.rhs(mode, t, y)))
            return phi, psi

        hits: list[SectionHit] = []
        s_a = 0.0
        fired, s_stop = None, span
        while s_a < span:
            s = s_a + ds * np.arange(_CHUNK + 1)
            s = s[s < span]
            s = np.append(s, span) if s[-1] < span and s.size <= _CHUNK else s
            y = flow.states(s)
            t = t0 + s
            dy = problem.rhs(mode, t, y)
            counts["nfev"] += s.size
            counts["nsteps"] += s.size - 1
            best = None
            for q, guard in enumerate(guards):
                phi = guard.expected_sign * np.asarray(guard.value(t, y), dtype=float)
                psi = guard.expected_sign * np.asarray(guard.rate(t, y, dy), dtype=float)
                f, fp = signed(guard, guard.expected_sign)
                for j in range(s.size - 1):
                    if best is not None and s[j] >= best[0]:
                        break
                    hit = first_zero(f, fp, float(s[j]), float(s[j + 1]), float(phi[j]),
                                     float(phi[j + 1]), float(psi[j]), float(psi[j + 1]),
                                     start=(j == 0 and s_a == 0.0))
                    if hit is not None:
                        counts["roots"] += 1
                        if best is None or hit < best[0]:
                            best = (hit, q)
                        break
            end = best[0] if best is not None else float(s[-1])
            for k, sec in enumerate(sections):
                val = np.asarray(sec.value(t, y), dtype=float)
                f, _ = signed(sec, 1.0)
                for j in range(s.size - 1):
                    if s[j] >= end:
                        break
                    right = min(float(s[j + 1]), end)
                    v_right = float(val[j + 1]) if right == s[j + 1] else f(right)
                    if sec.crossed(float(val[j]), v_right):
                        root = float(s[j + 1]) if v_right == 0.0 else bracketed_root(f, float(s[j]), right)
                        hits.append(SectionHit(k, t0 + (t0_lo + root), state(root)))
            if best is not None:
                fired, s_stop = best[1], best[0]
                break
            s_a = float(s[-1])
        hits.sort(key=lambda h: h.t)
        polished = None
        if fired is not None:
            polished = flow.refine_root(guard_row(problem, guards[fired]), s_stop)
        if polished is not None:
            t_stop, t_lo, y_stop, evaluations = polished
            counts["nfev"] += evaluations
        elif fired is not None:
            t_stop, t_lo = two_sum(t0, t0_lo + s_stop)
            y_stop = state(s_stop)
        else:
            t_stop, t_lo = request.t_end, 0.0
            y_stop = state(s_stop)
        n_eval = int(np.searchsorted(request.t_eval, t_stop, side="right"))
        y_eval = (flow.states((request.t_eval[:n_eval] - t0) - t0_lo) if n_eval
                  else np.empty((problem.n_states, 0)))
        counts["nfev"] += n_eval
        return ArcResult(
            t=t_stop, y=y_stop, fired=fired, y_eval=y_eval, section_hits=hits,
            nfev=counts["nfev"], njev=0, nsteps=counts["nsteps"],
            extra={"roots": counts["roots"], "expm_fallback_arcs": int(mf.use_expm)}, t_lo=t_lo,
        )

