"""``lugre``: the LuGre friction model (a bristle per contact) on a stiff solver, the bristles as internal states.

Canudas de Wit, Olsson, Astrom and Lischinsky, "A new model for control of systems with
friction", IEEE Transactions on Automatic Control 40(3) (1995) 419-425: the contact is an
average bristle of deflection ``z``; with ``u = v - v_belt`` the block's velocity relative to
the belt,

    dz/dt = u - sigma0 |u| z / G(u),      G(u) = Fc + (Fs - Fc) exp(-(u / vs)^2),
    f = -(sigma0 z + sigma1 dz/dt + sigma2 u)        (the friction force on the block),

so a block slipping steadily feels ``-G(u) sign(u) - sigma2 u`` (Coulomb's ``Fc`` with a Stribeck
rise to ``Fs`` at low speed), and a stuck block's bristle deflects elastically under its load
(presliding) until the load nears ``Fs``, where it breaks away. nsbench takes ``Fc`` and ``Fs``
from the problem (the kinetic level ``fs_i`` and the static limit ``fr_i`` of each block) and the
other parameters from the paper's simulations (its Table I, for a unit mass): ``sigma0 = 1e5``
(bristle stiffness), ``sigma1 = sqrt(1e5) = 316.2`` (bristle damping), ``vs = 0.001`` (Stribeck
velocity); its viscous ``sigma2 = 0.4`` is an option left at 0 by default, since the belt problems
carry their own viscous damping and Coulomb's law has none. The problems are dimensionless with
unit mass and unit static limit of block 1, the scale of the paper's example (``m = 1 kg``,
``Fc = 1 N``, ``Fs = 1.5 N``).

**The internal states.** The bristle deflections ``z_i`` are the method's own states, beside the
problem's: the system stepped is ``[y, z]``; :class:`~nsbench.integrators.whole.SystemResult`
returns ``y`` and the bristles as ``internal`` (names ``z1 .. zn``), which
:func:`nsbench.simulate` hands on as ``SimulationResult.internal`` (one row per step). The
bristles start in the steady state of the start's phase: ``z = -R / sigma0`` for a block that
starts stuck (its bristle carries the load ``R``), ``G(u) sign(u) / sigma0`` for one that slips.

The stiff system (rates up to ``sqrt(sigma0 / m)`` = 316 and ``sigma0 |u| / Fc``) is stepped by
scipy's ``Radau`` (default) or ``BDF`` with the analytic Jacobian; the events are read off the
velocities with the band ``|u| <= band`` (default ``vs``: a stuck block's presliding creep, about
``|dR/dt| / sigma0``, is far below it, a slipping block far above; at ``vs / 10`` the bristle's
ringing after a block lands, damping ratio ``sigma1 / (2 sqrt(sigma0 m)) = 0.5``, leaves the band
two or three times and reads as stick-slip chatter). Friction problems with
Coulomb's law (the model has its own Stribeck curve); cubic springs included.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from nsbench.integrators.base import Capabilities, Option
from nsbench.integrators.whole import SystemRequest, SystemResult, WholeSystem

#: The paper's parameters (Canudas de Wit et al. 1995, Table I): bristle stiffness, damping, Stribeck velocity,
#: viscous coefficient.
SIGMA0, SIGMA1, VS, SIGMA2_PAPER = 1e5, math.sqrt(1e5), 1e-3, 0.4


def stribeck(fc: np.ndarray, fs: np.ndarray, vs: float, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``G(u) = Fc + (Fs - Fc) exp(-(u/vs)^2)`` and its derivative in ``u``."""
    e = np.exp(-((u / vs) ** 2))
    return fc + (fs - fc) * e, (fs - fc) * e * (-2.0 * u / (vs * vs))


