"""The hybrid rules every problem shares, compiled: which guard fires at once, the settle step, storms, accumulations.

A problem's law (:mod:`nsbench.model.law`) says what its modes, guards and
resets are; these rules say how they are applied, the same for every problem:

- after a transition, a guard of the new mode that is already on its wrong
  side (or on its surface, heading the wrong way) fires at once, at the same
  time, until none is left (:func:`pending_guard`); a guard the transition put
  on its surface by construction (``fresh``) is not tested again at once, and a
  crossing of it that an integrator reports while it heads back into its mode is a
  false start, not an event (:func:`settle_fired`);
- more than ``ring.size`` consecutive events within ``zeno_span`` are an event
  storm, and the event budget ends a run;
- a run of consecutive events of one guard whose intervals shrink
  geometrically accumulates (Zeno): its accumulation time is extrapolated from
  the geometric tail, ``t_Z = t_k + dt_k r / (1 - r)``, as soon as that is
  accurate (:func:`accumulation_time`: the tail's error estimate
  (:func:`tail_estimate`) within the run's tolerance ``lim.accumulation``, or
  at the rounding of the event times, or when more events cannot improve it or
  would not be resolved in double precision), and the problem's declared limit
  behaviour is applied there, with an event of its own that carries the
  estimate (:func:`settle`).

Guards of a mode come in the law's order, which is also the tie order.
"""

from __future__ import annotations

import numpy as np

from nsbench.model import law
from nsbench.model.abi import SF_T, SF_TLO, SI_ACC_KEY, SI_ACC_N, SI_EVENTS, SI_RECORDED, SI_RING, SI_STOP_SEEN
from nsbench.model.compile import hot, inline, small

#: Outcomes of :func:`settle`.
SETTLED, STORM, EVENT_BUDGET = 0, 1, 2
_EPS = np.finfo(np.float64).eps
#: Largest ratio of consecutive intervals that counts as an accumulation (1 - it: the smallest contraction).
ACCUMULATION_RATIO = 1.0 - 1e-9
#: Relative spread of the last ratios of an accumulation's intervals that stops it on a plateau or at the
#: resolution (a geometric sequence has one ratio); an estimate within the tolerance needs no such test.
ACCUMULATION_SPREAD = 0.1
#: Event times of a streak the rule keeps (the ring ``st.acc``): four give an estimate, seven the last four.
STREAK_TIMES = 8
#: An estimate within this many times the rounding of its times (:func:`rounding_error`) is as good as
#: double event times allow: the rule extrapolates.
ROUNDING_ULPS = 16.0
#: A next event whose guard would move less than this many ``eps max(1, |y|)`` off its surface is not
#: resolved in double (the tolerance of :func:`wrong_side`): the rule extrapolates before it.
RESOLUTION_ULPS = 64.0


@inline
def wrong_side(prob, mode, kind, index, sign, t, y, dy):
    """Whether a guard is already past its surface, or on it (within rounding) and heading the wrong way."""
    g = law.guard_value(prob, mode, kind, index, t, y)
    phi = sign * g
    ymax = 0.0
    for j in range(y.shape[0]):
        ymax = max(ymax, abs(y[j]))
    tol = 64.0 * _EPS * max(1.0, abs(g), ymax)
    if phi < -tol:
        return True
    if abs(phi) <= tol:
        return sign * law.guard_rate(prob, mode, kind, index, t, y, dy) < 0.0
    return False


@hot
def pending_guard(prob, st, t):
    """Index (into the guards of ``st.mode``, refilled here) of the first guard that must fire at once, or -1.

    A guard of an element marked ``fresh`` starts on its surface by construction
    (the transition chose the new phase from the forces) and is not re-tested.
    """
    mode, y, gk, gi, gs, dy = st.mode, st.y, st.gk, st.gi, st.gs, st.dy
    ng = law.guards_of(prob, mode, gk, gi, gs)
    have_dy = False
    for q in range(ng):
        if st.fresh[gi[q]]:
            continue
        if not have_dy:
            law.rhs(prob, mode, t, y, dy)
            have_dy = True
        if wrong_side(prob, mode, gk[q], gi[q], gs[q], t, y, dy):
            return q
    return -1


