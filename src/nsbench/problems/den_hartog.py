"""``den-hartog``: Den Hartog's forced oscillator with Coulomb and viscous friction, and its non-stop motion.

``m x'' + c x' + k x = f + F cos(w t)`` on fixed ground, with Coulomb friction
(``f = -fs sign(x')`` while the block slides, ``|f| <= fr`` while it sticks):
the friction family with a belt that does not move (``v0 = 0``, MODEL.md's law
with one block), forced. J. P. Den Hartog, "Forced vibrations with combined
Coulomb and viscous friction", *Trans. ASME* 53 (APM-53-9), 1931, 107-115,
found its steady *non-stop* motion in closed form: a symmetric periodic orbit of
the forcing's period, ``x(t + pi / w) = -x(t)``, whose velocity vanishes only at
the two reversals of each period. :func:`steady_state` derives it (the
derivation is on the problem sheet, docs/problems.md): on a half period with
``x' > 0`` the motion is linear, ``u = x + fs / k`` obeys ``m u'' + c u' + k u =
F cos(w t)``, and the four conditions ``x = -X, x' = 0`` at the reversal and ``x
= X, x' = 0`` half a period later fix the amplitude ``X`` and the phase of the
reversal. Undamped it is Den Hartog's formula

    X / (F / k) = sqrt( 1 / (1 - r^2)^2 - (fs / F)^2 (tan(pi / (2 r)) / r)^2 ),   r = w / sqrt(k / m).

The motion is non-stop where, in addition, the block does not stick at a
reversal (``k X + F cos(w t_r) > fr``: the spring and the force overcome static
friction) and its velocity keeps its sign between reversals; beyond that
boundary stops appear (:attr:`SteadyState.push`, :attr:`SteadyState.non_stop`).

Default start: on that orbit at ``t = 0`` (computed from the parameters), so the
run is the steady motion from its first step.
"""

from __future__ import annotations

import cmath
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from nsbench.errors import ConfigError
from nsbench.problems.oscillator import FrictionOscillator, split_start
from nsbench.problems.parameters import Bound, Coefficients, check_friction_order, check_values, scales_of

NAME = "den-hartog"
#: ``fr`` defaults to ``fs`` (Den Hartog's model has one friction force); the other values are this
#: sheet's, a point well inside the non-stop region (Den Hartog gives his results as curves).
DEFAULTS = {"m": 1.0, "c": 0.1, "k": 1.0, "fs": 0.3, "F": 1.0, "w": 1.5}
BOUNDS = {
    "m": Bound(0.0, False, "mass m"),
    "c": Bound(0.0, True, "viscous damping c"),
    "k": Bound(0.0, False, "stiffness k"),
    "fs": Bound(0.0, False, "kinetic friction fs"),
    "fr": Bound(0.0, False, "static friction fr"),
    "F": Bound(0.0, False, "forcing amplitude F"),
    "w": Bound(0.0, False, "forcing frequency w"),
}
#: Samples per half period at which the closed form's velocity is checked for a stop between reversals.
VELOCITY_SAMPLES = 2000


@dataclass(frozen=True)
class SteadyState:
    """Den Hartog's symmetric non-stop periodic motion (:func:`steady_state`).

    Attributes
    ----------
    amplitude
        ``X``: the motion goes from ``-X`` to ``X`` and back in one forcing period.
    reversal_time
        ``t_r`` in ``[0, 2 pi / w)``: a reversal at ``x = -X`` (the velocity turns positive); the
        others are ``t_r + j pi / w``, alternately at ``X`` and ``-X``.
    phase
        The phase lag of the displacement's maximum behind the force's, ``w (t_r + pi / w)`` mod ``2 pi``.
    push
        ``(k X + F cos(w t_r) - fr) / fr``: how far the spring and the force at a reversal exceed the
        static limit. Where it is positive the block reverses; where it falls to 0 the block sticks
        there: stops appear.
    velocity_positive
        Whether the velocity of the rising half keeps its sign between the reversals (checked at
        :data:`VELOCITY_SAMPLES` points; a stop between reversals would end the non-stop motion too).
    """

    amplitude: float
    reversal_time: float
    phase: float
    push: float
    velocity_positive: bool
    _m: float
    _c: float
    _k: float
    _fs: float
    _z: complex
    _w: float
    _theta: float

    @property
    def non_stop(self) -> bool:
        """Whether the motion is Den Hartog's non-stop motion: it reverses at both ends and never stops between."""
        return self.push > 0.0 and self.velocity_positive

    @property
    def period(self) -> float:
        return 2.0 * math.pi / self._w

    def state(self, t) -> np.ndarray:
        """``(x, v)`` of the periodic motion at times ``t`` (closed form; shape ``(2,)`` or ``(2, k)``)."""
        t = np.asarray(t, dtype=float)
        half = math.pi / self._w
        k_half = np.floor((t - self.reversal_time) / half)
        tau = t - self.reversal_time - k_half * half  # time since the last reversal, in [0, pi / w)
        sign = np.where(k_half % 2 == 0, 1.0, -1.0)  # rising half (from -X) or falling half (the mirror)
        x, v = _rising_half(self, tau)
        return np.array([sign * x, sign * v])


