"""``exact-mp``: the closed-form flow of each mode of a linear problem, in extended precision (mpmath).

``exact`` evaluates the closed form of each mode in double precision and hands
the state to the next arc as doubles; on an ill-conditioned case the rounding of
every arc is amplified (at the forced point of ``tests/integrators/test_exact_mp.py``
its event times are 3.4e-9 off by ``tau`` 300). ``exact-mp`` keeps time and state
in ``digits`` decimal digits (mpmath) from the start of a run to its end, never
passing through a double between arcs, so it can certify ``exact`` and
``heyoka-q``. Python per arc, no compiled kernel.

The flow of a mode
------------------
On the augmented state ``z = [y, 1, cos w t, sin w t]`` (``[y, 1]`` without
forcing) each mode is ``z' = M z``, every guard is a row ``q`` with value
``q . z`` and every state section a row too. The option ``model`` says where
``M`` and the rows come from:

- ``'coefficients'`` (default): the problem's coefficients (doubles, taken
  exactly) through its own force code (``restoring_forces``) and the slip and
  stick laws of MODEL.md, all in mp. This is the problem of MODEL.md with those
  coefficients, the one ``heyoka-q`` integrates.
- ``'linear-form'``: the doubles of ``problem.linear_form(mode)`` and
  :func:`nsbench.integrators.exact.guard_row`, taken exactly: the problem
  ``exact`` and ``tests/mp_reference.py`` solve. ``linear_form`` rounds each
  entry once (``k / m``, ``fs / m`` in double), so the two models coincide when
  the masses are 1 (the dimensionless presets) and differ by such roundings
  otherwise.

The arc advances on a grid of steps ``h`` (a power of two with
``||M||_D h <= 1/2``, ``D`` the diagonal balancing of ``M``) by the step
propagator ``Phi = expm(M h)``, computed once per mode as its Taylor series,
truncated below ``10^-(digits+3)``.

No crossing is missed
---------------------
On a step the signed guard ``phi(s) = sign * q . expm(M s) z_k`` has
``phi'' = sign * q M^2 z(s)``; in the balanced norm ``||z||_D = max |z_i| / D_i``,
``||expm(M s)||_D <= exp(||M||_D s) <= e^(1/2)``, so on the whole step
``|phi''| <= B = ||q M^2 D||_1 exp(||M||_D h) ||z_k||_D``. Taylor's theorem
from both ends of the step bounds ``phi`` from below everywhere on it::

    phi(s) >= max(phi(0) + phi'(0) s - B s^2 / 2,  phi(h) - phi'(h) (h - s) - B (h - s)^2 / 2)

and the smallest value of that maximum over the step is at least the smallest
of ``phi(0)``, ``phi(h)`` and the two parabolas at any split point (the best one
is where they meet; any other is still a valid bound). If it is positive (with
a relative margin of 1e-12 that covers the rounding of this test, done in
double from the mp values), ``phi`` has no zero on the step: no crossing and no
touch (a grazing, where ``phi`` only touches zero between two step ends, needs
``phi = 0`` somewhere, which the bound excludes). When that fails, the same
four numbers give the cubic Hermite interpolant ``H`` of ``phi``, with
``|phi - H| <= h^4 B4 / 384`` (``B4`` the same bound for ``q M^4``); the
smallest Bernstein coefficient of ``H`` (split at its minimum) minus that is
another rigorous lower bound, much tighter on short steps. Only steps that
fail both are searched: on the guard's Taylor polynomial on the step
(``sum_j (q M^j z_k) s^j / j!``, truncated below ``10^-(digits+3)`` of the
guard's scale), with the first test on halves, leftmost half first, and the
exact curvature bound of the polynomial on each half, so the zero found is the
first one; a half whose derivative is negative throughout holds a single zero,
refined by Newton's method inside its bracket to the working precision. Halves
narrower than ``2^-(prec/2)`` of the step are decided by the sign change of
``phi'`` (a touch). What cannot be resolved is a touch shallower than the
rounding of the guard (``10^-digits`` of its scale): the working precision's
own limit. The arc ends at the first zero of ``expected_sign * guard`` over all
guards (a tie goes to the lowest index); a phase that starts on its own
surface (``phi(0) = 0``) is positive on ``(0, phi'(0) / B]`` and searched from
there.

Time, carry, sections, dense states
-----------------------------------
An arc starts at the exact sum ``t0 + t0_lo`` (or at the kept mp time, below)
and returns ``t = float(T)``, ``t_lo = float(T - t)``. Like the extended
precisions of heyoka (:mod:`nsbench.integrators.heyoka_`), the mp time and
augmented state where an arc stopped at an event are kept; when the next
request starts at that arc's returned ``(t, t_lo)`` with its returned double
state, up to velocities the transition set to exactly ``v0``, the arc continues
from the kept state with those velocities set to ``v0`` in mp. Any other
request starts from its doubles. State sections are found with the same
exclusion test and bisection/Newton on the polynomial, never stopping the arc.
States at ``t_eval`` need double accuracy only: they come from a double Taylor
series of the flow from the mp state at the step's start.

Counters: ``nsteps`` propagation steps; ``nfev`` the matrix-vector products
in mp (with ``Phi`` or ``M``: each one evaluates the flow or the field of the
augmented system once; no right-hand side is called), also reported as
``extra['mp_matvecs']``; ``extra['careful_steps']`` guard or section searches on
a step's Taylor polynomial, ``extra['roots']`` roots refined.
"""

from __future__ import annotations

import math
from typing import Any

import mpmath
import numpy as np

from nsbench.integrators._carry import reset_velocities
from nsbench.integrators.base import ArcRequest, ArcResult, Capabilities, Integrator, Option, SectionHit
from nsbench.problems.base import problem_traits
from nsbench.problems.modes import Mode
from nsbench.problems.oscillator import FrictionOscillator
from nsbench.status import Status