@hot
def _record(ev, lim, st, t, code, index, err=np.nan):
    """Count an event and store it if ``t >= lim.record_from`` (``err``: an accumulation's error estimate)."""
    si = st.si
    si[SI_EVENTS] += 1
    if t >= lim.record_from:
        k = si[SI_RECORDED]
        ev.t[k] = t
        ev.kind[k] = code
        ev.index[k] = index
        ev.err[k] = err
        for i in range(st.y.shape[0]):
            ev.y[k, i] = st.y[i]
        for i in range(st.mode.shape[0]):
            ev.mode[k, i] = st.mode[i]
        si[SI_RECORDED] = k + 1
        if code == lim.stop_kind:
            si[SI_STOP_SEEN] += 1


@hot
def _storm(st, lim, t):
    """Push ``t`` into the ring of the last events; whether they now make a storm."""
    ring, si = st.ring, st.si
    nring = ring.shape[0]
    oldest = ring[si[SI_RING] % nring]
    full = si[SI_RING] >= nring
    ring[si[SI_RING] % nring] = t
    si[SI_RING] += 1
    return full and t - oldest <= lim.zeno_span


@small
def tail_estimate(t0, t1, t2, t3, ratio_max):
    """The accumulation time ``t_Z`` of four consecutive event times of a streak, its error estimate and ratio.

    ``t_Z = t3 + d3 r / (1 - r)`` (the geometric tail after the last interval ``d3``, ``r = d3 / d2``).
    The ratios of an accumulation's intervals converge geometrically (a chattering mass's next speed
    is ``r`` times its last one up to a term of the order of that speed), so the ratios still to come
    stay within ``delta = |r - r_before| / (1 - r)`` of the last one (the sum of changes that shrink by
    ``r`` each time); a tail whose every ratio is within ``delta`` of ``r`` is within
    ``d3 ((r + delta) / (1 - r - delta) - r / (1 - r))`` of the estimate, the error estimate returned. It
    also covers the rounding of the times, which shows in ``r - r_before``. Not counted: the errors of
    the event times themselves, which ``t_Z`` inherits through ``t3``. Written for doubles and for
    mpmath numbers alike (the check of :mod:`nsbench.integrators.mp_hybrid` runs it in mp).

    Returns ``(NaN, inf, NaN)`` if the intervals do not shrink (ratios outside ``(0, ratio_max)``),
    ``(t_Z, inf, r)`` if the ratios move too much for a bound (``r + delta >= 1``).
    """
    d1, d2, d3 = t1 - t0, t2 - t1, t3 - t2
    if not (d1 > 0.0 and d2 > 0.0 and d3 > 0.0):
        return np.nan, np.inf, np.nan
    r1, r2 = d2 / d1, d3 / d2
    if not (0.0 < r1 < ratio_max and 0.0 < r2 < ratio_max):
        return np.nan, np.inf, np.nan
    t_z = t3 + d3 * r2 / (1.0 - r2)
    delta = abs(r2 - r1) / (1.0 - r2)
    if not r2 + delta < 1.0:
        return t_z, np.inf, r2
    return t_z, d3 * ((r2 + delta) / (1.0 - r2 - delta) - r2 / (1.0 - r2)), r2


@inline
def _estimate_back(times, newest, back):
    """:func:`tail_estimate` of the four times of the ring ending ``back`` events before the newest."""
    m = times.shape[0]
    e = newest - back
    return tail_estimate(times[(e - 3) % m], times[(e - 2) % m], times[(e - 1) % m], times[e % m], ACCUMULATION_RATIO)


@small
def rounding_error(t, ratio, unit):
    """How far ``t_Z`` of :func:`tail_estimate` moves when each time moves by ``unit max(1, |t|)``.

    ``t_Z = t3 + d3^2 / (d2 - d3)`` has the derivatives ``1 / (1 - r)^2``, ``-2 r / (1 - r)^2`` and
    ``r^2 / (1 - r)^2`` in ``t3``, ``t2`` and ``t1``: their absolute values sum to ``((1 + r) / (1 - r))^2``.
    """
    q = (1.0 + ratio) / (1.0 - ratio)
    return unit * max(1.0, abs(t)) * q * q


