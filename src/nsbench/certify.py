"""Certifying an event log: an independent run at higher precision bounds the error of each event time.

A reference-grade log (``reference``, ``exact``) is only as good as its check: the
first of :data:`CERTIFY_CHECKS` that accepts the problem runs over the same span
from the same start, and the difference of the two logs, event by event, plus an
ulp bounds the error of each event time (:func:`certified_errors`). From the first
event where the two logs differ in kind or block nothing is certified, and the note
says so (:data:`NOT_CERTIFIED_FROM`).

This module sits just above the engine (it calls :func:`nsbench.engine.simulate`)
and below the commands that certify: the bench's references
(:mod:`nsbench.bench.reference`) and ``nsbench simulate --integrator reference``,
which therefore needs no part of the bench.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pandas as pd

from nsbench.errors import UnsupportedProblemError

#: The event-log column of each event's certified error (a bound on ``|t - t_true|``).
CERTIFIED = "certified_error"

#: Ends the certification note of a log whose check gives another event sequence.
NOT_CERTIFIED_FROM = "not certified from there"

#: The independent checks of a reference-grade log, the first that accepts the problem.
#: ``exact-mp`` (the closed form in 40 digits, time and state never rounded between arcs)
#: for linear problems of at most :data:`MP_CHECK_STATES` states: an extended-precision
#: ``exact``. Otherwise heyoka's Taylor method in quad precision, at a tolerance looser than
#: ``reference``'s own (so a different step sequence) but far below double rounding.
CERTIFY_CHECKS: tuple[dict[str, Any], ...] = (
    {"name": "exact-mp", "options": {"digits": 40}},
    {"name": "heyoka-q", "options": {"tol": 1e-30}},
)
#: ``exact-mp`` runs in Python (mpmath matrices): past this many states (8 blocks) it would cost
#: minutes per run, and the quad Taylor check takes over.
MP_CHECK_STATES = 16


def _paired(events: pd.DataFrame, other: pd.DataFrame) -> tuple[np.ndarray, np.ndarray, float | None]:
    """Indices of the events of two logs paired over their common ``(kind, block)`` prefix, and the
    time of the first event where they differ (``None`` if they agree to the end). A Zeno tail the two
    resolved to different depths before the same accumulation event pairs its first events
    (:func:`nsbench.model.streaks.pair_events`); other logs pair one to one."""
    from nsbench.engine import event_labels, extrapolated_events
    from nsbench.model.streaks import pair_events

    pairs, stop = pair_events(
        event_labels(events), extrapolated_events(events), event_labels(other), extrapolated_events(other)
    )
    ia = np.array([i for i, _ in pairs], dtype=np.int64)
    ib = np.array([j for _, j in pairs], dtype=np.int64)
    if stop is None:
        return ia, ib, None
    i, j = stop
    return ia, ib, float(events["t"].iloc[i]) if i < len(events) else float(other["t"].iloc[j])


def compare_logs(events: pd.DataFrame, other: pd.DataFrame) -> tuple[np.ndarray, float | None]:
    """``|t - t_other|`` over the two event logs' common ``(kind, block)`` prefix (paired as
    :func:`_paired` says), and the time of the first event where they differ (``None`` if they agree
    to the end)."""
    ia, ib, at = _paired(events, other)
    dt = np.abs(other["t"].to_numpy(dtype=float)[ib] - events["t"].to_numpy(dtype=float)[ia])
    return dt, at


def _checks_for(problem, reference: str | None = None) -> list[dict[str, Any]]:
    """The checks that may certify ``reference``'s log of ``problem``: never the reference itself."""
    small_linear = problem.is_linear and problem.n_states <= MP_CHECK_STATES
    return [c for c in CERTIFY_CHECKS if (c["name"] != "exact-mp" or small_linear) and c["name"] != reference]


def _check_name(config: dict[str, Any]) -> str:
    options = " ".join(f"{k} {v:g}" if isinstance(v, float) else f"{k} {v}" for k, v in config["options"].items())
    return f"{config['name']} {options}".strip()


