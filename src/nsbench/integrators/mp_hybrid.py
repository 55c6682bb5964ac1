"""A whole hybrid run in extended precision: the independent check of a reference on impact problems.

``exact-mp`` driven by the core (:mod:`nsbench.hybrid`) keeps its mp state across an event only when
the transition left the state alone (or set friction velocities to the belt speed): an impact's reset
is the core's, applied in double, and the core's Zeno rule extrapolates accumulations from double
event times. Such a run repeats the double run's roundings where they matter most, so it cannot
certify it. :func:`hybrid_run` runs the whole hybrid model in ``digits`` decimal digits instead:

- the arcs are ``exact-mp``'s (closed-form flow, rigorous crossing search), started from the mp time
  and state where the last one stopped;
- the law's transitions, start rule and accumulation limit are the law module's own functions run as
  plain Python on mpmath numbers (:func:`python_law`), so every reset is applied in mp; a law may use
  ``math`` functions only in sign decisions (the impact oscillator's pressing force), which are then
  taken in double;
- a guard of a new mode already on its wrong side fires at once, as in
  :func:`nsbench.model.rules.pending_guard`, tested in mp;
- an accumulation of events of one guard (Zeno) is extrapolated with the core's geometric tail
  (:func:`nsbench.model.rules.tail_estimate`, on mp times) only once its error estimate is below
  ``tolerance * max(1, |t|)`` (default ``1e-24``, far below a double's resolution; the double rule
  stops ~1e8 times coarser), and the accumulation limit is applied in mp. A sequence that reaches
  the working precision's resolution first ends the run with :class:`ArithmeticError`.

The result is a list of :class:`MpEvent`: time and state in mp, the event kind's code, the element
index, the mode, and for an accumulation its error estimate.
"""

from __future__ import annotations

import types
from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

from nsbench.integrators.base import ArcRequest
from nsbench.model.rules import ACCUMULATION_RATIO
from nsbench.model.rules import rounding_error as _compiled_rounding
from nsbench.model.rules import tail_estimate as _compiled_tail

#: The core's tail estimate and its rounding term as plain Python (written for doubles and mp numbers alike).
_tail_estimate = _compiled_tail.py_func
_rounding_error = _compiled_rounding.py_func

#: An extrapolated accumulation time is accepted once its error estimate is below this, times max(1, |t|).
TOLERANCE = "1e-24"
#: Events of one run at most (a runaway sequence is an error, not a hang).
MAX_EVENTS = 200_000


@dataclass
class MpEvent:
    """One event of an mp run: time, state and mode after it, kind code, element index."""

    t: Any  # mpf
    code: int
    index: int
    y: list  # mpf
    mode: tuple
    #: The tail's error estimate (mpf) of an accumulation event, ``None`` for every other event.
    accumulation_error: Any = None


def python_law(problem) -> dict[str, Callable]:
    """The law's functions as plain Python: numba's ``py_func`` of each, with every compiled function it
    calls replaced by that one's ``py_func`` (recursively), so that they run on mpmath numbers."""
    from numba.core.dispatcher import Dispatcher

    memo: dict[Any, Callable] = {}

    def plain(fn):
        if fn in memo:
            return memo[fn]
        py = fn.py_func
        scope = dict(py.__globals__)
        clone = types.FunctionType(py.__code__, scope, py.__name__, py.__defaults__, py.__closure__)
        memo[fn] = clone
        for name, value in list(scope.items()):
            if isinstance(value, Dispatcher):
                scope[name] = plain(value)
        return clone

    return {name: plain(fn) for name, fn in problem.law.functions.items()}


class _Streak:
    """The event times of the current run of events of one guard and kind (mp), for accumulations."""

    def __init__(self) -> None:
        self.key: tuple | None = None
        self.times: list = []

    def push(self, key: tuple, t) -> list:
        if key != self.key:
            self.key, self.times = key, []
        self.times.append(t)
        del self.times[:-4]
        return self.times

    def clear(self) -> None:
        self.key, self.times = None, []


