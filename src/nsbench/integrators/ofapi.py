"""``ofapi`` and ``mcpi``: Chebyshev-Gauss-Lobatto collocation with (feedback-accelerated) Picard iteration.

Each segment of a frozen-mode arc is a degree-``N`` Chebyshev interpolant on
CGL nodes, converged by the Picard iteration with the optimal-feedback term of
Wang & Atluri (``order`` 1, the paper's form; 2 adds the next Taylor term of the
Lagrange multiplier; 0 is plain Picard-Chebyshev, registered as ``mcpi``).
Guards are located on the converged interpolant (node signs against the
expected sign, a derivative sign-change check for tangential touches, Newton
with a kept bracket). The hot path is compiled (:mod:`._picard_arc`).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from nsbench.errors import ConfigError
from nsbench.integrators.base import ArcRequest, ArcResult, Capabilities, Integrator, Option, SectionHit
from nsbench.results import Status

#: A segment halved or shrunk below ``h * MIN_FRACTION`` is a failure.
MIN_FRACTION = 2.0**-24
#: Default cap of the adaptive segment length, as a multiple of ``h``.
H_MAX_FACTOR = 8.0
_WARM: list[bool] = []  # whether the compiled kernels were loaded in this process


def _options(feedback: bool) -> dict[str, Option]:
    """Options of ``ofapi`` (``feedback``) or ``mcpi``; defaults as measured in the README."""
    opts: dict[str, Option] = {}
    if feedback:
        opts["order"] = Option(1, int, choices=(0, 1, 2),
                               doc="feedback order: 0 Picard (MCPI), 1 the paper's OFAPI, 2 second order")
        opts["jacobian"] = Option("node", str, choices=("node", "segment_start"),
                                  doc="feedback Jacobian at each node's iterate, or once per segment")
    else:
        opts["order"] = Option(0, int, choices=(0,), doc="always 0, plain Picard (ofapi has the feedback)")
    opts.update({
        "N": Option(12, int, lower=2, lower_inclusive=True, upper=64,
                    doc="Chebyshev degree (N + 1 Gauss-Lobatto nodes per segment)"),
        "h": Option(0.5, float, lower=0.0, doc="segment length (time units); the start value when adaptive"),
        # The increment left at the stop is ~ r tol, with r the last contraction ratio (~1e-3 for
        # order 1, ~0.1 for order 0); 1e-12 let event times drift by 1.6e-11 over tau = 300 (case 1).
        "tol": Option(1e-14 if feedback else 1e-15, float, lower=0.0, upper=1e-2,
                      doc="iteration stop: max|X_new - X| <= tol max(1, max|X|), or stalled at round-off"),
        "max_iter": Option(50, int, lower=1, lower_inclusive=True, upper=10_000,
                           doc="iterations per segment before it is halved"),
        "adaptive": Option(True, bool, doc="adapt the segment length to the trailing Chebyshev coefficients"),
        "coef_tol": Option(1e-13, float, lower=0.0, upper=1e-2,
                           doc="adaptive target of the two trailing Chebyshev coefficients (relative)"),
        "h_max": Option(None, float, lower=0.0, nullable=True,
                        doc=f"largest adaptive segment length; None: {H_MAX_FACTOR:g} h"),
    })
    return opts


class ChebyshevPicard(Integrator):
    """Shared machinery of ``ofapi`` and ``mcpi`` (see the module docstring)."""

    def check_settings(self) -> None:
        s = self.settings
        if s["h_max"] is not None and s["h_max"] < s["h"]:
            raise ConfigError(f"{self.name}: option h_max = {s['h_max']!r} must be >= h = {s['h']!r}")

    def setup(self, problem) -> None:
        """Build (or fetch) the operators of degree ``N`` and load the compiled kernels."""
        super().setup(problem)
        from nsbench.integrators import _chebyshev
        from nsbench.problems import kernels

        ops = _chebyshev.operators(self.settings["N"])
        # writable copies: the same numba specialisation for every call
        self._ops = (ops.nodes.copy(), ops.weights.copy(), ops.integration.copy(),
                     ops.to_coefficients.copy())
        self._packed = kernels.pack(problem)
        self._problem = problem
        self._modes: dict[Any, tuple] = {}
        if not _WARM:  # compile or load the kernels here, so that setup_time holds that cost
            mode = problem.modes[0]
            self._run(problem, mode, problem.guards(mode), 0.0, problem.initial_state(), 1e-3, (),
                      np.empty(0), 10)
            _WARM.append(True)

    def advance(self, request: ArcRequest) -> ArcResult:
        from nsbench.integrators import _picard_arc as arc

        if getattr(self, "_problem", None) is not request.problem:
            self.setup(request.problem)
        out = self._run(request.problem, request.mode, request.guards, request.t0, request.y0,
                        request.t_end, request.sections, request.t_eval, request.max_steps)
        code, t, y, fired, y_eval, n_eval, hit_index, hit_t, hit_y, n_hits, counts = out
        hits = [SectionHit(int(hit_index[k]), float(hit_t[k]), hit_y[k].copy()) for k in range(n_hits)]
        hits.sort(key=lambda hit: hit.t)
        status, message = self._status(int(code), float(t))
        return ArcResult(
            t=float(t), y=np.array(y), fired=None if fired < 0 else int(fired),
            y_eval=y_eval[:, :n_eval], section_hits=hits,
            nfev=int(counts[arc.NFEV]), njev=int(counts[arc.NJEV]), nsteps=int(counts[arc.NSTEPS]),
            extra={"iterations": int(counts[arc.ITERATIONS]), "segments": int(counts[arc.SEGMENTS]),
                   "halvings": int(counts[arc.HALVINGS]), "rejections": int(counts[arc.REJECTIONS])},
            status=status, message=message,
        )

    def _run(self, problem, mode, guards, t0, y0, t_end, sections, t_eval, max_steps) -> tuple:
        """Call the compiled arc kernel (argument types fixed here, for one specialisation)."""
        from nsbench.integrators import _picard_arc as arc
        from nsbench.problems import kernels

        key = (mode, tuple((g.kind, g.block, g.expected_sign) for g in guards))
        codes = self._modes.get(key)
        if codes is None:
            codes = self._modes[key] = (kernels.mode_array(mode), *kernels.guard_codes(guards))
        n = problem.n_states
        sec_coeffs = np.array([sec.coeffs for sec in sections], dtype=float).reshape(len(sections), n)
        sec_levels = np.array([sec.level for sec in sections], dtype=float)
        sec_dirs = np.array([sec.direction for sec in sections], dtype=np.int64)
        s = self.settings
        h = float(s["h"])
        h_max = float(s["h_max"]) if s["h_max"] is not None else H_MAX_FACTOR * h
        return arc.advance_arc(
            self._packed, *codes, sec_coeffs, sec_levels, sec_dirs, float(t0),
            np.array(y0, dtype=float), float(t_end), np.array(t_eval, dtype=float),
            int(min(max_steps, 2**62)), *self._ops, h, h_max, h * MIN_FRACTION, float(s["tol"]),
            float(s["coef_tol"]), int(s["max_iter"]), int(s["order"]),
            s.get("jacobian", "node") == "node", bool(s["adaptive"]),
        )

    def _status(self, code: int, t: float) -> tuple[Status, str]:
        from nsbench.integrators import _picard_arc as arc

        s = self.settings
        floor = s["h"] * MIN_FRACTION
        if code == arc.SUCCESS:
            return Status.SUCCESS, ""
        if code == arc.BUDGET_EXHAUSTED:
            return Status.BUDGET_EXHAUSTED, f"step budget exhausted at t = {t:.6g}"
        if code == arc.NOT_CONVERGED:
            return Status.INTEGRATOR_FAILURE, (
                f"{self.name}: the Picard iteration did not converge to tol = {s['tol']:g} within "
                f"max_iter = {s['max_iter']} on a segment from t = {t:.17g}, even halved below {floor:.3g}")
        return Status.INTEGRATOR_FAILURE, (
            f"{self.name}: the trailing Chebyshev coefficients stay above coef_tol = {s['coef_tol']:g} "
            f"on segments from t = {t:.17g} shorter than {floor:.3g} (raise N or coef_tol)")


def _caps(needs_jacobian: bool) -> Capabilities:
    # spectral (no fixed order); the accuracy knob of a convergence study is tol
    return Capabilities(event_location="collocation-newton", order=None, adaptive=True,
                        needs_jacobian=needs_jacobian, supports_nonlinear=True, precision="double",
                        step_option="tol")


class OFAPI(ChebyshevPicard):
    """Optimal-feedback accelerated Picard iteration on CGL collocation segments (Wang & Atluri)."""

    name = "ofapi"
    capabilities = _caps(True)
    options = _options(True)
    # measured max event-time errors (1-DOF case 1, 2-DOF cases 1-2, tau 300): ~5e-9, ~2e-10, ~4e-13
    accuracy_levels = ({"N": 8, "tol": 1e-9, "coef_tol": 1e-8},
                       {"N": 10, "tol": 1e-11, "coef_tol": 1e-10},
                       {"N": 12, "tol": 1e-14, "coef_tol": 1e-13})


class MCPI(ChebyshevPicard):
    """Modified Chebyshev-Picard iteration: the same segments and event location, no feedback."""

    name = "mcpi"
    capabilities = _caps(False)
    options = _options(False)
    # measured as for ofapi: ~2e-9, ~2e-11, ~5e-13
    accuracy_levels = ({"N": 8, "tol": 1e-10, "coef_tol": 1e-8},
                       {"N": 10, "tol": 1e-13, "coef_tol": 1e-10},
                       {"N": 12, "tol": 1e-15, "coef_tol": 1e-13})


def iterate_segment(problem, mode, t_a: float, y_a, h: float, *, N: int = 12, order: int = 1,
                    jacobian: str = "node", tol: float = 1e-13, max_iter: int = 50,
                    guess: np.ndarray | None = None) -> tuple[np.ndarray, bool, int]:
    """Run the iteration of one segment ``[t_a, t_a + h]`` (for tests and studies).

    Parameters
    ----------
    problem, mode
        The problem and the frozen mode.
    t_a, y_a, h
        Segment start, initial state and length.
    N, order, jacobian, tol, max_iter
        As the integrator options (``tol = 0`` runs exactly ``max_iter`` iterations).
    guess
        Initial node values ``(N + 1, n)``; default the linear predictor
        ``y_a + (t_j - t_a) g(y_a, t_a)``. Row 0 is replaced by ``y_a``.

    Returns
    -------
    (X, converged, iterations)
        Node values of the last iterate at the nodes ``t_a + (h/2)(tau_j + 1)``.
    """
    from nsbench.integrators import _chebyshev, _picard_iteration
    from nsbench.problems import kernels

    ops = _chebyshev.operators(N)
    p = kernels.pack(problem)
    m_arr = kernels.mode_array(mode)
    y_a = np.array(y_a, dtype=float)
    n = y_a.size
    w = 0.5 * h
    g0 = np.empty(n)
    kernels.rhs(p, m_arr, float(t_a), y_a, g0)
    if guess is None:
        D = (w * (ops.nodes + 1.0))[:, None] * g0[None, :]
    else:
        D = np.array(guess, dtype=float).reshape(N + 1, n) - y_a[None, :]
    D[0] = 0.0
    G = np.empty_like(D)
    G[0] = g0
    X, P, Y, Z = (np.empty_like(D) for _ in range(4))
    J = np.empty((N + 1, n, n))
    code, its, _, _ = _picard_iteration.picard_iterations(
        p, m_arr, float(t_a), y_a, w, ops.nodes.copy(), ops.integration.copy(), D, X, G, J, P, Y, Z,
        order, jacobian == "node", tol, max_iter)
    return X, code == _picard_iteration.CONVERGED, int(its)