def _homogeneous(m: float, c: float, k: float, s: float) -> np.ndarray:
    """The state-transition matrix of ``m u'' + c u' + k u = 0`` over a time ``s`` (closed form)."""
    zeta_w = c / (2.0 * m)
    disc = k / m - zeta_w * zeta_w
    e = math.exp(-zeta_w * s)
    if disc > 0.0:
        wd = math.sqrt(disc)
        cs, sn = math.cos(wd * s), math.sin(wd * s)
        f, g = sn / wd, cs
    elif disc < 0.0:
        wd = math.sqrt(-disc)
        f, g = math.sinh(wd * s) / wd, math.cosh(wd * s)
    else:
        f, g = s, 1.0
    # u = e^{-zeta_w s} (u0 (g + zeta_w f) + v0 f);  v = e^{-zeta_w s} (-u0 (k/m) f + v0 (g - zeta_w f))
    return e * np.array([[g + zeta_w * f, f], [-(k / m) * f, g - zeta_w * f]])


def _rising_half(ss: SteadyState, tau) -> tuple[np.ndarray, np.ndarray]:
    """``(x, v)`` at ``tau`` in ``[0, pi / w)`` after a reversal at ``-X``: particular plus homogeneous solution."""
    tau = np.asarray(tau, dtype=float)
    zt = ss._z * np.exp(1j * (ss._w * tau + ss._theta))  # P(tau) = Re(Z e^{i (w tau + theta)})
    p, dp = zt.real, (1j * ss._w * zt).real
    a = ss._fs / ss._k
    z0 = ss._z * cmath.exp(1j * ss._theta)
    h0 = np.array([a - ss.amplitude - z0.real, -(1j * ss._w * z0).real])  # u(0) - P(0), u'(0) - P'(0)
    flat = np.atleast_1d(tau)
    hom = np.array([_homogeneous(ss._m, ss._c, ss._k, float(s)) @ h0 for s in flat]).T.reshape((2, *tau.shape))
    return p + hom[0] - a, dp + hom[1]


def steady_state(m: float, c: float, k: float, fs: float, fr: float, F: float, w: float) -> SteadyState | None:
    """Den Hartog's symmetric periodic motion with two reversals per period, or ``None`` where it does not exist.

    With ``a = fs / k``, ``Phi`` the state-transition matrix of the unforced linear motion over half
    a period ``T = pi / w`` and ``P = Re(Z e^{i(w tau + theta)})``, ``Z = F / (k - m w^2 + i c w)``, the
    particular solution of the rising half (``tau`` from the reversal at ``-X``, ``theta = w t_r``), the
    conditions ``u(0) = (a - X, 0)``, ``u(T) = (a + X, 0)`` and ``P(T) = -P(0)`` give
    ``(P(0), P'(0)) = -X e + a q`` with ``q = (I + Phi)^-1 (Phi - I) e``, ``e = (1, 0)``; with
    ``|Z|^2 = P(0)^2 + (P'(0) / w)^2`` that is ``X = a q0 + sqrt(|Z|^2 - (a q1 / w)^2)`` and
    ``Z e^{i theta} = P(0) - i P'(0) / w``. ``None``: no real positive ``X`` (the friction is too large
    for this force), or ``I + Phi`` singular (undamped, at ``r = 1/(2j + 1)``).
    """
    half = math.pi / w
    phi = _homogeneous(m, c, k, half)
    ipf = np.eye(2) + phi
    if abs(np.linalg.det(ipf)) < 1e-14 * max(1.0, float(np.abs(phi).max())) ** 2:
        return None
    q = np.linalg.solve(ipf, (phi - np.eye(2)) @ np.array([1.0, 0.0]))
    z = F / complex(k - m * w * w, c * w)
    a = fs / k
    disc = abs(z) ** 2 - (a * q[1] / w) ** 2
    if not disc > 0.0:
        return None
    amplitude = a * q[0] + math.sqrt(disc)
    if not amplitude > 0.0:
        return None
    p0, p1 = -amplitude + a * q[0], a * q[1]
    theta = cmath.phase(complex(p0, -p1 / w)) - cmath.phase(z)
    period = 2.0 * math.pi / w
    reversal = (theta / w) % period
    theta = w * reversal
    phase = (theta + math.pi) % (2.0 * math.pi)
    push = (k * amplitude + F * math.cos(theta) - fr) / fr
    ss = SteadyState(amplitude, reversal, phase, push, True, m, c, k, fs, z, w, theta)
    tau = np.linspace(0.0, half, VELOCITY_SAMPLES + 1)[1:-1]
    positive = bool((_rising_half(ss, tau)[1] > 0.0).all())
    return SteadyState(amplitude, reversal, phase, push, positive, m, c, k, fs, z, w, theta)