def hybrid_run(
    problem,
    t_end: float,
    *,
    t0: float = 0.0,
    y0=None,
    digits: int = 40,
    tolerance: str = TOLERANCE,
    max_events: int = MAX_EVENTS,
) -> list[MpEvent]:
    """The event log of ``problem`` over ``[t0, t_end]`` with time, state, resets and accumulations in mp.

    Raises
    ------
    ArithmeticError
        An arc that fails (``exact-mp``'s search), an accumulation that reaches the working precision's
        resolution before its tolerance, or more than ``max_events`` events.
    UnsupportedProblemError
        A problem ``exact-mp`` refuses (not piecewise linear).
    """
    from nsbench.integrators.exact_mp import ExactMP, _Arc

    integ = ExactMP(digits=digits)
    integ.setup(problem)
    ctx = integ._ctx
    law = python_law(problem)
    model = integ._model
    n = problem.n_states
    p = [ctx.mpf(float(v)) for v in problem.data.p]
    t = ctx.mpf(float(t0))
    y = [ctx.mpf(float(v)) for v in (problem.initial_state() if y0 is None else y0)]
    mode = [0] * problem.mode_size
    law["initial_mode"](p, t, y, mode)
    fresh = [False] * max(problem.n_elements, 1)
    law["start_fresh"](p, mode, t, y, fresh)
    z = _augmented(ctx, model, t, y)
    tol = ctx.mpf(tolerance)
    resolution = ctx.ldexp(1, 24 - ctx.prec)  # far below any excursion a sequence is resolved at
    streak = _Streak()
    events: list[MpEvent] = []
    span_end = ctx.mpf(float(t_end))
    while True:
        guards = problem.guards(tuple(mode))
        flow = integ._flow(tuple(mode))
        q = _pending(ctx, flow, integ, guards, fresh, z, n)
        if q is None:
            request = ArcRequest(
                problem=problem,
                mode=tuple(mode),
                t0=float(t),
                y0=np.array([float(v) for v in z[:n]]),
                t_end=float(t_end),
                guards=guards,
                max_steps=10**12,
            )
            arc = _Arc(integ, request, start=(t, list(z))).run()
            if not arc.status.ok:
                raise ArithmeticError(f"exact-mp arc from t = {float(t):.17g} failed: {arc.message}")
            if arc.fired is None:
                return events
            carry = integ._carry
            assert carry is not None  # an arc that fired keeps its mp stop
            _, _, _, t, z = carry
            q = arc.fired
        guard = guards[q]
        kind, index = guard.code, guard.block - 1
        y = list(z[:n])
        fresh = [False] * len(fresh)
        code = law["transition"](p, mode, kind, index, t, y, fresh)
        events.append(MpEvent(t, int(code), index, list(y), tuple(int(v) for v in mode)))
        if len(events) > max_events:
            raise ArithmeticError(f"more than {max_events} events by t = {float(t):.17g}")
        z = list(y) + list(z[n:])
        times = streak.push((kind, index, int(code)), t)
        if len(times) == 4:
            t_z, err, ratio = _tail_estimate(times[0], times[1], times[2], times[3], ACCUMULATION_RATIO)
            if t_z == t_z and err < ctx.inf:  # and the rounding of the mp times (as in the double rule)
                err = err + _rounding_error(t, ratio, ctx.eps)
            if t_z == t_z and err <= tol * max(1, abs(t)):  # a finite estimate within the tolerance
                if t_z >= span_end:
                    return events
                limit = law["accumulation_limit"](p, mode, kind, index, t_z, y)
                if limit >= 0:
                    t = t_z
                    events.append(MpEvent(t, int(limit), index, list(y), tuple(int(v) for v in mode), err))
                    z = _augmented(ctx, model, t, y)
                    streak.clear()
                    continue
            elif t_z == t_z and _excursion(ctx, integ, integ._flow(tuple(mode)), guard, z, times) <= resolution * max(
                1, _norm(y)
            ):
                raise ArithmeticError(
                    f"an accumulation at t = {float(t):.17g} reaches the resolution of {integ.settings['digits']} "
                    f"digits with its tail's error estimate {float(err):.2g} above the tolerance {tolerance}"
                )


