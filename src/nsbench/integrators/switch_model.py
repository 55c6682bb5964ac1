"""``switch-model``: Leine's switch model of Coulomb friction with stiction, on a scipy or SUNDIALS ODE solver.

Leine, van Campen, de Kraker & van den Steen, "Stick-slip vibrations induced by
alternate friction models", Nonlinear Dynamics 16 (1998) 41-54. A thin band
``|u| <= eta`` around the belt speed (``u = v - v_belt``) stands for stick, and the
friction force follows from the *force* in the band, so the vector field is
discontinuous but defined everywhere and any ODE solver integrates it without
event location. Per block ``i``, with ``R_i`` the restoring force (MODEL.md):

- ``|u_i| > eta``: slip, friction ``-fs_i sign(u_i)``;
- ``|u_i| <= eta`` and ``|R_i| <= fr_i``: stick, friction ``R_i`` (the block keeps
  its velocity: ``dv_i/dt = 0``, so it moves at most ``eta`` off the belt);
- ``|u_i| <= eta`` and ``|R_i| > fr_i``: break-away, friction ``fs_i sign(R_i)``
  (slip in the direction of the load).

The method reports its stick set at each point it returns (``SystemResult.modes``);
the inference reads the phases off the trajectory with a test of the same kind (``eta`` is its
stick band; at the belt speed past the static limit a block slips: rule 1 of
:mod:`nsbench.hybrid.inference`), and places the events on the band's edges. ``eta`` is in the problem's velocity units.
The right-hand side is discontinuous at the band's edges: the solver's error
control (option ``solver``: scipy ``RK45`` by default, as Leine used an explicit
Runge-Kutta, or ``Radau``/``BDF``/``DOP853``, or SUNDIALS CVODE through scikit-sundae,
``CVODE-BDF``/``CVODE-Adams``, with a difference-quotient Jacobian: the field has no
Jacobian across the band's edges) shortens the steps there. Any friction problem,
cubic springs included.
"""

from __future__ import annotations

import numpy as np

from nsbench.integrators.base import Capabilities, Option
from nsbench.integrators.whole import SystemRequest, SystemResult, WholeSystem


class SwitchModel(WholeSystem):
    """Leine's switch model: a stick band |v - v_belt| <= eta with force-based switching, on scipy or CVODE."""

    name = "switch-model"
    WARM_IN_SETUP = True  # its first integrate loads the law's compiled functions: in setup, untimed
    COULOMB_ONLY = True  # its force law is built on fs alone: a weakening or Stribeck law is refused
    capabilities = Capabilities(
        event_location="inferred-from-status", order=None, adaptive=True, step_option="rtol", family="switch-model"
    )
    options = {
        "eta": Option(1e-4, float, lower=0.0, doc="half-width of the stick band (velocity units)"),
        "solver": Option(
            "RK45",
            str,
            choices=("RK45", "DOP853", "Radau", "BDF", "CVODE-BDF", "CVODE-Adams"),
            doc="the ODE solver: scipy's, or SUNDIALS CVODE (scikit-sundae)",
        ),
        "rtol": Option(1e-8, float, lower=0.0, upper=0.1, doc="relative tolerance"),
        "atol": Option(1e-10, float, lower=0.0, doc="absolute tolerance"),
    }
    accuracy_levels = (
        {"eta": 1e-3, "rtol": 1e-6, "atol": 1e-8},
        {"eta": 1e-4, "rtol": 1e-8, "atol": 1e-10},
        {"eta": 1e-5, "rtol": 1e-10, "atol": 1e-12},
    )
    known_gaps = {
        "event-times": "switches are placed on the band's edges and the discontinuous field is stepped over by "
        "error control: switching times within 1e-5 need eta and rtol far below the defaults",
        "energy-balance": "the phases of the band are not the model's: the balance closes to O(eta)",
        "cubic-event-times": "as event-times",
    }

    def stick_band(self, problem) -> float:
        return float(self.settings["eta"])

    def _law(self, problem):
        nb = problem.n_blocks
        fs = np.array(problem.coefficients.fs, dtype=float)
        fr = np.array(problem.coefficients.fr, dtype=float)
        m = np.array(problem.coefficients.m, dtype=float)
        v0, eta = problem.v0, self.settings["eta"]
        slip = (1,) * nb

        def restoring(t, y):
            # the slip+ mode's velocity rows are (-R - fs) / m
            return -(problem.rhs(slip, t, y)[1::2] * m) - fs

        def classify(t, y):
            """Per block: 0 stick, +-1 slip (the direction of motion relative to the belt), and the friction."""
            r = restoring(t, y)
            u = y[1::2] - v0
            band = np.abs(u) <= eta
            stick = band & (np.abs(r) <= fr)
            phase = np.where(stick, 0, np.where(band, -np.sign(r), np.sign(u))).astype(np.int64)
            f = np.where(stick, r, -fs * phase)
            return phase, f

        def fun(t, y):
            out = problem.rhs(slip, t, y)
            _, f = classify(t, y)
            out[1::2] += (fs + f) / m
            stuck = (np.abs(y[1::2] - v0) <= eta) & (np.abs(restoring(t, y)) <= fr)
            out[1::2][stuck] = 0.0
            return out

        def modes_of(ts, ys):
            return np.array([classify(t, y)[0] for t, y in zip(ts, ys)], dtype=np.int64).reshape(len(ts), nb)

        return fun, modes_of

    def integrate(self, request: SystemRequest) -> SystemResult:
        fun, modes_of = self._law(request.problem)
        s = self.settings
        if s["solver"].startswith("CVODE"):
            from nsbench.integrators._whole_sundials import CVODE_METHODS, run_cvode

            return run_cvode(
                request, fun, None, CVODE_METHODS[s["solver"]], s["rtol"], s["atol"], refine=4, modes_of=modes_of
            )
        from nsbench.integrators._whole_scipy import run_scipy

        return run_scipy(request, fun, None, s["solver"], s["rtol"], s["atol"], refine=4, modes_of=modes_of)
