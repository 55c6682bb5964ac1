"""The missed-crossing check on every accepted step of a library integrator (scipy, SUNDIALS per arc).

A library's root finding stops at a sign change of a guard between two step
ends; a guard that leaves its side and comes back inside one step (a short
excursion: a slip of a few hundredths, a stick shorter than the step) is
stepped over. So each step of an arc is checked here, guard by guard, from
what the arc already has: its step ends. At each of them the guard's signed
value ``h`` (positive on its own side) and its rate ``h'`` (along the field
there) give, on the step, the cubic Hermite interpolant of the guard:

1. :func:`may_dip`, the test on those four numbers. Scaled to the step
   (``d = dt h'``), the cubic stays above ``min(h_a, h_b) - (4/27)(|d_a| +
   |d_b|)``, so a step whose ends are far from zero against their slopes
   cannot dip (most steps end here, at a few float operations). Otherwise the
   step may hold a dip when the cubic has an interior minimum below
   :data:`MARGIN` times ``|d_a| + |d_b|`` (zero, with room for the cubic's
   error against the solution).
2. :func:`first_dip` runs that test over every step of an arc in one compiled
   call (after the arc, so that a step costs the check nothing but keeping its
   end), and :func:`checked` integrates each flagged step again from its start
   with a fresh start of the same method, in at least :data:`RERUN_STEPS` steps
   (they resolve what one long step did not), itself checked, to
   :data:`CHECK_DEPTH` levels. A crossing found there ends the arc at it; none, and the arc
   stands as it was (the flag was the cubic's, not the solution's).

The test misses a dip only where ``h`` has two or more extrema inside one step
and stays clear of zero at the ends with slopes that point away from it: a
guard whose variation inside a step the step does not resolve, which step-size
control does not allow except while the field is constant (every block stuck);
there the step is capped at a fraction of the forcing period
(:mod:`nsbench.integrators.scipy_`) or the forcing is a state of the step-size
control (``cvode-*``).
"""

from __future__ import annotations

import numpy as np

from nsbench.model import law
from nsbench.model.compile import hot, jit

_EPS = float(np.finfo(np.float64).eps)


#: A step may hold a dip when the cubic's interior minimum is at most this share of ``|d_a| + |d_b|`` above
#: zero: room for the cubic's own error against the solution (its terms in the end slopes are at most 4/27
#: of them each).
MARGIN = 0.125


@hot
def may_dip(h_a, h_b, d_a, d_b):
    """Whether a guard with values ``h_a, h_b >= 0`` and step-scaled rates ``d_a, d_b`` at a step's ends may go
    below zero inside the step (see the module docstring)."""
    reach = abs(d_a) + abs(d_b)
    # p(s) >= min(h_a, h_b) - (4/27) reach on the whole step: far from zero, no minimum comes near it
    if min(h_a, h_b) > (4.0 / 27.0 + MARGIN) * reach:
        return False
    # the cubic Hermite p(s) = ((a s + b) s + d_a) s + h_a on s in [0, 1], and its critical points
    a = 2.0 * h_a - 2.0 * h_b + d_a + d_b
    b = -3.0 * h_a + 3.0 * h_b - 2.0 * d_a - d_b
    qa, qb, qc = 3.0 * a, 2.0 * b, d_a
    r0, r1 = -1.0, -1.0
    if qa == 0.0:
        if qb != 0.0:
            r0 = -qc / qb
    else:
        disc = qb * qb - 4.0 * qa * qc
        if disc < 0.0:
            return False
        sq = np.sqrt(disc)
        r0, r1 = (-qb - sq) / (2.0 * qa), (-qb + sq) / (2.0 * qa)
    for k in range(2):
        s = r0 if k == 0 else r1
        if 0.0 < s < 1.0 and 6.0 * a * s + 2.0 * b > 0.0 and ((a * s + b) * s + d_a) * s + h_a <= MARGIN * reach:
            return True
    return False


#: Levels of steps integrated again by :func:`checked` within one step (each a fresh start).
CHECK_DEPTH = 3
#: A step integrated again is integrated in at least this many steps (the rerun's largest step is the
#: flagged step's length over it): an excursion of an eighth of the step is resolved at the first level.
RERUN_STEPS = 8


