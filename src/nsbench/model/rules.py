"""The hybrid rules every problem shares, compiled: which guard fires at once, the settle step, storms, accumulations.

A problem's law (:mod:`nsbench.model.law`) says what its modes, guards and
resets are; these rules say how they are applied, the same for every problem:

- after a transition, a guard of the new mode that is already on its wrong
  side (or on its surface, heading the wrong way) fires at once, at the same
  time, until none is left (:func:`pending_guard`); a guard the transition put
  on its surface by construction (``fresh``) is not tested again at once;
- more than ``ring.size`` consecutive events within ``zeno_span`` are an event
  storm, and the event budget ends a run;
- a run of consecutive events of one guard whose intervals shrink
  geometrically accumulates (Zeno): after ``accumulation`` such intervals the
  accumulation time is extrapolated, ``t_Z = t_k + dt_k r / (1 - r)``, and the
  problem's declared limit behaviour is applied there, with an event of its own
  (:func:`settle`).

Guards of a mode come in the law's order, which is also the tie order.
"""

from __future__ import annotations

import numpy as np

from nsbench.model import law
from nsbench.model.abi import SF_T, SF_TLO, SI_ACC_KEY, SI_ACC_N, SI_EVENTS, SI_RECORDED, SI_RING, SI_STOP_SEEN
from nsbench.model.compile import hot, inline

#: Outcomes of :func:`settle`.
SETTLED, STORM, EVENT_BUDGET = 0, 1, 2
_EPS = np.finfo(np.float64).eps
#: Largest ratio of consecutive intervals that counts as an accumulation (1 - it: the smallest contraction).
ACCUMULATION_RATIO = 1.0 - 1e-9
#: Relative spread of the ratios of an accumulation's intervals (a geometric sequence has one ratio).
ACCUMULATION_SPREAD = 0.1


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
def _record(ev, lim, st, t, code, index):
    """Count an event and store it if ``t >= lim.record_from``."""
    si = st.si
    si[SI_EVENTS] += 1
    if t >= lim.record_from:
        k = si[SI_RECORDED]
        ev.t[k] = t
        ev.kind[k] = code
        ev.index[k] = index
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


@hot
def accumulation_time(times, newest, k, t_end):
    """The accumulation time of the last ``k + 1`` event times of a streak, or NaN.

    ``times`` is a ring whose newest entry is at ``newest``. NaN if the ``k``
    intervals do not shrink geometrically (their ratios in ``(0, 1)`` and within
    :data:`ACCUMULATION_SPREAD` of each other) or the time falls at or after ``t_end``.
    """
    m = times.shape[0]
    r_last = 0.0
    d_prev = 0.0
    lo, hi = np.inf, -np.inf
    for j in range(k):
        d = times[(newest - k + 1 + j) % m] - times[(newest - k + j) % m]
        if not d > 0.0:
            return np.nan
        if j > 0:
            r = d / d_prev
            if not (0.0 < r < ACCUMULATION_RATIO):
                return np.nan
            lo, hi, r_last = min(lo, r), max(hi, r), r
        d_prev = d
    if k < 2 or hi - lo > ACCUMULATION_SPREAD * r_last:
        return np.nan
    t_z = times[newest] + d_prev * r_last / (1.0 - r_last)
    return t_z if t_z < t_end else np.nan


@hot
def _accumulates(st, lim, t, kind, index, code):
    """Add the event to the streak of its guard; the extrapolated accumulation time, or NaN."""
    si, times = st.si, st.acc
    key = (kind * 1_000_003 + index) * 64 + code
    if si[SI_ACC_KEY] != key:
        si[SI_ACC_KEY], si[SI_ACC_N] = key, 0
    n = si[SI_ACC_N]
    times[n % times.shape[0]] = t
    si[SI_ACC_N] = n + 1
    if n < lim.accumulation:
        return np.nan
    return accumulation_time(times, n % times.shape[0], lim.accumulation, lim.t_end)


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
        if lim.accumulation > 0:
            t_z = _accumulates(st, lim, t, kind, index, code)
            if not np.isnan(t_z):
                limit = law.accumulation_limit(prob, st.mode, kind, index, t_z, st.y)
                if limit >= 0:  # the problem's limit behaviour, at the accumulation time
                    t = t_z
                    sf[SF_T], sf[SF_TLO] = t, 0.0
                    si[SI_ACC_KEY], si[SI_ACC_N] = -1, 0
                    _record(ev, lim, st, t, limit, index)
                    if si[SI_EVENTS] >= lim.max_events:
                        return EVENT_BUDGET
                    if _storm(st, lim, t):
                        return STORM
        q = pending_guard(prob, st, t)
    return SETTLED
