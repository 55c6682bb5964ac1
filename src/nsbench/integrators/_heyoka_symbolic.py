"""heyoka's Taylor integrator for a problem that writes its field symbolically (``symbolic_field``).

A problem outside the friction family can give heyoka its field and guards as
expressions built with ``+ - *`` from heyoka's variables
(``problem.symbolic_field(mode, t, y)``, ``problem.symbolic_guard(mode, kind,
index, t, y)``; ``henon-heiles`` does). One ``taylor_adaptive`` is compiled per
mode visited (its guards as terminal events, ``expected_sign * guard``
decreasing through zero), cached per process. An arc loads time (double-length,
so ``t0 + t0_lo`` is exact) and state and propagates to ``t_end`` or the first
guard.

heyoka does not look for roots of an event function that is zero where a step
starts, so a phase that starts on its own surface takes its first step alone
and looks for a crossing on that step's polynomial (:func:`first_crossing`), as
the friction model does.
"""

from __future__ import annotations

import copy
import threading
import time
from typing import Any

import heyoka as hy
import numpy as np

from nsbench.integrators._heyoka_model import FP_TYPES, illinois

#: The cooldown of every guard's event, in the problem's time scale. heyoka reports the start of a step as a root
#: when a guard is exactly zero there and its rate points into the surface by a rounding error (a tangential
#: start); the report sets this cooldown, which lets the next step start past it (heyoka_.py, the fresh step).
#: Every arc resets the cooldowns, and every other report ends its arc: nothing else sees it.
START_COOLDOWN = 1e-12
_CACHE: dict[tuple, tuple[Any, float]] = {}
_LOCK = threading.Lock()


def supports(problem) -> bool:
    """Whether ``problem`` writes its field and guards for symbolic integrators."""
    return callable(getattr(problem, "symbolic_field", None)) and callable(getattr(problem, "symbolic_guard", None))


def compiled(
    problem, mode: tuple[int, ...], precision: str, tol: float | None, high_accuracy: bool, compact_mode: bool
) -> tuple[Any, float]:
    """A fresh copy of the integrator of ``mode`` and the seconds its compilation took (0 on a cache hit)."""
    key = (problem.name, problem.packed.tobytes(), tuple(mode), precision, tol, high_accuracy, compact_mode)
    with _LOCK:
        hit = _CACHE.get(key)
        if hit is None:
            fp = FP_TYPES[precision]
            tic = time.perf_counter()
            y = hy.make_vars(*problem.state_names)
            field = problem.symbolic_field(mode, hy.time, y)
            neg = hy.event_direction.negative
            events = [
                hy.t_event(
                    float(g.expected_sign) * problem.symbolic_guard(mode, g.code, g.block - 1, hy.time, y),
                    direction=neg,
                    cooldown=fp(START_COOLDOWN * problem.time_scale),
                    fp_type=fp,
                )
                for g in problem.guards(tuple(mode))
            ]
            kwargs = {} if tol is None else {"tol": fp(tol)}
            ta = hy.taylor_adaptive(
                list(zip(y, field)),
                np.zeros(len(y), dtype=fp),
                fp_type=fp,
                t_events=events,
                high_accuracy=high_accuracy,
                compact_mode=compact_mode,
                **kwargs,
            )
            hit = _CACHE[key] = (ta, time.perf_counter() - tic)
            return copy.deepcopy(ta), hit[1]
    return copy.deepcopy(hit[0]), 0.0


def first_crossing(ta, fp, guard, t_start, t_end):
    """First zero of ``expected_sign * guard`` in ``(t_start, t_end]`` after it left zero, on the step's dense
    output (in ``fp``), or ``None``."""
    sign = guard.expected_sign
    n = guard.problem.n_states

    def value(t):
        y = ta.update_d_output(t)
        return fp(sign * float(guard.value(float(t), np.asarray(y[:n]).astype(float))))

    lo, g_lo, positive = t_start, fp(0.0), False
    # A phase shorter than the first sample's distance (a ball's late bounces within one long Taylor step
    # of a quadratic flight): its guard is back on the wrong side there. Halve toward the start, where the
    # guard left its surface, for a point on its own side; the first zero lies between that and the last
    # point on the wrong side. None if no such point (the guard went to its wrong side at once).
    hi = t_start + (t_end - t_start) / fp(32)
    g_hi = value(hi)
    if not g_hi > 0:
        for _ in range(64):
            t = t_start + (hi - t_start) / fp(2)
            if not t_start < t < hi:
                return None
            g = value(t)
            if g > 0:
                return illinois(value, t, g, hi, g_hi)
            hi, g_hi = t, g
        return None
    for k in range(1, 33):
        t = t_start + (t_end - t_start) * fp(k) / fp(32)
        g = value(t)
        if g > 0:
            lo, g_lo, positive = t, g, True
        elif positive:
            return illinois(value, lo, g_lo, t, g)
    return None