#: Inflation of every bound computed in double (norms, exponentials) so that rounding cannot shrink it.
_SAFETY = 1.0 + 1e-9
#: Relative margin of the double-precision exclusion test (its rounding is ~1e-15 of the scale).
_MARGIN = 1e-12
#: Largest step of a slow mode (time units).
_H_MAX = 1.0
#: Terms of the double Taylor series for ``t_eval`` states (``0.5^18 / 18!`` ~ 6e-22).
_DENSE_TERMS = 18
#: Interval halvings allowed in one search before the arc is declared a failure.
_MAX_SPLITS = 20000
#: Extra decimal digits below ``digits`` for Taylor truncations.
_TAIL_DIGITS = 3


# ---------------------------------------------------------------------- double-precision bounds
def _lower_bound(fa: float, pa: float, fb: float, pb: float, w: float, b: float) -> float:
    """A lower bound of ``phi`` on ``[0, w]`` from its values and slopes at both ends and ``|phi''| <= b``.

    ``phi >= l0 = fa + pa s - b s^2/2`` and ``phi >= l1 = fb - pb (w - s) - b (w - s)^2/2``
    everywhere, so for any split ``u`` the minimum is at least that of ``l0`` on
    ``[0, u]`` and of ``l1`` on ``[u, w]``; both are concave, so their minima are at
    the ends. The split where ``l0 = l1`` is the tightest.
    """
    alpha = fa - fb + pb * w + 0.5 * b * w * w  # l0 - l1 = alpha + beta s
    beta = pa - pb - b * w
    u = -alpha / beta if beta != 0.0 else 0.5 * w
    u = min(max(u, 0.0), w) if math.isfinite(u) else 0.5 * w  # any split is valid
    r = w - u
    return min(fa, fb, fa + pa * u - 0.5 * b * u * u, fb - pb * r - 0.5 * b * r * r)


def _clear(fa: float, pa: float, fb: float, pb: float, w: float, b: float) -> bool:
    """Whether ``phi`` (positive at both ends) provably has no zero on the interval."""
    if not (fa > 0.0 and fb > 0.0):
        return False
    scale = fa + fb + (abs(pa) + abs(pb)) * w + b * w * w
    return _lower_bound(fa, pa, fb, pb, w, b) > _MARGIN * scale


def _hermite_clear(fa: float, pa: float, fb: float, pb: float, w: float, b4: float) -> bool:
    """Whether ``phi`` has no zero on ``[0, w]``, from its cubic Hermite interpolant and ``|phi^(4)| <= b4``.

    ``|phi - H| <= s^2 (w - s)^2 / 4! max |phi^(4)| <= w^4 b4 / 384`` (Hermite's error formula), and
    the cubic ``H`` is at least the smallest Bernstein control point of its two pieces split near its
    minimum (the convex hull property: a valid bound at any split, tight at the minimum). Much
    tighter than :func:`_clear` on short steps (``w^4`` against ``w^2``); tried when that one fails.
    """
    if not (fa > 0.0 and fb > 0.0):
        return False
    c0, c1, c2, c3 = fa, fa + w * pa / 3.0, fb - w * pb / 3.0, fb
    d0, d1, d2 = c1 - c0, c2 - c1, c3 - c2
    qa, qb = d0 - 2.0 * d1 + d2, 2.0 * (d1 - d0)  # H'/3 = qa t^2 + qb t + d0
    split = 0.5
    disc = qb * qb - 4.0 * qa * d0
    if qa != 0.0 and disc >= 0.0:
        roots = [(-qb - math.sqrt(disc)) / (2.0 * qa), (-qb + math.sqrt(disc)) / (2.0 * qa)]
        inside = [t for t in roots if 0.0 < t < 1.0]
        if inside:
            split = min(inside, key=lambda t: _bernstein(c0, c1, c2, c3, t)[-1])
    elif qa == 0.0 and qb != 0.0 and 0.0 < -d0 / qb < 1.0:
        split = -d0 / qb
    err = w**4 * b4 / 384.0
    scale = fa + fb + (abs(pa) + abs(pb)) * w + err
    return min(c0, c3, *_bernstein(c0, c1, c2, c3, split)) - err > _MARGIN * scale


def _bernstein(c0: float, c1: float, c2: float, c3: float, t: float) -> tuple[float, ...]:
    """De Casteljau at ``t``: the inner control points of both pieces, the curve value last."""
    u = 1.0 - t
    a01, a12, a23 = u * c0 + t * c1, u * c1 + t * c2, u * c2 + t * c3
    a012, a123 = u * a01 + t * a12, u * a12 + t * a23
    return a01, a012, a123, a23, u * a012 + t * a123


def _decreasing(pa: float, pb: float, w: float, b: float) -> bool:
    """Whether ``phi' < 0`` throughout ``[0, w]``.

    ``phi' <= min(pa + b s, pb + b (w - s))``, whose largest value is ``(pa + pb + b w) / 2``.
    """
    top = pa + pb + b * w
    return top < -_MARGIN * (abs(pa) + abs(pb) + b * w)


def _taylor_terms(rho: float, digits: int) -> int:
    """Smallest ``J`` with ``2 rho^(J+1) / (J+1)! <= 10^-(digits + 3)`` (``rho <= 1/2``): the series' tail."""
    target = -(digits + _TAIL_DIGITS) * math.log(10.0)
    log_rho = math.log(max(rho, 1e-300))
    j = 1
    while math.log(2.0) + (j + 1) * log_rho - math.lgamma(j + 2) > target:
        j += 1
    return j


