"""``heyoka``, ``heyoka-ld``, ``heyoka-q``: heyoka's adaptive Taylor method in double, long double and quad.

One ``taylor_adaptive`` is compiled per problem structure in :meth:`setup`
(see :mod:`nsbench.integrators._heyoka_model`); an arc sets the mode, the
coefficients and the sections as runtime parameters, the time and the state in
the integrator's own precision, and propagates to ``t_end``. Guards are
terminal events located by heyoka on the Taylor polynomial of each step
(direction "decreasing", so a phase that starts on its own surface does not
stop at once); sections are non-terminal events; trajectory points come from
heyoka's continuous output. Times and states cross the protocol as doubles.

Counters: ``nsteps`` Taylor steps; ``nfev`` counts one Taylor jet (all
coefficients up to the order, about ``order`` field evaluations' worth of
work) per step, and ``extra['taylor_coefficients']`` the jets times the order.
Compilation happens in :meth:`setup` (two section slots); a request with more
sections compiles a wider model once, reported in ``extra['compile_seconds']``.
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np

from nsbench.errors import ConfigError
from nsbench.integrators import _heyoka_model as model
from nsbench.integrators.base import ArcRequest, ArcResult, Capabilities, Integrator, Option, SectionHit
from nsbench.problems.modes import STICK
from nsbench.results import Status

_SECTION_SLOTS = 2  # compiled in setup(); a request with more sections compiles a wider model


def _caps(precision: str) -> Capabilities:
    return Capabilities(event_location="taylor-root", order=None, adaptive=True,
                        needs_jacobian=False, supports_nonlinear=True, precision=precision,
                        step_option="tol")


def _illinois(f, a, fa, b, fb, iterations: int = 100):
    """Root of ``f`` in ``[a, b]`` with ``fa > 0 >= fb`` (Illinois regula falsi), in ``a``'s precision."""
    side = 0
    for _ in range(iterations):
        c = (a * fb - b * fa) / (fb - fa)
        if not (a < c < b) or fb == 0:
            break
        fc = f(c)
        if fc > 0:
            a, fa = c, fc
            if side == 1:
                fb = fb / 2
            side = 1
        else:
            b, fb = c, fc
            if side == -1:
                fa = fa / 2
            side = -1
    return b