@hot
def accumulation_time(times, newest, count, tol, excursion, y_scale):
    """Whether a streak's accumulation is extrapolated now: ``(t_Z, error estimate)``, or ``(NaN, NaN)``.

    ``times`` is the streak's ring (:data:`STREAK_TIMES`), its newest entry at ``newest``, ``count`` times
    in it so far; ``tol`` the run's tolerance (relative to ``max(1, |t|)``), ``excursion`` how far the
    streak's guard moves off its surface over the next interval (``|rate| d r / 4``, a parabola's height)
    and ``y_scale`` ``max(1, |y|)``. The error estimate is the tail's (:func:`tail_estimate`) plus the
    effect of an ulp of ``max(1, |t|)`` on each time (:func:`rounding_error`). Extrapolated, with the
    latest estimate, when

    - the estimate is within ``tol`` or within :data:`ROUNDING_ULPS` times that rounding term (as
      good as double times allow);
    - or the ratios agree to :data:`ACCUMULATION_SPREAD` and either the next event would be within
      :data:`RESOLUTION_ULPS` of its surface (not resolved in double), or the estimate stopped
      shrinking after shrinking twice (the times' own errors dominate it: more events cannot improve
      it); then the better of the last two estimates is used (the newest interval, the shortest, may
      be the least accurate).
    """
    if count < 4:
        return np.nan, np.nan
    t = times[newest]
    t_z, err, ratio = _estimate_back(times, newest, 0)
    if not err < np.inf:
        return np.nan, np.nan
    rounding = rounding_error(t, ratio, _EPS)
    if err + rounding <= max(tol * max(1.0, abs(t)), ROUNDING_ULPS * rounding):
        return t_z, err + rounding
    if count < 5:
        return np.nan, np.nan
    m = times.shape[0]
    lo, hi = ratio, ratio
    for j in range(1, 3):  # the two ratios before the last (all three intervals are > 0 here)
        a, b, c = times[(newest - j - 2) % m], times[(newest - j - 1) % m], times[(newest - j) % m]
        r = (c - b) / (b - a)
        lo, hi = min(lo, r), max(hi, r)
    if hi - lo > ACCUMULATION_SPREAD * ratio:
        return np.nan, np.nan
    t_z1, e1, r1 = _estimate_back(times, newest, 1)
    if excursion <= RESOLUTION_ULPS * _EPS * y_scale or (
        count >= 7 and _estimate_back(times, newest, 3)[1] > _estimate_back(times, newest, 2)[1] > e1 and err >= e1
    ):
        # the better of the last two estimates (the newest interval may be the least accurate), if still ahead
        if e1 < err and t_z1 > t:
            return t_z1, e1 + rounding_error(t, r1, _EPS)
        return t_z, err + rounding
    return np.nan, np.nan


@hot
def _accumulates(prob, st, lim, t, kind, index, code):
    """Add the event to the streak of its guard; ``(t_Z, error estimate)`` if its accumulation is to be
    extrapolated now (:func:`accumulation_time`), else ``(NaN, NaN)``."""
    si, times = st.si, st.acc
    key = (kind * 1_000_003 + index) * 64 + code
    if si[SI_ACC_KEY] != key:
        si[SI_ACC_KEY], si[SI_ACC_N] = key, 0
    n = si[SI_ACC_N]
    m = times.shape[0]
    times[n % m] = t
    si[SI_ACC_N] = n + 1
    if n < 3:
        return np.nan, np.nan
    y = st.y
    y_scale = 1.0
    for i in range(y.shape[0]):
        y_scale = max(y_scale, abs(y[i]))
    # how far the guard moves off its surface before the next event: |rate| times a quarter of the next
    # interval (the height of a parabola through the two events), the next interval r times the last
    d, before = times[n % m] - times[(n - 1) % m], times[(n - 1) % m] - times[(n - 2) % m]
    excursion = np.inf
    if d > 0.0 and before > 0.0:
        law.rhs(prob, st.mode, t, y, st.dy)
        excursion = abs(law.guard_rate(prob, st.mode, kind, index, t, y, st.dy)) * d * (d / before) / 4.0
    t_z, err = accumulation_time(times, n % m, min(n + 1, m), lim.accumulation, excursion, y_scale)
    if not t_z < lim.t_end:
        return np.nan, np.nan
    return t_z, err