# ---------------------------------------------------------------------- a polynomial on one step
class _Poly:
    """``P(s) = sum_j c_j s^j`` (mp coefficients), a guard or section on one step.

    ``c_j = q M^j z / j!``, so ``|c_j| <= ||q D||_1 ||z||_D nu^j / j!`` (``nu = ||M||_D``): at a point
    ``s`` of the step the terms past :func:`_taylor_terms` ``(nu s)`` sum to below ``10^-(digits+3)`` of
    that scale, the truncation the series already has at the step's end, and are not evaluated (a
    short flight after an impact is evaluated on a handful of terms, not on the step's whole series).
    """

    __slots__ = ("c", "abs2", "tail2", "nu", "digits")

    def __init__(self, coeffs: list, tail2: float, nu: float = math.inf, digits: int = 0) -> None:
        self.c = coeffs
        # |c_j| j (j - 1), inflated: the curvature bound on [0, b] is a polynomial in b
        self.abs2 = [abs(float(c)) * j * (j - 1) * _SAFETY for j, c in enumerate(coeffs)]
        self.tail2 = tail2
        self.nu, self.digits = nu, digits

    def _top(self, s) -> int:
        """Index of the last term worth evaluating at ``s``."""
        rho = self.nu * abs(float(s))
        if not rho < 0.5:
            return len(self.c) - 1
        return min(len(self.c) - 1, _taylor_terms(rho, self.digits) + 1)

    def value(self, s):
        top = self._top(s)
        acc = self.c[top]
        for c in reversed(self.c[:top]):
            acc = acc * s + c
        return acc

    def value_rate(self, s):
        """``(P(s), P'(s))`` by Horner's scheme."""
        top = self._top(s)
        p = self.c[top]
        dp = p * 0
        for c in reversed(self.c[:top]):
            dp = dp * s + p
            p = p * s + c
        return p, dp

    def curvature(self, b: float) -> float:
        """A bound of ``|P''|`` (and of the truncated series' second derivative) on ``[0, b]``."""
        acc = 0.0
        for a2 in reversed(self.abs2[2:]):
            acc = acc * b + a2
        return acc * _SAFETY + self.tail2

    def negated(self) -> "_Poly":
        other = _Poly.__new__(_Poly)
        other.c = [-c for c in self.c]
        other.abs2, other.tail2, other.nu, other.digits = self.abs2, self.tail2, self.nu, self.digits
        return other


# ---------------------------------------------------------------------- zeros of a polynomial
class _Search:
    """Zeros of step polynomials at the working precision: first zero (guards), all sign changes (sections)."""

    def __init__(self, ctx, min_width, tol) -> None:
        self.ctx = ctx
        self.min_width = min_width  # narrowest interval that is still halved (mp)
        self.tol = tol  # absolute resolution of a root (mp)
        self.splits = 0
        self.roots = 0

    def _halve(self, poly: _Poly, a, b):
        self.splits += 1
        if self.splits > _MAX_SPLITS:
            raise ArithmeticError(f"no decision after {_MAX_SPLITS} interval halvings")
        m = a + (b - a) / 2
        return (m, *poly.value_rate(m))

    def first_zero(self, poly: _Poly, a, b, fa, pa, fb, pb):
        """First ``s`` in ``(a, b]`` with ``P(s) <= 0``, given ``P(a) > 0``; ``None`` if there is none."""
        stack = [(a, b, fa, pa, fb, pb)]
        while stack:
            a, b, fa, pa, fb, pb = stack.pop()
            w = float(b - a)
            curv = poly.curvature(float(b))
            fa_f, pa_f, fb_f, pb_f = float(fa), float(pa), float(fb), float(pb)
            if fb > 0 and _clear(fa_f, pa_f, fb_f, pb_f, w, curv):
                continue
            if fb <= 0 and _decreasing(pa_f, pb_f, w, curv):
                return self.refine(poly, a, b)  # the only zero of the interval
            if b - a <= self.min_width:
                hit = self._touch(poly, a, b, fa, pa, fb, pb)
                if hit is not None:
                    return hit
                continue
            m, fm, pm = self._halve(poly, a, b)
            if fm > 0:  # the right half waits below the left one: leftmost first
                stack.append((m, b, fm, pm, fb, pb))
            stack.append((a, m, fa, pa, fm, pm))
        return None

    def _touch(self, poly: _Poly, a, b, fa, pa, fb, pb):
        """A zero in a narrowest interval: a sign change, or a minimum at or below zero (found through ``P'``)."""
        if fb <= 0:
            return self.refine(poly, a, b)
        if pa < 0 < pb:
            lo, hi = a, b
            for _ in range(self.ctx.prec):
                mid = lo + (hi - lo) / 2
                if poly.value_rate(mid)[1] < 0:
                    lo = mid
                else:
                    hi = mid
                if hi - lo <= self.tol:
                    break
            f_min = poly.value(hi)
            if f_min <= 0:
                return hi if f_min == 0 else self.refine(poly, a, hi)
        return None

    def refine(self, poly: _Poly, lo, hi):
        """A zero of ``P`` in ``(lo, hi]`` with ``P(lo) > 0 >= P(hi)``: Newton's method kept in the bracket."""
        self.roots += 1
        x = lo + (hi - lo) / 2
        for _ in range(4 * self.ctx.prec):
            f, p = poly.value_rate(x)
            if f == 0:
                return x
            if f > 0:
                lo = x
            else:
                hi = x
            step = f / p if p != 0 else None
            nxt = x - step if step is not None else None
            if nxt is None or not lo < nxt < hi:
                nxt = lo + (hi - lo) / 2
            if abs(nxt - x) <= self.tol or hi - lo <= self.tol:
                return nxt if lo < nxt <= hi else hi
            x = nxt
        return hi

    def leave_surface(self, poly: _Poly, b, pa, noise_p: float):
        """For a guard exactly on its surface at 0: ``(u, P(u), P'(u))`` with ``P > 0`` on ``(0, u]``,
        ``'clear'`` if that holds on all of ``(0, b]``, or ``None`` if it goes to the wrong side at once.

        ``P >= P'(0) s - B s^2 / 2 > 0`` on ``(0, P'(0) / B]`` (``B`` the curvature bound).
        A start with ``|P'(0)|`` at rounding level is degenerate: the first positive sample is taken.
        """
        ctx = self.ctx
        pa_f = float(pa)
        if pa_f > noise_p:
            curv = poly.curvature(float(b))
            u = pa_f / curv * (1.0 - 1e-9) if curv > 0 else math.inf
            if u >= float(b):
                return "clear"
            u = ctx.mpf(u)
            fu, pu = poly.value_rate(u)
            if fu > 0:
                return u, fu, pu
        elif pa_f < -noise_p:
            return None
        for k in range(1, 65):  # degenerate start (P'(0) ~ 0): the first sample off the surface
            s = b * k / 64
            fs, ps = poly.value_rate(s)
            if fs > 0:
                return s, fs, ps
            if fs < 0:
                return None
        return None

    def sign_changes(self, poly: _Poly, a, b, fa, pa, fb, pb) -> list[tuple[Any, Any, Any, Any]]:
        """Brackets ``(lo, hi, P(lo), P(hi))`` of every sign change of ``P`` on ``(a, b]``, in time order.

        ``P(a) != 0``. Intervals the exclusion test clears hold none; a sign change with
        a monotone ``P`` holds one; two crossings closer than the narrowest interval
        cancel (sections only need double accuracy).
        """
        out = []
        stack = [(a, b, fa, pa, fb, pb)]
        while stack:
            a, b, fa, pa, fb, pb = stack.pop()
            sgn = 1.0 if fa > 0 else -1.0
            w = float(b - a)
            curv = poly.curvature(float(b))
            fa_f, pa_f, fb_f, pb_f = sgn * float(fa), sgn * float(pa), sgn * float(fb), sgn * float(pb)
            if _clear(fa_f, pa_f, fb_f, pb_f, w, curv):
                continue
            changes = fb_f <= 0.0
            if changes and _decreasing(pa_f, pb_f, w, curv):
                out.append((a, b, fa, fb))
                continue
            if b - a <= self.min_width:
                if changes:
                    out.append((a, b, fa, fb))
                continue
            m, fm, pm = self._halve(poly, a, b)
            if fm == 0:  # lands exactly on the section at m: the left half ends there, the right one leaves it
                start = self.leave_section(poly, m, b, pm)
                if start is not None:
                    stack.append((*start, fb, pb))
            else:
                stack.append((m, b, fm, pm, fb, pb))
            stack.append((a, m, fa, pa, fm, pm))
        return out

    def leave_section(self, poly: _Poly, a, b, pa):
        """For ``P(a) = 0``: ``(u, P(u), P'(u))`` with ``P(u) != 0`` and no crossing in ``(a, u)``, or ``None``."""
        curv = poly.curvature(float(b))
        pa_f = abs(float(pa))
        if pa_f > 0:
            u = pa_f / curv * (1.0 - 1e-9) if curv > 0 else math.inf
            if u >= float(b - a):
                return None  # one sign on all of (a, b]: no crossing
            u = a + self.ctx.mpf(u)
            fu, pu = poly.value_rate(u)
            if fu != 0 and (fu > 0) == (pa > 0):
                return u, fu, pu
        for k in range(1, 65):
            s = a + (b - a) * k / 64
            fs, ps = poly.value_rate(s)
            if fs != 0:
                return s, fs, ps
        return None

    def root(self, poly: _Poly, lo, hi, f_lo, f_hi):
        """The zero of a sign-change bracket (either orientation)."""
        if f_hi == 0:
            self.roots += 1
            return hi
        return self.refine(poly if f_lo > 0 else poly.negated(), lo, hi)


