"""Double-double arithmetic for compiled code: about 32 significant digits from pairs of doubles.

A number is ``(hi, lo)`` with ``|lo| <= ulp(hi) / 2``; a complex one is
``(re_hi, re_lo, im_hi, im_lo)``. Only what the exact solver's event polish
needs: sums and products (error-free transformations: the rounding error of a
product is one fused multiply-add, which gives the same double as Dekker's
splitting and takes one instruction instead of seventeen), and ``exp``, ``cos``/``sin`` of double-double arguments by argument
reduction and Taylor series. Accuracy: a few units of 2^-104 relative (tested
against mpmath).
"""

from __future__ import annotations

import math

from numba import types
from numba.extending import intrinsic

from nsbench.model.compile import hot, small

# ln 2 and pi/2 to double-double
LN2_HI, LN2_LO = 0.6931471805599453, 2.3190468138462996e-17
PIO2_HI, PIO2_LO = 1.5707963267948966, 6.123233995736766e-17


@small
def two_sum(a, b):
    s = a + b
    bb = s - a
    return s, (a - (s - bb)) + (b - bb)


@small
def quick_two_sum(a, b):  # |a| >= |b|
    s = a + b
    return s, b - (s - a)


@intrinsic
def fma(typingctx, a, b, c):
    """``a * b + c`` rounded once (LLVM's ``fma``: one instruction where the processor has it)."""
    if not all(isinstance(x, (types.Float, types.Integer)) for x in (a, b, c)):  # integers: converted, as in a * b
        return None
    sig = types.float64(types.float64, types.float64, types.float64)

    def codegen(context, builder, signature, args):
        vals = [context.cast(builder, v, t, types.float64) for v, t in zip(args, signature.args)]
        return builder.fma(*vals)

    return sig, codegen


@small
def two_prod(a, b):
    """``a * b`` as ``(p, e)`` with ``p + e`` exact: ``e = fma(a, b, -p)`` is exact, so it is the double
    Dekker's splitting (``2^27 + 1``) gives (no overflow or underflow), in one instruction."""
    p = a * b
    return p, fma(a, b, -p)


@small
def add(ah, al, bh, bl):
    s, e = two_sum(ah, bh)
    t, f = two_sum(al, bl)
    e += t
    s, e = quick_two_sum(s, e)
    e += f
    return quick_two_sum(s, e)


@small
def add_d(ah, al, b):
    s, e = two_sum(ah, b)
    e += al
    return quick_two_sum(s, e)


@small
def mul(ah, al, bh, bl):
    p, e = two_prod(ah, bh)
    e += ah * bl + al * bh
    return quick_two_sum(p, e)


@small
def mul_d(ah, al, b):
    p, e = two_prod(ah, b)
    e += al * b
    return quick_two_sum(p, e)


@small
def div_d(ah, al, b):
    """A double-double divided by a double."""
    q1 = ah / b
    ph, pl = two_prod(q1, b)
    r = ((ah - ph) - pl) + al
    return quick_two_sum(q1, r / b)


@hot
def cmul(a0, a1, a2, a3, b0, b1, b2, b3):
    """Product of two complex double-doubles."""
    rr = mul(a0, a1, b0, b1)
    ii = mul(a2, a3, b2, b3)
    ri = mul(a0, a1, b2, b3)
    ir = mul(a2, a3, b0, b1)
    re = add(rr[0], rr[1], -ii[0], -ii[1])
    im = add(ri[0], ri[1], ir[0], ir[1])
    return re[0], re[1], im[0], im[1]


# ``exp``, ``cos``/``sin`` and ``exp`` of a complex number are written in stages (reduction, one Taylor
# term, one squaring or doubling, the result), so that independent evaluations can run in lockstep
# (:func:`cexp`, :func:`cos_sin2`): each argument goes through exactly the operations, in the same order,
# of its own evaluation (the same doubles), but their chains of dependent divisions and products overlap
# in the processor instead of following one another.
@small
def _exp_reduce(xh, xl):
    """``k`` and ``r / 2^8`` with ``x = k ln2 + r``."""
    k = math.floor(xh / LN2_HI + 0.5)
    ph, pl = mul_d(LN2_HI, LN2_LO, -k)
    rh, rl = add(xh, xl, ph, pl)
    return k, rh * 2.0**-8, rl * 2.0**-8


@small
def _exp_term(j, rh, rl, th, tl, sh, sl):
    """The term ``r^j / j!`` from the previous one, added to the sum."""
    th, tl = mul(th, tl, rh, rl)
    th, tl = div_d(th, tl, float(j))
    sh, sl = add(sh, sl, th, tl)
    return th, tl, sh, sl


@small
def _exp_square(sh, sl):
    """``(1 + s)^2 - 1 = 2 s + s^2`` (keeps the small part exact)."""
    qh, ql = mul(sh, sl, sh, sl)
    return add(2.0 * sh, 2.0 * sl, qh, ql)