class HeyokaIntegrator(Integrator):
    """Base of the heyoka adapters; subclasses set the precision."""

    precision: ClassVar[str] = "double"
    options = {
        "tol": Option(None, float, lower=0.0, upper=1e-2, nullable=True,
                      doc="Taylor tolerance (relative and absolute); None: the precision's epsilon"),
        "high_accuracy": Option(False, bool, doc="heyoka's compensated summation for long runs"),
        "compact_mode": Option(None, bool, nullable=True,
                               doc="compile in compact mode; None: only for quad precision"),
    }
    accuracy_levels = ({"tol": 1e-6}, {"tol": 1e-10}, {"tol": 1e-14})

    def setup(self, problem) -> None:
        super().setup(problem)
        self._problem = problem
        self._models: dict[int, Any] = {}
        self._fp = model.FP_TYPES.get(self.precision)
        if self._fp is None:  # pragma: no cover - depends on the heyoka build
            raise ConfigError(f"{self.name}: this heyoka build has no {self.precision} type")
        self._coefficients = np.array(model.coefficient_values(problem), dtype=float)
        self.compile_time = 0.0
        self._model(_SECTION_SLOTS)
        self._compiled_in_advance = 0.0

    def _model(self, n_sections: int):
        """The compiled integrator with at least ``n_sections`` section slots."""
        usable = [n for n in self._models if n >= n_sections]
        if usable:
            return self._models[min(usable)]
        compact = self.settings["compact_mode"]
        if compact is None:
            compact = self.precision == "quad"
        st = model.Structure.of(self._problem, max(n_sections, _SECTION_SLOTS))
        ta, seconds = model.compiled(st, self.precision, self.settings["tol"],
                                     self.settings["high_accuracy"], compact)
        self.compile_time += seconds  # setup's share lands in setup_time; later ones in extra
        self._compiled_in_advance = getattr(self, "_compiled_in_advance", 0.0) + seconds
        self._models[st.n_sections] = (st, ta)
        return self._models[st.n_sections]

    def _load(self, st: model.Structure, ta, request: ArcRequest):
        """Write coefficients, mode, sections, time and state into ``ta``; return the start time."""
        fp = self._fp
        pars = np.zeros(st.n_pars)
        pars[: self._coefficients.size] = self._coefficients
        nb = st.n_blocks
        for i, phase in enumerate(request.mode):
            pars[st.mode_offset + i] = 1.0 if phase == STICK else 0.0
            pars[st.mode_offset + nb + i] = float(phase)
        for guard in request.guards:
            off = st.guard_offset + 2 * (3 * (guard.block - 1) + model.GUARD_SLOT[guard.kind])
            pars[off], pars[off + 1] = 1.0, float(guard.expected_sign)
        for q, sec in enumerate(request.sections):
            off = st.section_offset(q)
            pars[off], pars[off + 1] = 1.0, sec.level
            pars[off + 2: off + 2 + st.n_mech] = sec.coeffs
        ta.pars[:] = pars.astype(fp)
        state = np.asarray(request.y0, dtype=float).astype(fp)
        # heyoka keeps time as a double-length number: the start t0 + t0_lo is exact.
        ta.dtime = (fp(request.t0), fp(request.t0_lo))
        t0 = ta.time
        if st.forced:
            w = np.array([pars[6 * nb + 1]], dtype=float).astype(fp)
            phase = w * (fp(request.t0) + fp(request.t0_lo))
            state = np.concatenate([state, np.cos(phase), np.sin(phase)])
        ta.state[:] = state
        ta.reset_cooldowns()
        for ev in ta.nt_events:
            ev.callback.hits.clear()
        return t0

    def advance(self, request: ArcRequest) -> ArcResult:
        problem = request.problem
        if getattr(self, "_problem", None) is not problem:
            self.setup(problem)
        st, ta = self._model(len(request.sections))
        t0 = self._load(st, ta, request)
        fp = self._fp
        n = problem.n_states
        if request.max_steps <= 0:
            return ArcResult(t=request.t0, y=np.array(request.y0, dtype=float), fired=None,
                             y_eval=np.empty((n, 0)), status=Status.BUDGET_EXHAUSTED,
                             message=f"step budget exhausted at t = {request.t0:.6g}")
        want_dense = request.t_eval.size > 0
        dense_rows: list[np.ndarray] = []
        nsteps, fresh_hit, c_out = 0, None, None
        fresh = self._fresh_guards(request)
        if fresh:
            outcome, fresh_hit = self._first_step(st, ta, request, fresh, dense_rows)
            nsteps = 1
        if fresh_hit is None and (not fresh or outcome == model.hy.taylor_outcome.success):
            if nsteps >= request.max_steps:  # heyoka reads max_steps=0 as "no limit"
                outcome = model.hy.taylor_outcome.step_limit
            else:
                outcome, _, _, taken, c_out, _ = ta.propagate_until(
                    fp(request.t_end), max_steps=int(request.max_steps) - nsteps, c_output=want_dense)
                nsteps += taken
        if fresh_hit is not None:  # a fresh guard crossed inside the first step
            t_fp, q, y_fp = fresh_hit
            hi, lo = t_fp, fp(0.0)
        else:
            hi, lo = ta.dtime
            y_fp = ta.state
        t_stop = float(hi)
        t_lo = float((hi - fp(t_stop)) + lo)
        y_stop = np.asarray(y_fp[:n]).astype(float)
        counts = dict(nfev=int(nsteps), njev=0, nsteps=int(nsteps),
                      extra={"taylor_coefficients": int(nsteps) * int(ta.order)})
        if self._compiled_in_advance:  # a wider model compiled for more sections
            counts["extra"]["compile_seconds"] = self._compiled_in_advance
            self._compiled_in_advance = 0.0
        fired, status, message, t_lo = None, Status.SUCCESS, "", t_lo
        code = int(outcome)
        if fresh_hit is not None:
            fired = fresh_hit[1]
        elif outcome == model.hy.taylor_outcome.time_limit:
            t_stop, t_lo = request.t_end, 0.0
        elif outcome == model.hy.taylor_outcome.step_limit:
            status, message = Status.BUDGET_EXHAUSTED, f"step budget exhausted at t = {t_stop:.6g}"
        elif outcome == model.hy.taylor_outcome.err_nf_state:
            status, message = Status.INTEGRATOR_FAILURE, f"non-finite state at t = {t_stop:.6g}"
        elif code < 0 and -code - 1 < len(ta.t_events):
            fired = self._guard_index(request, -code - 1)
            if fired is None:
                status, message = Status.INTEGRATOR_FAILURE, (
                    f"event {-code - 1} of an inactive phase fired at t = {t_stop:.17g}")
        else:
            status, message = Status.INTEGRATOR_FAILURE, f"unexpected heyoka outcome {outcome!r}"
        hits = self._section_hits(ta, request, t0, hi)
        n_eval = int(np.searchsorted(request.t_eval, t_stop, side="right")) if status.ok else 0
        rows = [row for row in dense_rows[:n_eval]]
        if len(rows) < n_eval and c_out is not None:
            times = np.asarray(request.t_eval[len(rows):n_eval], dtype=float).astype(fp)
            rows += list(np.asarray(c_out(times)).reshape(times.size, -1))
        rows += [y_fp] * (n_eval - len(rows))  # no step was taken
        y_eval = (np.array([np.asarray(r[:n]).astype(float) for r in rows]).T if rows
                  else np.empty((n, 0)))
        return ArcResult(t=t_stop, y=y_stop, fired=fired, y_eval=y_eval, section_hits=hits,
                         status=status, message=message, t_lo=t_lo, **counts)

    @staticmethod
    def _fresh_guards(request: ArcRequest) -> list[int]:
        """Guards exactly zero at the start: the phase starts on its own surface."""
        return [q for q, g in enumerate(request.guards)
                if g.expected_sign * float(g.value(request.t0, request.y0)) == 0.0]

    def _first_step(self, st, ta, request: ArcRequest, fresh: list[int], dense_rows: list):
        """One Taylor step with the fresh guards' events off; their crossings found on its polynomial.

        heyoka does not look for the roots of an event function that is zero
        where a step starts, so the first step of a phase that starts on its own
        surface would miss that surface's next crossing if the step reached it
        (quad precision takes long steps). After this step the guard is off its
        surface and heyoka's own detection takes over. Returns heyoka's outcome
        and ``(t, guard index, state)`` of the earliest fresh crossing, if any.
        """
        fp = self._fp
        offsets = [st.guard_offset + 2 * (3 * (request.guards[q].block - 1)
                                          + model.GUARD_SLOT[request.guards[q].kind]) for q in fresh]
        for off in offsets:
            ta.pars[off] = fp(0.0)
        t_start = ta.time
        outcome, _ = ta.step(fp(request.t_end) - t_start)
        t_end = ta.time
        for te in request.t_eval[int(np.searchsorted(request.t_eval, float(t_start), side="right")):]:
            if fp(float(te)) > t_end:
                break
            dense_rows.append(np.array(ta.update_d_output(fp(float(te))), copy=True))
        best = None
        for q in fresh:
            root = self._first_crossing(ta, request.guards[q], t_start, t_end)
            if root is not None and (best is None or root < best[0]):
                best = (root, q, np.array(ta.update_d_output(root), copy=True))
        for off in offsets:
            ta.pars[off] = fp(1.0)
        return outcome, best

    def _first_crossing(self, ta, guard, t_start, t_end):
        """First zero of ``expected_sign * guard`` in ``(t_start, t_end]`` after it turned positive."""
        fp = self._fp
        problem = guard.problem
        sign = guard.expected_sign

        def value(t):
            y = ta.update_d_output(t)
            if guard.kind == "velocity":  # in the integrator's own precision
                return fp(sign) * (y[2 * guard.block - 1] - fp(problem.v0))
            return fp(sign * float(guard.value(float(t), np.asarray(y[: problem.n_states]).astype(float))))

        lo, g_lo, positive = t_start, fp(0.0), False
        for k in range(1, 33):
            t = t_start + (t_end - t_start) * fp(k) / fp(32)
            g = value(t)
            if g > 0:
                lo, g_lo, positive = t, g, True
            elif positive:
                return _illinois(value, lo, g_lo, t, g)
        return None if positive or value(t_end) > 0 else t_start  # never off its surface: at once

    @staticmethod
    def _guard_index(request: ArcRequest, event: int) -> int | None:
        block, slot = divmod(event, 3)
        for q, guard in enumerate(request.guards):
            if guard.block == block + 1 and model.GUARD_SLOT[guard.kind] == slot:
                return q
        return None

    @staticmethod
    def _section_hits(ta, request: ArcRequest, t0, t_stop) -> list[SectionHit]:
        n = request.problem.n_states
        hits = []
        for ev in ta.nt_events:
            for slot, t, d_sgn, y in ev.callback.hits:
                if slot >= len(request.sections) or not (t0 < t <= t_stop) or d_sgn == 0:
                    continue  # starting on a section is not a crossing; touches are not either
                direction = request.sections[slot].direction
                if direction == 0 or direction == d_sgn:
                    hits.append(SectionHit(slot, float(t), np.asarray(y[:n]).astype(float)))
        hits.sort(key=lambda h: h.t)
        return hits


class Heyoka(HeyokaIntegrator):
    """heyoka's Taylor method in double precision, guards as terminal events."""

    name = "heyoka"
    precision = "double"
    capabilities = _caps("double")


class HeyokaLongDouble(HeyokaIntegrator):
    """heyoka's Taylor method in extended (80-bit long double) precision."""

    name = "heyoka-ld"
    precision = "long double"
    capabilities = _caps("long double")


class HeyokaQuad(HeyokaIntegrator):
    """heyoka's Taylor method in quadruple (real128) precision."""

    name = "heyoka-q"
    precision = "quad"
    capabilities = _caps("quad")
    accuracy_levels = ({"tol": 1e-10}, {"tol": 1e-20}, {"tol": 1e-30})

