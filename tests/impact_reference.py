"""An independent high-precision solution of the impact oscillator and the bouncing ball (mpmath).

Written from the equations of ``docs/problems.md``, without nsbench's integrators or its core: time
and state are carried in ``dps`` decimal digits from the start to the end, resets are applied in
that precision, and the Zeno accumulations are computed in it too.

The impact oscillator ``x'' + 2 zeta x' + x = F cos(w t)`` (``zeta < 1``, not at resonance) has, from
``(t0, x0, v0)``, the closed-form flight

    x(t) = Re(Z e^(i w t)) + Re(c e^(lam s)),   Z = F / (1 - w^2 + 2 i zeta w),   lam = -zeta + i wd,

``s = t - t0``, ``wd = sqrt(1 - zeta^2)``, ``c`` fixed by ``x(t0) = x0, v(t0) = v0``. Every derivative
of it is bounded by ``|x^(k)| <= w^k |Z| + |c|`` (``|lam| = 1``), which makes the search for the first
zero of the gap ``g = sigma - x`` after a start rigorous: on ``[a, b]``, ``g`` is within
``M2 (b - a)^2 / 8`` of its chord, so an interval whose ends clear that margin holds no zero; the
others are halved, leftmost first, and the zero is refined by Newton's method kept inside its
bracket. A flight leaving the stop with speed ``u > 0`` is positive on ``(0, 2 u / M2)``; one leaving
it at rest (a release, ``g = g' = g'' = 0``) on ``(0, 4 g''' / M4)``.

An impact at ``x = sigma`` resets ``v -> -r v``. A chattering sequence (the pressing force
``P(t) = -sigma + F cos(w t)`` positive) is followed impact by impact until its flights are shorter than
:data:`STOP_INTERVAL`; its accumulation time is then Aitken's extrapolation of the last three impact
times (the geometric tail), whose error is of the order of the square of the last flight (far below
``10^-30``), and its own change from the previous three times is kept as ``err``. The mass then sticks
(``x = sigma, v = 0``) until ``P`` falls through zero: ``cos(w t) = sigma / F`` with ``sin(w t) > 0``,
in closed form.

The bouncing ball has its closed form (``BouncingBall`` documents it): impact times
``t1 + sum 2 e^k v1 / g`` and the rest at ``t_Z = t1 + 2 e v1 / (g (1 - e))``.
"""

from __future__ import annotations

from dataclasses import dataclass

import mpmath

#: Flights shorter than this end a chattering sequence's impact-by-impact solution (Aitken from there).
STOP_INTERVAL = "1e-16"


@dataclass
class MpEvent:
    """One event of the independent solution: time and state after it (mpf), kind, and for an
    accumulation the change of its extrapolated time from the one before (an error scale)."""

    t: mpmath.mpf
    kind: str
    x: mpmath.mpf
    v: mpmath.mpf
    err: mpmath.mpf | None = None


class _Flight:
    """The closed-form free motion from ``(t0, x0, v0)`` (see the module docstring)."""

    def __init__(self, ctx, t0, x0, v0, zeta, F, w) -> None:
        self.ctx, self.t0, self.w = ctx, t0, w
        self.z = F / ctx.mpc(1 - w**2, 2 * zeta * w)
        self.lam = ctx.mpc(-zeta, ctx.sqrt(1 - zeta**2))
        e = ctx.expj(w * t0)
        xp, vp = (self.z * e).real, (1j * w * self.z * e).real
        # x_h = Re(c e^(lam s)), v_h = Re(c lam e^(lam s)); at s = 0: cr and cr lr - ci li
        lr, li = self.lam.real, self.lam.imag
        cr = x0 - xp
        self.c = ctx.mpc(cr, (cr * lr - (v0 - vp)) / li)
        self.abs_z, self.abs_c = abs(self.z), abs(self.c)

    def derivatives(self, t, count: int) -> list:
        """``x, x', ..., x^(count - 1)`` at ``t``."""
        fp = self.z * self.ctx.expj(self.w * t)
        fh = self.c * self.ctx.exp(self.lam * (t - self.t0))
        out = []
        for _ in range(count):
            out.append(fp.real + fh.real)
            fp, fh = fp * 1j * self.w, fh * self.lam
        return out

    def state(self, t) -> tuple:
        x, v = self.derivatives(t, 2)
        return x, v

    def bound_of(self, k: int):
        """A bound of ``|x^(k)|`` over the whole flight (``|lam| = 1``, ``|e^(lam s)| <= 1``)."""
        return self.w**k * self.abs_z + self.abs_c