def certified_errors(
    problem, events: pd.DataFrame, t0: float, t_end: float, y0=None, reference: str | None = None
) -> tuple[np.ndarray, str]:
    """A bound on the error of each event time of ``events``, from an independent check.

    The first of :data:`CERTIFY_CHECKS` that accepts the problem (``exact-mp``
    for small linear ones) and is not the integrator named ``reference`` (the
    one that wrote ``events``) runs over the same span from the same start. Its
    event times are rounded once from values correct to far below an ulp, which
    leaves half an ulp; the other half covers readings of the problem that differ
    by a rounding of its coefficients (``exact`` forms ``k / m`` in double, the
    checks in their own precision; equal when the masses are 1). So ``|t -
    t_true| <= |t - t_check| + ulp(t_check)``: that bound is the event's
    certified error.
    Returns the array (one value per event of ``events``; NaN from the first
    event where the two logs differ in kind or block, with the reason in the
    note) and a one-line note naming the check.
    """
    from nsbench.engine import simulate
    from nsbench.errors import PluginLoadError
    from nsbench.integrators import integrator_from_config

    if _mp_check(problem):
        return _certified_in_mp(problem, events, t0, t_end, y0)
    out = np.full(len(events), np.nan)
    other, what = None, "no check accepts the problem"
    for config in _checks_for(problem, reference):
        what = _check_name(config)
        try:
            check = integrator_from_config(config)
        except PluginLoadError:  # not installed here: the next check certifies
            continue
        try:
            other = simulate(problem, check, t_end, t0=t0, y0=y0, max_steps=10**9, check_points=0).events
            break
        except UnsupportedProblemError:
            continue
        except Exception as exc:  # no check is no reason to lose the log
            return out, f"not certified: the check ({what}) failed: {type(exc).__name__}: {exc}"
    if other is None:
        return out, f"not certified: {what}"
    ia, ib, at = _paired(events, other)
    t_check = other["t"].to_numpy(dtype=float)[ib]
    out[ia] = np.abs(events["t"].to_numpy(dtype=float)[ia] - t_check) + np.spacing(np.abs(t_check))
    note = f"against {what}"
    if at is not None:
        note += f"; the event sequences differ from event {ia.size + 1} (t = {at:.6g}): {NOT_CERTIFIED_FROM}"
    return out, note


def _mp_check(problem) -> bool:
    """Whether the reference of ``problem`` is certified by a whole hybrid run in mp
    (:mod:`nsbench.integrators.mp_hybrid`): a small piecewise-linear problem whose law runs on mpmath
    numbers (``problem.mp_law``: the impact problems, whose resets and Zeno accumulations an arc-by-arc
    check through the double core would take from the double run)."""
    return bool(getattr(problem, "mp_law", False)) and problem.is_linear and problem.n_states <= MP_CHECK_STATES


def _certified_in_mp(problem, events: pd.DataFrame, t0: float, t_end: float, y0) -> tuple[np.ndarray, str]:
    """:func:`certified_errors` through :func:`nsbench.integrators.mp_hybrid.certify`: a bound per
    event, NaN from where the check cannot certify, with the reason in the note."""
    from nsbench.engine import event_labels, extrapolated_events
    from nsbench.integrators.mp_hybrid import certify

    times = events["t"].to_numpy(dtype=float)
    cert = certify(problem, times, event_labels(events), extrapolated_events(events), t0, t_end, y0)
    note = f"against {cert.what}"
    if cert.stop < len(times):
        note += f"; {cert.reason}: {NOT_CERTIFIED_FROM} (event {cert.stop + 1}, t = {times[cert.stop]:.6g})"
    return cert.bounds, note


def certainty_of(events: pd.DataFrame) -> float:
    """The largest certified error of a log: ``inf`` if some event is not certified, NaN if none is."""
    if CERTIFIED not in events or not len(events):
        return math.nan
    c = events[CERTIFIED].to_numpy(dtype=float)
    if np.isnan(c).all():
        return math.nan
    return math.inf if np.isnan(c).any() else float(c.max())
