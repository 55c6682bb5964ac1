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


import numpy as np

from nsbench.errors import ConfigError
from nsbench.integrators.base import Capabilities, CompiledArcs, Option

#: A segment halved or shrunk below ``h * MIN_FRACTION`` is a failure.
MIN_FRACTION = 2.0**-24
#: Default cap of the adaptive segment length, as a multiple of ``h``.
H_MAX_FACTOR = 8.0


def _options(feedback: bool) -> dict[str, Option]:
    """Options of ``ofapi`` (``feedback``) or ``mcpi``; defaults as measured in the README."""
    opts: dict[str, Option] = {}
    if feedback:
        opts["order"] = Option(
            1, int, choices=(0, 1, 2), doc="feedback order: 0 Picard (MCPI), 1 the paper's OFAPI, 2 second order"
        )
        opts["jacobian"] = Option(
            "node",
            str,
            choices=("node", "segment_start"),
            doc="feedback Jacobian at each node's iterate, or once per segment",
        )
    else:
        opts["order"] = Option(0, int, choices=(0,), doc="always 0, plain Picard (ofapi has the feedback)")
    opts.update(
        {
            "N": Option(
                12,
                int,
                lower=2,
                lower_inclusive=True,
                upper=64,
                doc="Chebyshev degree (N + 1 Gauss-Lobatto nodes per segment)",
            ),
            "h": Option(0.5, float, lower=0.0, doc="segment length (time units); the start value when adaptive"),
            # The increment left at the stop is ~ r tol, with r the last contraction ratio (~1e-3 for
            # order 1, ~0.1 for order 0); 1e-12 let event times drift by 1.6e-11 over tau = 300 (case 1).
            "tol": Option(
                1e-14 if feedback else 1e-15,
                float,
                lower=0.0,
                upper=1e-2,
                doc="iteration stop: max|X_new - X| <= tol max(1, max|X|), or stalled at round-off",
            ),
            "max_iter": Option(
                50, int, lower=1, lower_inclusive=True, upper=10_000, doc="iterations per segment before it is halved"
            ),
            "adaptive": Option(True, bool, doc="adapt the segment length to the trailing Chebyshev coefficients"),
            "coef_tol": Option(
                1e-13,
                float,
                lower=0.0,
                upper=1e-2,
                doc="adaptive target of the two trailing Chebyshev coefficients (relative)",
            ),
            "h_max": Option(
                None, float, lower=0.0, nullable=True, doc=f"largest adaptive segment length; None: {H_MAX_FACTOR:g} h"
            ),
        }
    )
    return opts


class ChebyshevPicard(CompiledArcs):
    """Shared machinery of ``ofapi`` and ``mcpi`` (see the module docstring)."""

    # ofapi and mcpi run one compiled arc function, _picard_arc.picard_arc: one compiles, the other waits
    kernel_group = "chebyshev-picard"

    counter_names = ("iterations", "segments", "halvings", "rejections")

    def check_settings(self) -> None:
        s = self.settings
        if s["h_max"] is not None and s["h_max"] < s["h"]:
            raise ConfigError(f"{self.name}: option h_max = {s['h_max']!r} must be >= h = {s['h']!r}")

    def build_kernel(self, problem):
        """The CGL operators of degree ``N`` and the options as the compiled arc reads them."""
        from nsbench.integrators import _chebyshev
        from nsbench.integrators._picard_arc import OPTIONS, picard_arc, scratch
        from nsbench.model.abi import kernel_data
        from nsbench.model.kernel import ArcKernel, arc_table

        ops = _chebyshev.operators(self.settings["N"])
        # writable copies: the same numba specialisation for every call
        operators = dict(
            f1a=ops.nodes.copy(), f1b=ops.weights.copy(), f2a=ops.integration.copy(), f2b=ops.to_coefficients.copy()
        )
        s = self.settings
        h = float(s["h"])
        values = {
            "h": h,
            "h_max": float(s["h_max"]) if s["h_max"] is not None else H_MAX_FACTOR * h,
            "h_min": h * MIN_FRACTION,
            "tol": float(s["tol"]),
            "coef_tol": float(s["coef_tol"]),
            "max_iter": float(s["max_iter"]),
            "order": float(s["order"]),
            "jac_node": 1.0 if s.get("jacobian", "node") == "node" else 0.0,
            "adaptive": 1.0 if s["adaptive"] else 0.0,
        }
        options = np.array([values[name] for name in OPTIONS])
        m, n, g = operators["f1a"].size, problem.n_states, problem.max_guards

        def data_for(n_sections: int):
            nodal, jacobians, vectors = scratch(m, n, n_sections, g)
            return kernel_data(**operators, f3a=nodal, f3b=jacobians, f2c=vectors)

        kernel = ArcKernel(
            arc_table(picard_arc, problem),
            data_for(2),
            options,
            self.counter_names,
            failure=self._failure,
            name=self.name,
        )

        def prepare_run(n_sections: int):
            if kernel.data.f2c.shape[1] < n_sections:
                kernel.data = data_for(n_sections)
            return kernel.data

        kernel.prepare_run = prepare_run
        return kernel

    def _failure(self, code: int, t: float) -> str:
        from nsbench.integrators import _picard_arc as arc

        s = self.settings
        floor = s["h"] * MIN_FRACTION
        if code == arc.NOT_CONVERGED:
            return (
                f"{self.name}: the Picard iteration did not converge to tol = {s['tol']:g} within "
                f"max_iter = {s['max_iter']} on a segment from t = {t:.17g}, even halved below {floor:.3g}"
            )
        return (
            f"{self.name}: the trailing Chebyshev coefficients stay above coef_tol = {s['coef_tol']:g} "
            f"on segments from t = {t:.17g} shorter than {floor:.3g} (raise N or coef_tol)"
        )