class LuGre(WholeSystem):
    """LuGre friction (Canudas de Wit et al. 1995): a bristle per block as an internal state, on scipy Radau/BDF."""

    name = "lugre"
    WARM_IN_SETUP = True  # its first integrate loads the law's compiled functions: in setup, untimed
    COULOMB_ONLY = True  # its slip force is its own Stribeck curve between the problem's fs and fr
    capabilities = Capabilities(
        event_location="inferred-from-band",
        order=None,
        adaptive=True,
        needs_jacobian=True,
        step_option="rtol",
        family="smoothing",
    )
    options = {
        "sigma0": Option(SIGMA0, float, lower=0.0, doc="bristle stiffness (force per unit deflection)"),
        "sigma1": Option(SIGMA1, float, lower=0.0, lower_inclusive=True, doc="bristle damping"),
        "sigma2": Option(0.0, float, lower=0.0, lower_inclusive=True, doc="viscous friction (the paper's: 0.4)"),
        "vs": Option(VS, float, lower=0.0, doc="Stribeck velocity"),
        "solver": Option("Radau", str, choices=("Radau", "BDF"), doc="the stiff solver (scipy)"),
        "rtol": Option(1e-8, float, lower=0.0, upper=0.1, doc="relative tolerance"),
        "atol": Option(1e-12, float, lower=0.0, doc="absolute tolerance (the bristles deflect by about 1e-5)"),
        "band": Option(None, float, lower=0.0, nullable=True, doc="stick band |v - v_belt| <= band (default vs)"),
    }
    accuracy_levels = (
        {"rtol": 1e-6, "atol": 1e-10},
        {"rtol": 1e-8, "atol": 1e-12},
        {"rtol": 1e-10, "atol": 1e-14},
    )
    known_gaps = {
        "event-times": "LuGre is a friction model of its own, not Coulomb's law with stiction: it breaks away near "
        "fr at a time that depends on the load's rate, and its presliding delays every switch",
        "stuck-stays-stuck": "a stuck block creeps (presliding: |v - v_belt| about |dR/dt| / sigma0, 8e-7 here)",
        "energy-balance": "the bristles store and dissipate energy that Coulomb's law has not",
        "cubic-event-times": "as event-times",
        "switch-convergence": "its switching times converge to LuGre's, not to exact's, as rtol tightens",
    }

    def stick_band(self, problem) -> float:
        band = self.settings["band"]
        return self.settings["vs"] if band is None else float(band)

    def _fields(self, problem):
        nb, n = problem.n_blocks, problem.n_states
        slip = (1,) * nb
        c = problem.coefficients
        fc, fs = np.array(c.fs, dtype=float), np.array(c.fr, dtype=float)
        m = np.array(c.m, dtype=float)
        v0 = problem.v0
        s0, s1, s2, vs = (self.settings[k] for k in ("sigma0", "sigma1", "sigma2", "vs"))
        vel = np.arange(1, 2 * nb, 2)

        def parts(y):
            u = y[vel] - v0
            z = y[n:]
            g, dg = stribeck(fc, fs, vs, u)
            zdot = u - s0 * np.abs(u) * z / g
            f = -(s0 * z + s1 * zdot + s2 * u)
            return u, z, g, dg, zdot, f

        def fun(t, y):
            out = np.empty(n + nb)
            u, z, g, dg, zdot, f = parts(y)
            out[:n] = problem.rhs(slip, t, y[:n])  # every block slipping forwards: the constant friction -fs
            out[vel] += (fc + f) / m
            out[n:] = zdot
            return out

        def jac(t, y):
            out = np.zeros((n + nb, n + nb))
            out[:n, :n] = problem.jacobian(slip, t, y[:n])
            u, z, g, dg, zdot, f = parts(y)
            dzdot_du = 1.0 - s0 * z * (np.sign(u) / g - np.abs(u) * dg / (g * g))
            dzdot_dz = -s0 * np.abs(u) / g
            zi = np.arange(n, n + nb)
            out[vel, vel] += -(s1 * dzdot_du + s2) / m
            out[vel, zi] = -(s0 + s1 * dzdot_dz) / m
            out[zi, vel] = dzdot_du
            out[zi, zi] = dzdot_dz
            return out

        return fun, jac

    def initial_bristles(self, problem, t0: float, y0: np.ndarray) -> np.ndarray:
        """The steady deflection of each bristle in the start's phase (see the module docstring)."""
        nb = problem.n_blocks
        c = problem.coefficients
        u = np.asarray(y0, dtype=float)[1::2] - problem.v0
        g, _ = stribeck(np.array(c.fs, dtype=float), np.array(c.fr, dtype=float), self.settings["vs"], u)
        z = np.sign(u) * g / self.settings["sigma0"]
        stuck = (1,) * nb
        acc = problem.rhs(stuck, t0, np.asarray(y0, dtype=float))  # (-R - fs) / m with every block slipping
        r = -(acc[1::2] * np.array(c.m, dtype=float)) - np.array(c.fs, dtype=float)
        z = np.where(u == 0.0, -r / self.settings["sigma0"], z)
        return z

    def integrate(self, request: SystemRequest) -> SystemResult:
        from nsbench.integrators._whole_scipy import run_scipy

        problem = request.problem
        n = problem.n_states
        fun, jac = self._fields(problem)
        z0 = self.initial_bristles(problem, request.t0, request.y0)
        augmented = dataclasses.replace(request, y0=np.concatenate([np.asarray(request.y0, dtype=float), z0]))
        s = self.settings
        res = run_scipy(augmented, fun, jac, s["solver"], s["rtol"], s["atol"], refine=4)
        res.internal = res.y[:, n:].copy()
        res.internal_names = tuple(f"z{i + 1}" for i in range(z0.size))
        res.y = res.y[:, :n].copy()
        if res.y_eval is not None:
            res.y_eval = np.asarray(res.y_eval)[:, :n].copy()
        return res