@hot
def false_start(prob, st, q, t):
    """Whether guard ``q`` of ``st.mode``, reported crossed at ``(t, st.y)``, is a false start.

    An element marked ``fresh`` began the arc on its surface by construction. An
    integrator that starts with a guard at zero (a double zero where the
    acceleration vanishes at the switch, e.g. static = kinetic friction) can see
    the noise of its first steps as a sign change and report a crossing just after
    the start. If the guard heads back into its mode there (``sign * rate > 0``),
    nothing left the mode: the law's transition would choose the same mode again.
    """
    index = st.gi[q]
    if not st.fresh[index]:
        return False
    law.rhs(prob, st.mode, t, st.y, st.dy)
    return st.gs[q] * law.guard_rate(prob, st.mode, st.gk[q], index, t, st.y, st.dy) > 0.0


@hot
def settle_fired(prob, st, lim, ev, q):
    """The step after an arc ended at guard ``q`` (an index into the guards of ``st.mode``) at ``st.sf[SF_T]``.

    A false start (:func:`false_start`) is not an event: the mode, its ``fresh``
    marks and its guards stay, the arc goes on from ``st.y``, and it counts in the
    storm ring so that an integrator that keeps reporting it ends in a storm, not a
    loop. Otherwise the ``fresh`` marks are cleared and :func:`settle` applies the
    transition. Returns what :func:`settle` returns.
    """
    t = st.sf[SF_T]
    if false_start(prob, st, q, t):
        return STORM if _storm(st, lim, t) else SETTLED
    for i in range(st.fresh.shape[0]):
        st.fresh[i] = False
    law.guards_of(prob, st.mode, st.gk, st.gi, st.gs)
    return settle(prob, st, lim, ev, q)


@hot
def settle(prob, st, lim, ev, q):
    """Apply guard ``q`` of ``st.mode`` at ``t = st.sf[SF_T]`` and every guard that must follow there.

    ``st.mode``, ``st.y`` and ``st.fresh`` are updated in place, and ``st.sf[SF_T]``
    when an accumulation is extrapolated; the guards of the final mode are left
    in ``st.gk, st.gi, st.gs``. Events go through :func:`_record` (the caller
    guarantees room for ``ring.size + 2`` of them). Returns :data:`SETTLED`,
    :data:`STORM` or :data:`EVENT_BUDGET`.
    """
    gk, gi, si, sf = st.gk, st.gi, st.si, st.sf
    t = sf[SF_T]
    while q >= 0:
        kind, index = gk[q], gi[q]
        code = law.transition(prob, st.mode, kind, index, t, st.y, st.fresh)
        _record(ev, lim, st, t, code, index)
        if si[SI_EVENTS] >= lim.max_events:
            return EVENT_BUDGET
        if _storm(st, lim, t):
            return STORM
        if lim.accumulation > 0.0:
            t_z, err = _accumulates(prob, st, lim, t, kind, index, code)
            if not np.isnan(t_z):
                limit = law.accumulation_limit(prob, st.mode, kind, index, t_z, st.y)
                if limit >= 0:  # the problem's limit behaviour, at the accumulation time
                    t = t_z
                    sf[SF_T], sf[SF_TLO] = t, 0.0
                    si[SI_ACC_KEY], si[SI_ACC_N] = -1, 0
                    _record(ev, lim, st, t, limit, index, err)
                    if si[SI_EVENTS] >= lim.max_events:
                        return EVENT_BUDGET
                    if _storm(st, lim, t):
                        return STORM
        q = pending_guard(prob, st, t)
    return SETTLED