# ---------------------------------------------------------------------- the problem in mp
def _friction(problem) -> bool:
    return problem_traits(problem).belt_blocks


def _forced(problem) -> bool:
    """Whether the modes carry ``cos w t, sin w t`` (the friction family says so by its force ``F``)."""
    if _friction(problem):
        return problem.coefficients.F != 0.0
    return bool(problem.is_forced and problem.forcing_frequency != 0.0)


def _frequency(problem) -> float:
    return float(problem.coefficients.w) if _friction(problem) else float(problem.forcing_frequency)


class _Model:
    """A linear problem's modes in mp: the augmented matrix ``M`` and the guard rows.

    ``z = [y, 1, cos w t, sin w t]`` (``[y, 1]`` without forcing). Two sources
    (the option ``model``): the problem's coefficients (:class:`_CoefficientModel`)
    or the doubles of ``problem.linear_form`` and
    :func:`nsbench.integrators.exact.guard_row` (:class:`_LinearFormModel`).
    """

    def __init__(self, ctx, problem: FrictionOscillator) -> None:
        self.ctx, self.problem = ctx, problem
        self.n = problem.n_states
        self.forced = _forced(problem)
        self.d = self.n + 3 if self.forced else self.n + 1

    def _harmonic_rows(self, rows: list) -> None:
        """``cos' = -w sin``, ``sin' = w cos`` in place."""
        if self.forced:
            w = self.ctx.mpf(_frequency(self.problem))
            n = self.n
            rows[n + 1][n + 2], rows[n + 2][n + 1] = -w, w

    def matrix(self, mode: Mode) -> list:  # pragma: no cover - abstract
        raise NotImplementedError

    def guard(self, kind: int, block: int) -> list:  # pragma: no cover - abstract
        raise NotImplementedError


class _LinearFormModel(_Model):
    """``problem.linear_form(mode)`` and ``guard_row``, doubles taken exactly: the problem ``exact`` solves."""

    def matrix(self, mode: Mode) -> list:
        ctx, n = self.ctx, self.n
        a, b0, bc, bs = self.problem.linear_form(tuple(mode))
        rows = [[ctx.zero] * self.d for _ in range(self.d)]
        for i in range(n):
            cols = [*a[i], b0[i], bc[i], bs[i]][: self.d]
            rows[i] = [ctx.mpf(float(v)) for v in cols]
        self._harmonic_rows(rows)
        return rows

    def guard(self, kind: int, block: int) -> list:
        return [self.ctx.mpf(float(v)) for v in self.problem.guard_row((), kind, block)[: self.d]]