def _caps(needs_jacobian: bool) -> Capabilities:
    # spectral (no fixed order); the accuracy knob of a convergence study is tol
    return Capabilities(
        event_location="collocation-newton",
        order=None,
        adaptive=True,
        needs_jacobian=needs_jacobian,
        supports_nonlinear=True,
        precision="double",
        step_option="tol",
        checks_steps=True,
    )


class OFAPI(ChebyshevPicard):
    """Optimal-feedback accelerated Picard iteration on CGL collocation segments (Wang & Atluri)."""

    name = "ofapi"
    capabilities = _caps(True)
    options = _options(True)
    # measured max event-time errors (1-DOF case 1, 2-DOF cases 1-2, tau 300): ~5e-9, ~2e-10, ~4e-13
    accuracy_levels = (
        {"N": 8, "tol": 1e-9, "coef_tol": 1e-8},
        {"N": 10, "tol": 1e-11, "coef_tol": 1e-10},
        {"N": 12, "tol": 1e-14, "coef_tol": 1e-13},
    )


class MCPI(ChebyshevPicard):
    """Modified Chebyshev-Picard iteration: the same segments and event location, no feedback."""

    name = "mcpi"
    capabilities = _caps(False)
    options = _options(False)
    # measured as for ofapi: ~2e-9, ~2e-11, ~5e-13
    accuracy_levels = (
        {"N": 8, "tol": 1e-10, "coef_tol": 1e-8},
        {"N": 10, "tol": 1e-13, "coef_tol": 1e-10},
        {"N": 12, "tol": 1e-15, "coef_tol": 1e-13},
    )


def iterate_segment(
    problem,
    mode,
    t_a: float,
    y_a,
    h: float,
    *,
    N: int = 12,
    order: int = 1,
    jacobian: str = "node",
    tol: float = 1e-13,
    max_iter: int = 50,
    guess: np.ndarray | None = None,
) -> tuple[np.ndarray, bool, int]:
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

    ops = _chebyshev.operators(N)
    p = problem.data
    m_arr = problem.mode_array(mode)
    y_a = np.array(y_a, dtype=float)
    n = y_a.size
    w = 0.5 * h
    g0 = problem.rhs(mode, float(t_a), y_a)
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
        p,
        m_arr,
        float(t_a),
        y_a,
        w,
        ops.nodes.copy(),
        ops.integration.copy(),
        _picard_iteration.Nodal(D, X, G, J, P, Y, Z),
        _picard_iteration.Iteration(int(order), jacobian == "node", float(tol), int(max_iter)),
    )
    return X, code == _picard_iteration.CONVERGED, int(its)