def _augmented(ctx, model, t, y) -> list:
    """``[y, 1]`` (``[y, 1, cos w t, sin w t]`` with forcing), in mp."""
    z = list(y) + [ctx.one]
    if model.forced:
        from nsbench.integrators.exact_mp import _frequency

        wt = ctx.mpf(_frequency(model.problem)) * t
        z += [ctx.cos(wt), ctx.sin(wt)]
    return z


def _norm(y) -> Any:
    return max(abs(v) for v in y)


def _row(integ, flow, guard):
    key = (guard.code, guard.block - 1)
    return flow.row(key, lambda: integ._model.guard(*key))


def _pending(ctx, flow, integ, guards, fresh, z, n) -> int | None:
    """The first guard of the new mode that must fire at once (on its wrong side, or on its surface
    heading there), as :func:`nsbench.model.rules.pending_guard` in mp; ``None`` if there is none."""
    for q, guard in enumerate(guards):
        if fresh[guard.block - 1]:
            continue
        row = _row(integ, flow, guard)
        g = guard.expected_sign * ctx.fdot(row.q, z)
        tol = ctx.ldexp(1, 16 - ctx.prec) * max(1, abs(g), _norm(z[:n]))
        if g < -tol:
            return q
        if abs(g) <= tol and guard.expected_sign * ctx.fdot(row.qm, z) < 0:
            return q
    return None


def _excursion(ctx, integ, flow, guard, z, times) -> Any:
    """How far the streak's guard moves from its surface over the next interval (``|rate| d / 4``, the
    height of a parabola), the scale at which its next event is resolved."""
    rate = abs(ctx.fdot(_row(integ, flow, guard).qm, z))
    return rate * (times[-1] - times[-2]) / 4


# ---------------------------------------------------------------------- certifying a double log with it
#: The two precisions of the check: their difference estimates the error of the finer one.
DIGITS = (40, 50)
#: The coarser run's difference from the finer one past which its error is no longer small enough for
#: that estimate (relative to max(1, |t|)): far from the linear regime's end, far above any double's error.
RESOLVED = 1e-12


@dataclass
class Certification:
    """Per event of a double log: a bound on its time's error (NaN where not certified), and why not."""

    bounds: np.ndarray
    #: What certified it (one line).
    what: str
    #: Index of the first event not certified (``len(bounds)`` if all are), and the reason.
    stop: int
    reason: str = ""


def _context(run: list):
    """The mp context of a run's numbers (a fresh one for an empty run)."""
    import mpmath

    return run[0].t.context if run else mpmath.MPContext()


def _identified(run: list, extrapolated: list, k: int):
    """Half the time from event ``k`` of an mp run to its nearest other event (not counting an
    extrapolated one, whose time is that of a tail): an event of another log closer than this to it
    is that event, one farther may be its neighbour."""
    gaps = []
    if k > 0 and not extrapolated[k - 1]:
        gaps.append(run[k].t - run[k - 1].t)
    if k + 1 < len(run) and not extrapolated[k + 1]:
        gaps.append(run[k + 1].t - run[k].t)
    return min(gaps) / 2 if gaps else float("inf")