class _CoefficientModel(_Model):
    """The modes from the problem's coefficients, in mp: no double rounding between them and the flow.

    The restoring forces ``R_i`` come from the problem's own generic force code
    (:meth:`FrictionOscillator.restoring_forces`, evaluated on mp unit vectors:
    it is linear), the slip law ``m_i v_i' = -R_i - fs_i s_i`` and the stick law
    ``x_i' = v0, v_i' = 0`` of MODEL.md are applied in mp. ``linear_form``
    instead rounds each entry to a double (``k / m``), a different problem by
    an ulp when a mass is not 1.
    """

    def __init__(self, ctx, problem: FrictionOscillator) -> None:
        super().__init__(ctx, problem)
        self.forces = self._force_rows()

    def _force_rows(self) -> list:
        """``R_i`` as rows over ``z`` (mp), one per block."""
        ctx, n, d = self.ctx, self.n, self.d
        nb = self.problem.n_blocks

        def forces(j: int) -> list:  # R at the unit vector e_j of z
            z = [ctx.zero] * d
            z[j] = ctx.one
            cos_value = z[n + 1] if self.forced else ctx.zero
            return self.problem.restoring_forces(ctx.zero, z[0:n:2], z[1:n:2], cos=lambda _arg: cos_value)

        columns = [forces(j) if j < n or j == n + 1 else [ctx.zero] * nb for j in range(d)]
        return [[ctx.mpf(columns[j][i]) for j in range(d)] for i in range(nb)]

    def matrix(self, mode: Mode) -> list:
        from nsbench.problems.modes import STICK

        ctx, n = self.ctx, self.n
        c = self.problem.coefficients
        rows = [[ctx.zero] * self.d for _ in range(self.d)]
        for i, phase in enumerate(mode):
            if phase == STICK:  # moves with the belt
                rows[2 * i][n] = ctx.mpf(float(c.v0))
                continue
            m = ctx.mpf(float(c.m[i]))
            rows[2 * i][2 * i + 1] = ctx.one
            rows[2 * i + 1] = [-r / m for r in self.forces[i]]
            rows[2 * i + 1][n] = -ctx.mpf(float(c.fs[i])) * phase / m
        self._harmonic_rows(rows)
        return rows

    def guard(self, kind: int, block: int) -> list:
        from nsbench.problems.friction_spec import UPPER, VELOCITY

        ctx, n = self.ctx, self.n
        c = self.problem.coefficients
        if kind == VELOCITY:
            q = [ctx.zero] * self.d
            q[2 * block + 1], q[n] = ctx.one, -ctx.mpf(float(c.v0))
            return q
        q = list(self.forces[block])
        limit = ctx.mpf(float(c.fr[block]))
        q[n] = -limit if kind == UPPER else limit
        return q


MODELS = {"coefficients": _CoefficientModel, "linear-form": _LinearFormModel}


# ---------------------------------------------------------------------- one mode
class _Row:
    """A guard or section row ``q`` (mp) of a mode with what its tests need."""

    __slots__ = ("q", "qm", "curv", "curv4", "norm", "norm1", "taylor")

    def __init__(self, flow: "_ModeFlow", q: list) -> None:
        self.q = q
        self.qm = flow.row_times(self.q)
        qm2 = flow.row_times(self.qm)
        d = flow.scale
        self.norm = _SAFETY * sum(abs(float(v)) * d[i] for i, v in enumerate(self.q))
        self.norm1 = _SAFETY * sum(abs(float(v)) * d[i] for i, v in enumerate(self.qm))
        self.curv = _SAFETY * sum(abs(float(v)) * d[i] for i, v in enumerate(qm2))  # ||q M^2 D||_1
        qm4 = flow.row_times(flow.row_times(qm2))
        self.curv4 = _SAFETY * sum(abs(float(v)) * d[i] for i, v in enumerate(qm4))  # ||q M^4 D||_1
        self.taylor: list | None = None  # q M^j / j!, j = 0..J, built on first use


class _ModeFlow:
    """The augmented linear flow ``z' = M z`` of one mode in mp, its step propagator and its rows."""

    def __init__(self, ctx, rows: list, n: int, digits: int) -> None:
        from scipy.linalg import matrix_balance

        self.ctx, self.n, self.d = ctx, n, len(rows)
        self.rows = rows
        self.cols = [list(col) for col in zip(*rows)]
        m = np.array([[float(v) for v in row] for row in rows])
        self.m_double = m  # for bounds, balancing and dense double states only
        _, (scale, _) = matrix_balance(m, permute=False, separate=True)
        self.scale = np.asarray(scale, dtype=float)
        self.norm = _SAFETY * float(np.max(np.abs(m) @ self.scale / self.scale))  # ||M||_D
        h = _H_MAX if self.norm == 0.0 else min(_H_MAX, 2.0 ** math.floor(math.log2(0.5 / self.norm)))
        self.h = ctx.mpf(h)  # a power of two: step grids k h are exact
        self.rho = self.norm * h
        self.digits = digits
        self.terms = _taylor_terms(self.rho, digits)
        # the truncated series' second derivative on a step, per unit of ||q D||_1 ||z||_D
        j = self.terms
        log_rho = math.log(max(self.rho, 1e-300))
        self.tail2 = 2.0 * self.norm**2 * math.exp((j - 1) * log_rho - math.lgamma(j))
        self.phi = self._propagator()
        self._rows: dict[Any, _Row] = {}
        self.matvecs = 0

    # -- mp linear algebra on lists
    def row_times(self, q: list) -> list:
        """``q M`` for a row ``q``."""
        fdot = self.ctx.fdot
        return [fdot(q, col) for col in self.cols]

    def times(self, rows: list, z: list) -> list:
        """``rows @ z``."""
        fdot = self.ctx.fdot
        self.matvecs += 1
        return [fdot(r, z) for r in rows]

    def _propagator(self) -> list:
        """``expm(M h)`` as its Taylor series (``||M h||_D <= 1/2``: the tail is below ``10^-(digits+3)``)."""
        ctx, d = self.ctx, self.d
        fdot = ctx.fdot
        eye = [[ctx.one if i == j else ctx.zero for j in range(d)] for i in range(d)]
        term = [row[:] for row in eye]
        acc = [row[:] for row in eye]
        for j in range(1, self.terms + 1):
            factor = self.h / j
            term = [[fdot(r, col) * factor for col in self.cols] for r in term]
            acc = [[x + y for x, y in zip(ra, rt)] for ra, rt in zip(acc, term)]
        return acc

    def row(self, key, make) -> _Row:
        """The row under ``key``, built from ``make()`` (an mp list) on first use."""
        found = self._rows.get(key)
        if found is None:
            found = self._rows[key] = _Row(self, make())
        return found

    def step(self, z: list) -> list:
        """``Phi z``: the state one full step later."""
        return self.times(self.phi, z)

    def state_at(self, z: list, s) -> list:
        """``expm(M s) z`` for ``0 <= s <= h`` by its Taylor series."""
        if s == 0:
            return list(z)
        # a short time needs fewer terms for the same truncation (below 10^-(digits+3), as the step's)
        terms = min(self.terms, _taylor_terms(self.norm * abs(float(s)), self.digits)) if self.norm > 0 else 1
        vecs = [list(z)]
        for j in range(1, terms + 1):
            v = self.times(self.rows, vecs[-1])
            vecs.append([x / j for x in v])
        acc = vecs[-1]
        for v in reversed(vecs[:-1]):
            acc = [a * s + b for a, b in zip(acc, v)]
        return acc

    def znorm(self, z: list) -> float:
        """``||z||_D = max |z_i| / D_i``, rounded up."""
        return _SAFETY * max(abs(float(v)) / self.scale[i] for i, v in enumerate(z))

    def curvature(self, row: _Row, zn: float, length: float, order: int = 2) -> float:
        """A bound of the row's 2nd (or 4th) derivative on ``[0, length]`` from ``z`` with ``||z||_D = zn``."""
        norm = row.curv if order == 2 else row.curv4
        return norm * math.exp(self.norm * length) * _SAFETY * zn

    def poly(self, row: _Row, z: list, sign: int, zn: float) -> _Poly:
        """The row's Taylor polynomial on the step from ``z``, times ``sign``."""
        ctx = self.ctx
        if row.taylor is None:
            rows = [row.q]
            for j in range(1, self.terms + 1):
                rows.append([x / j for x in self.row_times(rows[-1])])
            row.taylor = rows
        fdot = ctx.fdot
        coeffs = [fdot(r, z) for r in row.taylor]
        if sign < 0:
            coeffs = [-c for c in coeffs]
        return _Poly(coeffs, row.norm * zn * self.tail2, self.norm, self.digits)

    def dense(self, z: list, offsets: np.ndarray) -> np.ndarray:
        """States ``(n, k)`` at ``offsets`` (in ``[0, h]``) from ``z``: a double Taylor series."""
        v = np.array([float(x) for x in z])
        terms = [v]
        for j in range(1, _DENSE_TERMS):
            v = self.m_double @ v / j
            terms.append(v)
        s = np.asarray(offsets, dtype=float)[:, None]
        acc = np.broadcast_to(terms[-1], (s.shape[0], self.d)).copy()
        for t in reversed(terms[:-1]):
            acc = acc * s + t
        return acc[:, : self.n].T