def _first_zero(ctx, flight: _Flight, sigma, t_start, x_start, v_start, t_end):
    """The first time in ``(t_start, t_end]`` where the gap ``sigma - x`` reaches zero, or ``None``.

    The flight starts at ``(x_start, v_start)``: off the stop, or on it leaving (``v_start < 0``) or
    at rest (a release, where the pressing force has just turned).
    """

    def gap(t):
        x, v = flight.state(t)
        return sigma - x, -v

    m2 = flight.bound_of(2)
    if x_start < sigma:
        a = t_start
    elif v_start < 0:  # leaves with speed u = -v: g >= u s - m2 s^2 / 2 > 0 on (0, 2 u / m2)
        a = t_start - v_start / m2
    else:  # leaves at rest: g >= g3 s^3 / 6 - m4 s^4 / 24 > 0 on (0, 4 g3 / m4)
        g3 = -flight.derivatives(t_start, 4)[3]
        if not (v_start == 0 and g3 > 0):
            raise AssertionError(f"a flight that does not leave the stop: v = {v_start}, g3 = {g3}")
        a = t_start + 2 * g3 / flight.bound_of(4)
    ga, _ = gap(a)
    assert ga > 0
    h_max = ctx.mpf("0.05")
    while a < t_end:
        h = min(h_max, ctx.sqrt(4 * ga / m2), t_end - a)
        b = a + h
        gb, _ = gap(b)
        if gb > 0 and min(ga, gb) > m2 * h * h / 8:
            a, ga = b, gb  # no zero in [a, b]: the gap stays above its chord minus the margin
            continue
        hit = _leftmost(ctx, gap, m2, a, b, ga, gb)
        if hit is not None:
            return hit
        a, ga = b, gb
    return None


def _leftmost(ctx, gap, m2, a, b, ga, gb, depth: int = 0):
    """The first zero of the gap in ``(a, b]`` (``ga > 0``), by halving with the chord test, or ``None``."""
    if gb <= 0:
        return _refine(ctx, gap, a, b)
    if min(ga, gb) > m2 * (b - a) ** 2 / 8:
        return None
    if depth > ctx.prec:  # a touch below the working precision: not resolved here
        raise AssertionError(f"an unresolved grazing near t = {a}")
    m = (a + b) / 2
    gm, _ = gap(m)
    if gm <= 0:
        return _refine(ctx, gap, a, m)
    left = _leftmost(ctx, gap, m2, a, m, ga, gm, depth + 1)
    return left if left is not None else _leftmost(ctx, gap, m2, m, b, gm, gb, depth + 1)


def _refine(ctx, gap, lo, hi):
    """The zero of the gap in ``(lo, hi]`` with ``gap(lo) > 0 >= gap(hi)``: Newton inside the bracket."""
    width0 = hi - lo
    x = (lo + hi) / 2
    for _ in range(4 * ctx.prec):
        g, dg = gap(x)
        if g == 0:
            return x
        if g > 0:
            lo = x
        else:
            hi = x
        nxt = x - g / dg if dg != 0 else None
        if nxt is None or not lo < nxt < hi:
            nxt = (lo + hi) / 2
        if abs(nxt - x) <= width0 * ctx.eps * 16 or hi - lo <= width0 * ctx.eps * 16:
            return nxt
        x = nxt
    return hi