@jit
def first_dip(prob, mode, guards, times, states, f, first, stop, fired):
    """The end index ``j >= first`` of the first step ``[times[j - 1], times[j]]`` (starting before ``stop``) in
    which a guard on its side at both ends may go below zero (:func:`may_dip`), or -1.

    ``times``, ``states``: the arc's step ends (and the root that ended it), the rows of the solver's
    state with the problem's states first (a row may carry more: the forcing's cos and sin, friction
    forces); ``guards``: rows ``(kind, index, expected sign)``; ``f``: scratch for the field (as long as
    the problem's state); ``fired``: the guard whose root ended the arc at the last row (-1: none), left
    out there (it is on its surface). A guard exactly on its surface at the arc's start (a phase start)
    is not looked at on the arc's first step: how it leaves its surface is the start rule's (and, at
    ``fs = fr``, a double zero whose cubic says nothing; integrated again from there, with short steps,
    SUNDIALS' root finding read the rounding of the double zero as a crossing). At the last row, cut short at the root of the guard that
    fired, another guard across its surface is flagged too: the root finding did not stop at it,
    since it had come back by the end of the whole step (elsewhere a guard is across only by the
    difference of the solver's formulation, a forcing state for instance, and is left to the core).
    """
    n = f.shape[0]
    ng = guards.shape[0]
    h0, d0 = np.empty(ng), np.empty(ng)
    fresh = np.zeros(ng, np.bool_)
    start = max(first - 1, 0)
    y = states[start, :n]
    law.rhs(prob, mode, times[start], y, f)
    for q in range(ng):
        kind, index, sign = guards[q, 0], guards[q, 1], guards[q, 2]
        h0[q] = sign * law.guard_value(prob, mode, kind, index, times[start], y)
        d0[q] = sign * law.guard_rate(prob, mode, kind, index, times[start], y, f)
        fresh[q] = start == 0 and h0[q] == 0.0
    for j in range(start + 1, times.shape[0]):
        t_a, t_b = times[j - 1], times[j]
        if t_a >= stop:
            break
        dt = t_b - t_a
        if dt <= 0.0:
            continue
        y = states[j, :n]
        law.rhs(prob, mode, t_b, y, f)
        tol = 0.0  # what a guard's value may be off by from rounding alone (the core's own measure)
        for i in range(n):
            tol = max(tol, abs(y[i]))
        tol = 64.0 * _EPS * max(1.0, tol)
        last = j == times.shape[0] - 1
        found = False
        for q in range(ng):
            kind, index, sign = guards[q, 0], guards[q, 1], guards[q, 2]
            h1 = sign * law.guard_value(prob, mode, kind, index, t_b, y)
            d1 = sign * law.guard_rate(prob, mode, kind, index, t_b, y, f)
            if h0[q] >= 0.0 and not (last and q == fired):
                if last and h1 < -tol:
                    found = True  # across, where the arc's last step was cut short at another guard's root
                elif h1 > 0.0 and not (fresh[q] and j == 1) and may_dip(h0[q], h1, dt * d0[q], dt * d1):
                    found = True
            h0[q], d0[q] = h1, d1
        if found:
            return j
    return -1


def checked(request, res, times: np.ndarray, states: np.ndarray, rerun, depth: int):
    """``res`` (an arc's :class:`~nsbench.integrators.base.ArcResult`) with every step of the arc checked.

    ``times``, ``states``: the arc's step ends (:func:`first_dip`); ``rerun(sub_request, depth)``: the
    same integrator's arc over a sub-request, freshly started, with steps of at most its span over
    :data:`RERUN_STEPS`, checked in turn. A step :func:`first_dip` flags is integrated again from its
    start to its end; a guard's root there ends the arc at it (the states,
    hits and trajectory points up to that time are the arc's own: the same solution to the method's
    tolerance). The reruns' work is added to the arc's counters (``extra['check_reruns']`` counts them).
    """
    import dataclasses

    res.extra["check_reruns"] = res.extra.get("check_reruns", 0)
    if depth >= CHECK_DEPTH or not request.guards or not res.status.ok or times.shape[0] < 2:
        return res
    problem = request.problem
    prob, mode = problem.data, problem.mode_array(request.mode)
    guards = np.array([(g.code, g.block - 1, g.expected_sign) for g in request.guards], dtype=np.int64)
    scratch = np.empty(problem.n_states)
    j = 1
    while True:
        fired = -1 if res.fired is None else int(res.fired)
        j = int(first_dip(prob, mode, guards, times, states, scratch, j, float(res.t), fired))
        if j < 0:
            return res
        start = np.array(states[j - 1, : problem.n_states], dtype=float)
        start.flags.writeable = False
        sub = dataclasses.replace(
            request, t0=float(times[j - 1]), y0=start, t_end=float(times[j]), t_eval=np.empty(0), t0_lo=0.0
        )
        again = rerun(sub, depth + 1)
        res.nfev += again.nfev
        res.njev += again.njev
        res.nsteps += again.nsteps
        for name, value in again.extra.items():
            res.extra[name] = res.extra.get(name, 0) + value
        res.extra["check_reruns"] += 1
        if not again.status.ok:  # the check could not be made: the arc fails with its reason
            res.status, res.message, res.fired = again.status, again.message, None
            res.t, res.y = again.t, again.y
            return res
        if again.fired is not None:  # the excursion is real: the arc ends at its crossing
            t_hit = float(again.t)
            kept = int(np.searchsorted(request.t_eval, t_hit, side="right"))
            res.t, res.t_lo, res.y, res.fired = t_hit, 0.0, again.y, again.fired
            res.y_eval = res.y_eval[:, :kept]
            res.section_hits = [hit for hit in res.section_hits if hit.t <= t_hit]
            return res
        j += 1