# ---------------------------------------------------------------------- the integrator
class ExactMP(Integrator):
    """Closed-form flow of linear modes in ``digits`` decimal digits (mpmath), rigorous crossing search.

    ``precision = "mp"`` means: time, state and all arithmetic carry ``digits``
    significant decimal digits (mpmath's ``dps``), also across events; Taylor
    truncations stay below ``10^-(digits+3)`` of the quantities' scale.
    See the module docstring for the crossing argument.
    """

    name = "exact-mp"
    capabilities = Capabilities(
        event_location="taylor-bound-root",
        order=None,
        adaptive=False,
        needs_jacobian=False,
        supports_nonlinear=False,
        precision="mp",
        step_option=None,
        reference_grade=True,
        checks_steps=True,
    )
    options = {
        "digits": Option(
            40,
            int,
            lower=20,
            lower_inclusive=True,
            upper=200,
            doc="decimal digits of time, state and arithmetic (mpmath dps)",
        ),
        "model": Option(
            "coefficients",
            str,
            choices=tuple(MODELS),
            doc="the modes from the problem's coefficients in mp ('coefficients'), or the "
            "doubles of problem.linear_form and guard_row taken exactly ('linear-form', "
            "what exact solves)",
        ),
    }

    def setup(self, problem: FrictionOscillator) -> None:
        """Refuse non-linear problems (the base class); a fresh mp context, mode cache and carry for ``problem``.

        A piecewise-linear problem of another family (an impact, a relay) has no
        coefficients in the friction family's sense: its modes are always read from
        ``linear_form`` and ``guard_row`` (the model ``linear-form``).
        """
        super().setup(problem)  # refuses non-linear problems
        self._problem = problem
        self._ctx = mpmath.MPContext()  # private: global mpmath precision is never touched
        self._ctx.dps = int(self.settings["digits"])
        model = self.settings["model"] if _friction(problem) else "linear-form"
        self._model = MODELS[model](self._ctx, problem)
        self._flows: dict[Mode, _ModeFlow] = {}
        self._carry = None

    def __getstate__(self) -> dict[str, Any]:
        """The configuration only: numbers of a private mpmath context do not pickle; ``setup`` rebuilds the rest."""
        state = dict(self.__dict__)
        for key in ("_problem", "_ctx", "_model", "_flows", "_carry"):
            state.pop(key, None)
        return state

    # -- carry across events
    def _continued(self, request: ArcRequest):
        """The kept mp time and state if ``request`` continues the last arc (see heyoka's ``_continued``)."""
        carry = self._carry
        if carry is None:
            return None
        t, t_lo, y_out, time_mp, z = carry
        if not _friction(request.problem):  # only a transition that left the state alone is continued
            same = (
                float(request.t0) == t
                and float(request.t0_lo) == t_lo
                and np.array_equal(np.asarray(request.y0, dtype=float), y_out)
            )
            return (time_mp, list(z)) if same else None
        reset = reset_velocities(request, t, t_lo, y_out)
        if reset is None:
            return None
        z = list(z)
        for j in reset:
            z[j] = self._ctx.mpf(float(request.problem.coefficients.v0))
        return time_mp, z

    def _fresh(self, request: ArcRequest):
        """Start time ``t0 + t0_lo`` (exact) and augmented state from the request's doubles."""
        ctx = self._ctx
        t0 = ctx.fadd(float(request.t0), float(request.t0_lo), exact=True)
        z = [ctx.mpf(float(v)) for v in np.asarray(request.y0, dtype=float)] + [ctx.one]
        if self._model.forced:
            wt = ctx.mpf(_frequency(request.problem)) * t0
            z += [ctx.cos(wt), ctx.sin(wt)]
        return t0, z

    def _flow(self, mode: Mode) -> _ModeFlow:
        flow = self._flows.get(tuple(mode))
        if flow is None:
            flow = self._flows[tuple(mode)] = _ModeFlow(
                self._ctx, self._model.matrix(mode), self._model.n, int(self.settings["digits"])
            )
        return flow

    def _rows(self, request: ArcRequest, flow: _ModeFlow):
        """``[(row, sign)]`` of the guards and ``[row]`` of the sections of the request."""
        ctx, model = self._ctx, self._model
        guards = []
        for g in request.guards:
            key = (g.code, g.block - 1)
            guards.append((flow.row(key, lambda key=key: model.guard(*key)), int(g.expected_sign)))
        sections = []
        for sec in request.sections:
            key = (tuple(float(v) for v in sec.coeffs), float(sec.level))
            q = [*key[0], -key[1]] + [0.0] * (flow.d - flow.n - 1)
            sections.append(flow.row(key, lambda q=q: [ctx.mpf(v) for v in q]))
        return guards, sections

    # -- the arc
    def advance(self, request: ArcRequest) -> ArcResult:
        """One arc in mp (see the module docstring); a numerical failure is returned as a status."""
        problem = request.problem
        if getattr(self, "_problem", None) is not problem:
            self.setup(problem)
        try:
            return _Arc(self, request).run()
        except (ArithmeticError, ValueError) as exc:  # a numerical failure is a status, not an exception
            self._carry = None
            n = problem.n_states
            return ArcResult(
                t=float(request.t0),
                y=np.array(request.y0, dtype=float),
                fired=None,
                y_eval=np.empty((n, 0)),
                status=Status.INTEGRATOR_FAILURE,
                message=f"{self.name}: {type(exc).__name__}: {exc}",
            )