@small
def _exp_finish(k, sh, sl):
    eh, el = add_d(sh, sl, 1.0)
    scale = 2.0**k
    return eh * scale, el * scale


@hot
def exp(xh, xl):
    """``exp`` of a double-double: ``x = k ln2 + r``, ``exp(r / 2^8)`` by Taylor, squared 8 times."""
    if xh > 709.0:
        return math.inf, 0.0
    if xh < -745.0:
        return 0.0, 0.0
    k, rh, rl = _exp_reduce(xh, xl)
    # sum_{j>=1} r^j / j!  (|r| < 2^-9: 11 terms reach 2^-104)
    th, tl = rh, rl
    sh, sl = rh, rl
    for j in range(2, 12):
        th, tl, sh, sl = _exp_term(j, rh, rl, th, tl, sh, sl)
    for _ in range(8):
        sh, sl = _exp_square(sh, sl)
    return _exp_finish(k, sh, sl)


@small
def _cs_reduce(xh, xl):
    """``k``, ``r / 8`` and its square, with ``x = k pi/2 + r``."""
    k = math.floor(xh / PIO2_HI + 0.5)
    ph, pl = mul_d(PIO2_HI, PIO2_LO, -k)
    rh, rl = add(xh, xl, ph, pl)
    rh, rl = rh * 0.125, rl * 0.125
    r2h, r2l = mul(rh, rl, rh, rl)
    return k, rh, rl, r2h, r2l


@small
def _cs_term(j, r2h, r2l, uh, ul, ch, cl, th, tl, sh, sl):
    """The ``j``-th terms of the cosine and sine series from the previous ones, added to the sums."""
    uh, ul = mul(uh, ul, r2h, r2l)
    uh, ul = div_d(-uh, -ul, float((2 * j - 1) * (2 * j)))
    ch, cl = add(ch, cl, uh, ul)
    th, tl = mul(th, tl, r2h, r2l)
    th, tl = div_d(-th, -tl, float((2 * j) * (2 * j + 1)))
    sh, sl = add(sh, sl, th, tl)
    return uh, ul, ch, cl, th, tl, sh, sl


@small
def _cs_double(ch, cl, sh, sl):
    """``cos 2a = 1 - 2 sin^2 a``, ``sin 2a = 2 sin a cos a``."""
    s2h, s2l = mul(sh, sl, sh, sl)
    nsh, nsl = mul(sh, sl, ch, cl)
    ch, cl = add_d(-2.0 * s2h, -2.0 * s2l, 1.0)
    return ch, cl, 2.0 * nsh, 2.0 * nsl


@small
def _cs_quadrant(k, ch, cl, sh, sl):
    q = int(k) % 4
    if q == 0:
        return ch, cl, sh, sl
    if q == 1:
        return -sh, -sl, ch, cl
    if q == 2:
        return -ch, -cl, -sh, -sl
    return sh, sl, -ch, -cl


@hot
def cos_sin(xh, xl):
    """``(cos x, sin x)`` of a double-double, each as ``(hi, lo)``: ``x = k pi/2 + r``, Taylor on ``r / 8``."""
    k, rh, rl, r2h, r2l = _cs_reduce(xh, xl)
    # sin and cos of |r| <= pi/32 by Taylor (13 terms: below 2^-104)
    th, tl = rh, rl
    sh, sl = rh, rl
    ch, cl = 1.0, 0.0
    uh, ul = 1.0, 0.0
    for j in range(1, 13):
        uh, ul, ch, cl, th, tl, sh, sl = _cs_term(j, r2h, r2l, uh, ul, ch, cl, th, tl, sh, sl)
    # three doublings
    for _ in range(3):
        ch, cl, sh, sl = _cs_double(ch, cl, sh, sl)
    return _cs_quadrant(k, ch, cl, sh, sl)


@hot
def cos_sin2(xh, xl, yh, yl):
    """:func:`cos_sin` of two double-doubles in lockstep (the same doubles as two calls)."""
    k, rh, rl, r2h, r2l = _cs_reduce(xh, xl)
    k2, rh2, rl2, r2h2, r2l2 = _cs_reduce(yh, yl)
    th, tl, sh, sl, ch, cl, uh, ul = rh, rl, rh, rl, 1.0, 0.0, 1.0, 0.0
    th2, tl2, sh2, sl2, ch2, cl2, uh2, ul2 = rh2, rl2, rh2, rl2, 1.0, 0.0, 1.0, 0.0
    for j in range(1, 13):
        uh, ul, ch, cl, th, tl, sh, sl = _cs_term(j, r2h, r2l, uh, ul, ch, cl, th, tl, sh, sl)
        uh2, ul2, ch2, cl2, th2, tl2, sh2, sl2 = _cs_term(j, r2h2, r2l2, uh2, ul2, ch2, cl2, th2, tl2, sh2, sl2)
    for _ in range(3):
        ch, cl, sh, sl = _cs_double(ch, cl, sh, sl)
        ch2, cl2, sh2, sl2 = _cs_double(ch2, cl2, sh2, sl2)
    c0, c1, c2, c3 = _cs_quadrant(k, ch, cl, sh, sl)
    d0, d1, d2, d3 = _cs_quadrant(k2, ch2, cl2, sh2, sl2)
    return c0, c1, c2, c3, d0, d1, d2, d3


