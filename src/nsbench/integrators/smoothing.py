"""``smoothing``: the friction law regularised, then a stiff ODE solver (scipy Radau or BDF, SUNDIALS CVODE BDF).

The set-valued ``sign(v - v_belt)`` of Coulomb friction is replaced by a smooth
function of the relative velocity ``u = v - v_belt``: the friction force on block
``i`` is ``-fs_i * phi(eps * u)`` with ``phi = (2/pi) arctan`` (``law = 'arctan'``)
or ``tanh``. ``eps`` (in inverse velocity units of the problem) is the sharpness:
the force reaches half of ``fs`` at ``|u| = 1/eps`` (arctan) or ``0.55/eps`` (tanh),
so as ``eps`` grows the law tends to Coulomb's and the system stiffens (its
largest rate grows like ``fs eps / m``). Smoothing has no stiction: the
regularised force never exceeds ``fs``, so a block "sticks" by creeping at the
``u`` where ``fs phi(eps u)`` balances the load, and breaks away where the load
reaches ``fs`` instead of the static limit ``fr``. nsbench reads the stick/slip
status off the velocities with the band ``|u| <= band`` (default ``10/eps``, where
arctan's force is 94% of ``fs``; :mod:`nsbench.hybrid.inference`).

The step loop is scipy's (``Radau`` by default, ``BDF``) or SUNDIALS CVODE's
variable-order BDF through scikit-sundae (``CVODE-BDF``), chosen by option
``solver``, always with the analytic Jacobian (the problem's slip-mode Jacobian
plus the regularised friction's derivative); each step is returned with three
points of the solver's dense output inside it. Any friction problem, cubic
springs included.
"""

from __future__ import annotations

import math

import numpy as np

from nsbench.integrators.base import Capabilities, Option
from nsbench.integrators.whole import SystemRequest, SystemResult, WholeSystem

LAWS = ("arctan", "tanh")


def friction(law: str, fs: np.ndarray, eps: float, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The regularised friction force ``-fs phi(eps u)`` and its derivative in ``u``."""
    z = eps * u
    if law == "arctan":
        return -fs * (2.0 / math.pi) * np.arctan(z), -fs * (2.0 / math.pi) * eps / (1.0 + z * z)
    th = np.tanh(z)
    return -fs * th, -fs * eps * (1.0 - th * th)


class Smoothing(WholeSystem):
    """Regularised friction (arctan or tanh, sharpness eps) on scipy Radau/BDF or CVODE BDF, analytic Jacobian."""

    name = "smoothing"
    WARM_IN_SETUP = True  # its first integrate loads the law's compiled functions: in setup, untimed
    COULOMB_ONLY = True  # its force law is built on fs alone: a weakening or Stribeck law is refused
    capabilities = Capabilities(
        event_location="inferred-from-band",
        order=None,
        adaptive=True,
        needs_jacobian=True,
        step_option="rtol",
        family="smoothing",
    )
    options = {
        "eps": Option(1e3, float, lower=0.0, doc="sharpness of the regularisation (inverse velocity units)"),
        "law": Option("arctan", str, choices=LAWS, doc="the smooth sign: (2/pi) arctan or tanh"),
        "solver": Option(
            "Radau",
            str,
            choices=("Radau", "BDF", "CVODE-BDF"),
            doc="the stiff solver: scipy Radau or BDF, or SUNDIALS CVODE BDF (scikit-sundae)",
        ),
        "rtol": Option(1e-8, float, lower=0.0, upper=0.1, doc="relative tolerance"),
        "atol": Option(1e-10, float, lower=0.0, doc="absolute tolerance"),
        "band": Option(
            None,
            float,
            lower=0.0,
            nullable=True,
            doc="stick band |v - v_belt| <= band for the event inference (default 10/eps)",
        ),
    }
    accuracy_levels = (
        {"eps": 1e2, "rtol": 1e-6, "atol": 1e-8},
        {"eps": 1e3, "rtol": 1e-8, "atol": 1e-10},
        {"eps": 1e4, "rtol": 1e-10, "atol": 1e-12},
    )
    known_gaps = {
        "event-times": "smoothing has no stiction: a block breaks away where its load reaches fs, not fr, and "
        "creeps while stuck; its switching-time error is what the families suite measures",
        "stuck-stays-stuck": "a regularised block creeps (|v - v_belt| ~ 1/eps) instead of moving with the belt",
        "energy-balance": "the work of the regularised friction is not the Coulomb friction's of the phases",
        "cubic-event-times": "as event-times: no stiction",
        "switch-convergence": "without stiction it never has the stick-slip cycle of case 1 (fr > fs): no level "
        "has exact's switch sequence",
        "convergence": "on a slipping arc the regularised force misses fs by about 2 fs / (pi eps |u|): at "
        "eps = 1e4 the arc's error stays near 1e-3, above the check's 1e-5",
    }

    def stick_band(self, problem) -> float:
        band = self.settings["band"]
        return 10.0 / self.settings["eps"] if band is None else float(band)

    def _fields(self, problem):
        nb = problem.n_blocks
        slip = (1,) * nb
        fs = np.array(problem.coefficients.fs, dtype=float)
        m = np.array(problem.coefficients.m, dtype=float)
        v0, eps, law = problem.v0, self.settings["eps"], self.settings["law"]

        def fun(t, y):
            out = problem.rhs(slip, t, y)  # every block slipping forwards: the constant friction -fs
            f, _ = friction(law, fs, eps, y[1::2] - v0)
            out[1::2] += (fs + f) / m
            return out

        def jac(t, y):
            out = problem.jacobian(slip, t, y)
            _, df = friction(law, fs, eps, y[1::2] - v0)
            idx = np.arange(1, 2 * nb, 2)
            out[idx, idx] += df / m
            return out

        return fun, jac

    def integrate(self, request: SystemRequest) -> SystemResult:
        fun, jac = self._fields(request.problem)
        s = self.settings
        if s["solver"].startswith("CVODE"):
            from nsbench.integrators._whole_sundials import CVODE_METHODS, run_cvode

            return run_cvode(request, fun, jac, CVODE_METHODS[s["solver"]], s["rtol"], s["atol"], refine=4)
        from nsbench.integrators._whole_scipy import run_scipy

        return run_scipy(request, fun, jac, s["solver"], s["rtol"], s["atol"], refine=4)