class _Arc:
    """One arc of :class:`ExactMP`: the step loop, its guard and section searches, dense states."""

    def __init__(self, integ: ExactMP, request: ArcRequest, start: tuple | None = None) -> None:
        self.integ, self.request = integ, request
        self.ctx = ctx = integ._ctx
        self.flow = flow = integ._flow(request.mode)
        if start is None:  # an mp start given by the caller (the whole run in mp, below) is used as it is
            start = integ._continued(request)
        integ._carry = None
        self.t0, self.z0 = start if start is not None else integ._fresh(request)
        self.guards, self.sections = integ._rows(request, flow)
        self.span = ctx.mpf(float(request.t_end)) - self.t0
        scale = max(1.0, abs(float(self.t0)) + abs(float(request.t_end)))
        self.search = _Search(
            ctx, min_width=flow.h * ctx.ldexp(1, -(ctx.prec // 2)), tol=ctx.mpf(16.0 * scale) * ctx.eps
        )
        self.noise = 2.0 ** (8 - ctx.prec)  # relative rounding level of an mp guard value
        t_eval = np.asarray(request.t_eval, dtype=float)
        self.t_eval = t_eval
        self.offsets = [ctx.mpf(float(t)) - self.t0 for t in t_eval]  # t_eval from the arc start
        self.rows_eval: list[np.ndarray] = []
        self.hits: list[SectionHit] = []
        self.careful = 0

    # -- per-step pieces
    def _guard_values(self, z):
        fdot = self.ctx.fdot
        return [(sign * fdot(row.q, z), sign * fdot(row.qm, z)) for row, sign in self.guards]

    def _section_values(self, z):
        fdot = self.ctx.fdot
        return [(fdot(row.q, z), fdot(row.qm, z)) for row in self.sections]

    def _excluded(self, row: _Row, zn: float, w: float, fa: float, pa: float, fb: float, pb: float) -> bool:
        """The step-level exclusion tests: the curvature bound, then the Hermite bound."""
        flow = self.flow
        if _clear(fa, pa, fb, pb, w, flow.curvature(row, zn, w)):
            return True
        return _hermite_clear(fa, pa, fb, pb, w, flow.curvature(row, zn, w, order=4))

    def _guard_zero(self, j: int, first: bool, z_a, zn: float, length, fa, pa, fb, pb):
        """First zero of guard ``j`` on the step ``(0, length]`` from ``z_a``, or ``None``."""
        row, sign = self.guards[j]
        flow, search = self.flow, self.search
        on_surface = first and abs(float(fa)) <= self.noise * row.norm * zn
        if not on_surface:
            if fa <= 0:  # on the wrong side at the step start: the mode has already ended
                return self.ctx.zero
            if fb > 0 and self._excluded(row, zn, float(length), float(fa), float(pa), float(fb), float(pb)):
                return None
        self.careful += 1
        poly = flow.poly(row, z_a, sign, zn)
        fb, pb = poly.value_rate(length)
        if on_surface:
            start = search.leave_surface(poly, length, poly.c[1], self.noise * row.norm1 * zn)
            if start is None:
                return self.ctx.zero  # leaves its surface on the wrong side: the phase ends at once
            if start == "clear":
                return None
            u, fu, pu = start
            # a short flight (an impact at a small speed, a chattering tail): its first zero is a few
            # times u, and a search of (u, length] would halve its way down from the step's length
            # there; (u, 4u], (4u, 16u], ... are searched in turn instead, each as rigorously
            a = u
            while True:
                b = a * 4 if a * 4 < length else length
                fb_, pb_ = (fb, pb) if b is length else poly.value_rate(b)
                hit = search.first_zero(poly, a, b, fu, pu, fb_, pb_)
                if hit is not None or b is length:
                    return hit
                a, fu, pu = b, fb_, pb_
        return search.first_zero(poly, self.ctx.zero, length, poly.c[0], poly.c[1], fb, pb)

    def _section_crossings(self, k: int, z_a, zn: float, end, va, ra, vb, rb, at_end: bool):
        """Crossings ``[(s, before, after)]`` of section ``k`` on ``(0, end]``, in time order."""
        row = self.sections[k]
        flow, search = self.flow, self.search
        if va != 0 and at_end and (vb > 0) == (va > 0):
            sgn = 1.0 if va > 0 else -1.0
            if self._excluded(row, zn, float(end), sgn * float(va), sgn * float(ra), sgn * float(vb), sgn * float(rb)):
                return []
        self.careful += 1
        poly = flow.poly(row, z_a, 1, zn)
        vb, rb = poly.value_rate(end)
        a, fa, pa = self.ctx.zero, poly.c[0], poly.c[1]
        if fa == 0:  # starting on the section is not a crossing (it was counted when reached)
            start = search.leave_section(poly, a, end, pa)
            if start is None:
                return []
            a, fa, pa = start
        out = []
        for lo, hi, f_lo, f_hi in search.sign_changes(poly, a, end, fa, pa, vb, rb):
            out.append((search.root(poly, lo, hi, f_lo, f_hi), f_lo, f_hi))
        return out

    def _record_sections(self, s_a, z_a, zn: float, end, sec_a, sec_b, at_end: bool) -> None:
        found = []
        for k, sec in enumerate(self.request.sections):
            (va, ra), (vb, rb) = sec_a[k], sec_b[k]
            for s, before, after in self._section_crossings(k, z_a, zn, end, va, ra, vb, rb, at_end):
                if sec.crossed(float(before), float(after)):
                    found.append((s, k))
        for s, k in sorted(found, key=lambda item: item[0]):
            z = self.flow.state_at(z_a, s)
            t = self.t0 + s_a + s
            self.hits.append(SectionHit(index=k, t=float(t), y=np.array([float(v) for v in z[: self.flow.n]])))

    def _dense_upto(self, s_a, z_a, end) -> None:
        """States at the requested times in ``(s_a, s_a + end]`` (offsets from the arc start)."""
        i0 = len(self.rows_eval)
        i = i0
        while i < len(self.offsets) and self.offsets[i] <= s_a + end:
            i += 1
        if i > i0:
            local = np.array([max(float(self.offsets[j] - s_a), 0.0) for j in range(i0, i)])
            self.rows_eval.extend(self.flow.dense(z_a, local).T)

    # -- the loop
    def run(self) -> ArcResult:
        ctx, flow, request = self.ctx, self.flow, self.request
        n = flow.n
        s_a, z_a = ctx.zero, self.z0
        g_a, sec_a = self._guard_values(z_a), self._section_values(z_a)
        steps = 0
        fired, s_hit = None, None
        status, message = Status.SUCCESS, ""
        first = True
        while s_a < self.span:
            if steps >= request.max_steps:
                status = Status.BUDGET_EXHAUSTED
                message = f"step budget exhausted at t = {float(self.t0 + s_a):.6g}"
                break
            length = min(flow.h, self.span - s_a)
            z_b = flow.step(z_a) if length == flow.h else flow.state_at(z_a, length)
            steps += 1
            g_b, sec_b = self._guard_values(z_b), self._section_values(z_b)
            zn = flow.znorm(z_a)
            for j in range(len(self.guards)):
                s = self._guard_zero(j, first, z_a, zn, length, *g_a[j], *g_b[j])
                if s is not None and (s_hit is None or s < s_hit):  # earliest; lowest index on a tie
                    fired, s_hit = j, s
            end = length if fired is None else s_hit
            if self.sections:
                self._record_sections(s_a, z_a, zn, end, sec_a, sec_b, fired is None)
            self._dense_upto(s_a, z_a, end)
            if fired is not None:
                z_stop = flow.state_at(z_a, s_hit)
                return self._finish(s_a + s_hit, z_stop, fired, steps, z_a, s_a)
            s_a, z_a, g_a, sec_a = s_a + length, z_b, g_b, sec_b
            first = False
        if status is Status.SUCCESS:
            return self._finish(self.span, z_a, None, steps, z_a, s_a)
        y = np.array([float(v) for v in z_a[:n]])
        t = float(self.t0 + s_a)
        return self._result(t, 0.0, y, None, steps, status, message)

    def _finish(self, s_stop, z_stop, fired, steps, z_last, s_last) -> ArcResult:
        """The result at the event (kept for the next arc) or at ``t_end``."""
        request, integ = self.request, self.integ
        n = self.flow.n
        y = np.array([float(v) for v in z_stop[:n]])
        if fired is None:
            t, t_lo = float(request.t_end), 0.0
        elif s_stop == 0:
            t, t_lo = float(request.t0), float(request.t0_lo)
        else:
            time_mp = self.t0 + s_stop
            t = float(time_mp)
            if t < request.t0:  # the start's low part was negative: stay inside the arc
                t = float(request.t0)
            t_lo = float(time_mp - t)
        n_eval = int(np.searchsorted(self.t_eval, t, side="right"))
        if len(self.rows_eval) < n_eval:  # times equal to t after rounding: the state at the stop
            local = np.full(n_eval - len(self.rows_eval), max(float(s_stop - s_last), 0.0))
            self.rows_eval.extend(self.flow.dense(z_last, local).T)
        if fired is not None:
            integ._carry = (t, t_lo, y.copy(), self.t0 + s_stop, list(z_stop))
        return self._result(t, t_lo, y, fired, steps, Status.SUCCESS, "", n_eval)

    def _result(self, t, t_lo, y, fired, steps, status, message, n_eval=None) -> ArcResult:
        n = self.flow.n
        rows = self.rows_eval if n_eval is None else self.rows_eval[:n_eval]
        y_eval = np.array(rows).T if rows else np.empty((n, 0))
        nfev, self.flow.matvecs = self.flow.matvecs, 0
        # nfev counts mp matrix-vector products (flow or field of the augmented system), said here too
        extra = {"careful_steps": self.careful, "roots": self.search.roots, "mp_matvecs": nfev}
        return ArcResult(
            t=t,
            y=y,
            fired=fired,
            y_eval=y_eval,
            section_hits=self.hits,
            nfev=nfev,
            njev=0,
            nsteps=steps,
            extra=extra,
            status=status,
            message=message,
            t_lo=t_lo,
        )