@hot
def cexp(ah, al, bh, bl):
    """``exp(a + i b)`` of a complex double-double, as ``(re_hi, re_lo, im_hi, im_lo)``.

    ``exp(a)`` and ``cos b, sin b`` in lockstep: the same doubles as :func:`exp` and :func:`cos_sin`.
    """
    if ah > 709.0 or ah < -745.0:
        mh, ml = exp(ah, al)
        ch, cl, sh, sl = cos_sin(bh, bl)
    else:
        k, rh, rl = _exp_reduce(ah, al)
        kc, xh, xl, r2h, r2l = _cs_reduce(bh, bl)
        eth, etl, esh, esl = rh, rl, rh, rl
        th, tl, sh, sl, ch, cl, uh, ul = xh, xl, xh, xl, 1.0, 0.0, 1.0, 0.0
        for j in range(1, 13):
            uh, ul, ch, cl, th, tl, sh, sl = _cs_term(j, r2h, r2l, uh, ul, ch, cl, th, tl, sh, sl)
            if 2 <= j <= 11:
                eth, etl, esh, esl = _exp_term(j, rh, rl, eth, etl, esh, esl)
        for i in range(8):
            esh, esl = _exp_square(esh, esl)
            if i < 3:
                ch, cl, sh, sl = _cs_double(ch, cl, sh, sl)
        mh, ml = _exp_finish(k, esh, esl)
        ch, cl, sh, sl = _cs_quadrant(kc, ch, cl, sh, sl)
    re = mul(mh, ml, ch, cl)
    im = mul(mh, ml, sh, sl)
    return re[0], re[1], im[0], im[1]


@hot
def cexp2(ah, al, bh, bl, ch, cl, dh, dl):
    """:func:`cexp` of ``a + i b`` and of ``c + i d`` in lockstep (the same doubles as two calls)."""
    if ah > 709.0 or ah < -745.0 or ch > 709.0 or ch < -745.0:
        x0, x1, x2, x3 = cexp(ah, al, bh, bl)
        y0, y1, y2, y3 = cexp(ch, cl, dh, dl)
        return x0, x1, x2, x3, y0, y1, y2, y3
    k, rh, rl = _exp_reduce(ah, al)
    kc, xh, xl, r2h, r2l = _cs_reduce(bh, bl)
    k2, rh2, rl2 = _exp_reduce(ch, cl)
    kc2, xh2, xl2, r2h2, r2l2 = _cs_reduce(dh, dl)
    eth, etl, esh, esl = rh, rl, rh, rl
    th, tl, sh, sl, kh, kl, uh, ul = xh, xl, xh, xl, 1.0, 0.0, 1.0, 0.0
    eth2, etl2, esh2, esl2 = rh2, rl2, rh2, rl2
    th2, tl2, sh2, sl2, kh2, kl2, uh2, ul2 = xh2, xl2, xh2, xl2, 1.0, 0.0, 1.0, 0.0
    for j in range(1, 13):
        uh, ul, kh, kl, th, tl, sh, sl = _cs_term(j, r2h, r2l, uh, ul, kh, kl, th, tl, sh, sl)
        uh2, ul2, kh2, kl2, th2, tl2, sh2, sl2 = _cs_term(j, r2h2, r2l2, uh2, ul2, kh2, kl2, th2, tl2, sh2, sl2)
        if 2 <= j <= 11:
            eth, etl, esh, esl = _exp_term(j, rh, rl, eth, etl, esh, esl)
            eth2, etl2, esh2, esl2 = _exp_term(j, rh2, rl2, eth2, etl2, esh2, esl2)
    for i in range(8):
        esh, esl = _exp_square(esh, esl)
        esh2, esl2 = _exp_square(esh2, esl2)
        if i < 3:
            kh, kl, sh, sl = _cs_double(kh, kl, sh, sl)
            kh2, kl2, sh2, sl2 = _cs_double(kh2, kl2, sh2, sl2)
    mh, ml = _exp_finish(k, esh, esl)
    kh, kl, sh, sl = _cs_quadrant(kc, kh, kl, sh, sl)
    mh2, ml2 = _exp_finish(k2, esh2, esl2)
    kh2, kl2, sh2, sl2 = _cs_quadrant(kc2, kh2, kl2, sh2, sl2)
    re = mul(mh, ml, kh, kl)
    im = mul(mh, ml, sh, sl)
    re2 = mul(mh2, ml2, kh2, kl2)
    im2 = mul(mh2, ml2, sh2, sl2)
    return re[0], re[1], im[0], im[1], re2[0], re2[1], im2[0], im2[1]