def certify(
    problem,
    times: np.ndarray,
    labels: list,
    extrapolated: np.ndarray,
    t0: float,
    t_end: float,
    y0=None,
    digits: tuple[int, int] = DIGITS,
) -> Certification:
    """Bound the error of each event time of a double event log of ``problem`` (its ``times``, its events'
    ``(kind, block)`` ``labels``, and which of them the Zeno rule ``extrapolated``) with two independent
    mp runs of the whole hybrid model (:func:`hybrid_run`, at ``digits``).

    The finer run's time ``T`` of an event has the error estimate ``e = |T - T_coarse|`` (its own
    roundings are ``10^-(digits[1]-digits[0])`` times those of the coarser run, which the difference
    measures, as long as that stays below :data:`RESOLVED`), plus at an accumulation its tail's error
    estimate; an event time ``t`` of the log is then within ``|t - T| + e + ulp(T)`` of the true one
    (the ulp: half for the rounding of ``T``, half for a reading of the problem rounded otherwise).
    Events are paired across the logs as :func:`nsbench.model.streaks.pair_events` does (a Zeno tail
    the log resolved less deep than the check pairs its first events). Certification ends at the first
    event where the log and the check, or the check's two precisions, do not agree, or where the
    coarser precision no longer resolves the finer one's events (a chaotic span past what it resolves).
    """
    from nsbench.model.streaks import pair_events

    times = np.asarray(times, dtype=float)
    n_events = len(times)
    bounds = np.full(n_events, np.nan)
    what = f"an independent run of the whole hybrid model in {digits[0]} and {digits[1]} digits"
    try:
        runs = [hybrid_run(problem, t_end, t0=t0, y0=y0, digits=d) for d in digits]
    except (ArithmeticError, ValueError) as exc:
        return Certification(bounds, what, 0, f"the check failed: {type(exc).__name__}: {exc}")
    coarse, fine = runs
    kinds = problem.event_kinds

    def mp_labels(run):
        return [(kinds[e.code], e.index + 1) for e in run], [e.accumulation_error is not None for e in run]

    lc, xc = mp_labels(coarse)
    lf, xf = mp_labels(fine)
    pairs_cf, stop_cf = pair_events(lf, xf, lc, xc)
    own = [None] * len(fine)  # the finer run's error estimate per event, None past what it resolves
    reason = ""
    for i, j in pairs_cf:
        t_f = fine[i].t
        e = abs(t_f - coarse[j].t)
        if e > RESOLVED * max(1, abs(t_f)):
            reason = (
                f"the check's {digits[0]}- and {digits[1]}-digit runs differ by {float(e):.2g} at t = "
                f"{float(t_f):.6g}: past what {digits[0]} digits resolve"
            )
            break
        if fine[i].accumulation_error is not None:
            e = e + fine[i].accumulation_error
        own[i] = e
    else:
        if stop_cf is not None and stop_cf[0] < len(fine):
            reason = (
                f"the check's {digits[0]}- and {digits[1]}-digit runs give other events from t = "
                f"{float(fine[stop_cf[0]].t):.6g}: past what {digits[0]} digits resolve"
            )
    pairs, stop = pair_events(labels, extrapolated, lf, xf)
    ctx = _context(fine)
    first_missing = n_events
    for n, (i, k) in enumerate(pairs):
        if i != n:  # the log resolved a Zeno tail deeper than the check: those events are not checked
            first_missing = n
            reason = f"the log resolves a Zeno tail at t = {times[n]:.6g} deeper than the check"
            break
        if own[k] is None:
            first_missing = i
            break
        t_f = fine[k].t
        dt = abs(ctx.mpf(times[i]) - t_f)
        if not xf[k] and dt > _identified(fine, xf, k):
            first_missing = i
            reason = (
                f"the log's event {i + 1} (t = {times[i]:.6g}) is {float(dt):.2g} from the check's, more than "
                "half the time to the check's next or previous event: the two no longer show the same events"
            )
            break
        bound = dt + own[k]
        bounds[i] = float(bound) * (1 + 2.0**-50) + float(np.spacing(abs(float(t_f))))
    else:
        if stop is not None and stop[0] < n_events:
            first_missing = stop[0]
            reason = f"the event sequences differ from event {stop[0] + 1} (t = {times[stop[0]]:.6g})"
    if first_missing < n_events:
        bounds[first_missing:] = np.nan
        if not reason:
            reason = f"the events from t = {times[first_missing]:.6g} are in a span the check does not resolve"
    return Certification(bounds, what, first_missing, reason)