def _release_after(ctx, t, sigma, F, w):
    """The first time after ``t`` where ``P = -sigma + F cos(w t)`` falls through zero (closed form)."""
    phase = ctx.acos(sigma / F)  # w t = phase + 2 pi n, where sin(w t) > 0: P decreasing
    n = ctx.ceil((w * t - phase) / (2 * ctx.pi))
    t_rel = (phase + 2 * ctx.pi * n) / w
    if t_rel <= t:
        t_rel += 2 * ctx.pi / w
    return t_rel


def impact_oscillator_events(problem, t_end: float, dps: int = 60) -> list[MpEvent]:
    """The event log of ``problem`` (an ``impact-oscillator``) over ``[0, t_end]`` in ``dps`` digits.

    Kinds as nsbench names them: ``impact``, ``stick`` (the accumulation of a chattering sequence, or a
    start at rest pressed on the stop), ``release``. Parameters are the problem's doubles, taken exactly.
    """
    ctx = mpmath.MPContext()
    ctx.dps = dps
    f = lambda name: ctx.mpf(float(problem.parameters[name]))  # noqa: E731
    zeta, F, w, sigma, r = f("zeta"), f("F"), f("w"), f("sigma"), f("r")
    t_stop = ctx.mpf(float(t_end))
    stop_interval = ctx.mpf(STOP_INTERVAL)

    def pressing(t):
        return -sigma + F * ctx.cos(w * t)

    t, x, v = ctx.zero, f("x0"), f("v0")
    events: list[MpEvent] = []
    stuck = x == sigma and v == 0 and pressing(t) > 0
    streak: list = []  # impact times of the current chattering sequence
    while True:
        if stuck:
            t = _release_after(ctx, t, sigma, F, w)
            if t > t_stop:
                return events
            x, v = sigma, ctx.zero
            events.append(MpEvent(t, "release", x, v))
            stuck, streak = False, []
            continue
        flight = _Flight(ctx, t, x, v, zeta, F, w)
        hit = _first_zero(ctx, flight, sigma, t, x, v, t_stop)
        if hit is None:
            return events
        x_hit, v_hit = flight.state(hit)
        t, x, v = hit, sigma, -r * v_hit
        streak.append(t)
        if len(streak) >= 2 and streak[-1] - streak[-2] < stop_interval and pressing(t) > 0:
            assert len(streak) >= 5, "a chattering sequence too short to extrapolate"
            z_now, z_before = _aitken(streak[-3:]), _aitken(streak[-4:-1])
            assert z_now < _release_after(ctx, t, sigma, F, w), "the force turns inside the tail"
            if z_now > t_stop:
                return events
            t, x, v = z_now, sigma, ctx.zero
            events.append(MpEvent(t, "stick", x, v, err=abs(z_now - z_before)))
            stuck = True
            continue
        events.append(MpEvent(t, "impact", x, v))


def _aitken(times):
    """Aitken's extrapolation of three times: ``t2 + d2 q / (1 - q)``, ``q = d2 / d1``."""
    t0, t1, t2 = times
    d1, d2 = t1 - t0, t2 - t1
    q = d2 / d1
    return t2 + d2 * q / (1 - q)


def bouncing_ball_events(problem, count: int, dps: int = 60) -> tuple[list, object]:
    """The first ``count`` impact times and the rest time ``t_Z`` of ``problem`` (a ``bouncing-ball``), mpf."""
    ctx = mpmath.MPContext()
    ctx.dps = dps
    p = {k: ctx.mpf(float(v)) for k, v in problem.parameters.items()}
    g, e, x0, v0 = p["g"], p["e"], p["x0"], p["v0"]
    v1 = ctx.sqrt(v0 * v0 + 2 * g * x0)
    t1 = (v0 + v1) / g
    times, t = [t1], t1
    for k in range(1, count):
        t += 2 * v1 * e**k / g
        times.append(t)
    return times, t1 + 2 * e * v1 / (g * (1 - e))