def den_hartog(case: int | str | None = None, dimensional: bool = True, **params: Any) -> FrictionOscillator:
    """Build Den Hartog's forced Coulomb oscillator (``m c k fs fr F w``, start ``x1_0 v1_0``).

    The parameters are in the problem's own units (no cases, no dimensionless presets; ``dimensional``
    is ignored). ``fr`` defaults to ``fs``. The start defaults to the state of the non-stop periodic
    motion at ``t = 0`` (:func:`steady_state`).

    Raises
    ------
    ConfigError
        A case, an unknown parameter, a non-finite or out-of-range value, ``fs > fr``, or no start
        given where the parameters have no non-stop motion to start on.
    """
    if case not in (None, 1, "1"):
        raise ConfigError(f"{NAME}: unknown case {case!r}; the problem has no cases (give its parameters)")
    rest, _, start = split_start(NAME, params, 1)
    given = check_values(NAME, rest, (*DEFAULTS, "fr"), BOUNDS)
    v = {**DEFAULTS, **given}
    v.setdefault("fr", v["fs"])
    check_friction_order(NAME, "fs", v["fs"], "fr", v["fr"])
    ss = steady_state(*(v[key] for key in ("m", "c", "k", "fs", "fr", "F", "w")))
    if len(start) < 2:
        if ss is None or not ss.non_stop:
            why = (
                "it has none"
                if ss is None
                else f"stops appear (the push beyond static friction at a reversal is {ss.push:.3g} of fr)"
                if ss.push <= 0.0
                else "the velocity stops between reversals"
            )
            raise ConfigError(
                f"{NAME}: the default start is on the non-stop periodic motion, and at these parameters {why}; "
                "give the start x1_0 and v1_0"
            )
        x0, vel0 = (float(u) for u in ss.state(0.0))
        start = {"x1_0": start.get("x1_0", x0), "v1_0": start.get("v1_0", vel0)}
    y0 = np.array([start["x1_0"], start["v1_0"]])
    coeffs = Coefficients(
        m=(v["m"],), c=(v["c"],), k=(v["k"],), h=(0.0,), fs=(v["fs"],), fr=(v["fr"],), F=v["F"], w=v["w"], v0=0.0
    )
    return FrictionOscillator(
        coeffs,
        name=NAME,
        case=None,
        dimensional=True,
        params=dict(params),
        parameters={**v, **start},
        scales=scales_of(v["m"], v["k"], v["fr"]),
        y0=y0,
    )


def problem_steady_state(problem: FrictionOscillator) -> SteadyState | None:
    """:func:`steady_state` of a ``den-hartog`` problem's parameters."""
    return steady_state(*(problem.parameters[key] for key in ("m", "c", "k", "fs", "fr", "F", "w")))


def stop_boundary(m: float, c: float, k: float, F: float, w: float, fr_over_fs: float = 1.0) -> float:
    """The kinetic friction ``fs`` at which stops appear (``fr = fr_over_fs * fs``): the non-stop motion exists
    below it and not above, found by bisection on :attr:`SteadyState.non_stop` to 1e-13 relative.

    Raises
    ------
    ValueError
        No non-stop motion even at a vanishing friction (``fs = 1e-9 F``), or still one at ``fs = F``.
    """

    def non_stop(fs: float) -> bool:
        ss = steady_state(m, c, k, fs, fr_over_fs * fs, F, w)
        return ss is not None and ss.non_stop

    lo, hi = 1e-9 * F, F
    if not non_stop(lo) or non_stop(hi):
        raise ValueError(f"no stop boundary in fs in ({lo:g}, {hi:g}) at m={m}, c={c}, k={k}, F={F}, w={w}")
    while hi - lo > 1e-13 * hi:
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if non_stop(mid) else (lo, mid)
    return 0.5 * (lo + hi)
