"""Bifurcations of periodic orbits: located by bisection on the orbit's signature, named by their mechanism.

The *signature* of a converged orbit is its cyclic event pattern and the
number of its multipliers outside the unit circle. Between two continuation
steps whose signatures differ, :func:`locate` bisects the parameter (each probe
a converged periodic orbit, :func:`~nsbench.periodic.shooting.shoot`) until the
bracket is narrower than ``xtol`` (default ``1e-11``, so the located value is
good to well below ``1e-8``). A probe where no orbit of the near side's kind
exists counts as the far side, so the end of a branch is located the same way.

The two orbits at the ends of the final bracket then decide the kind
(:func:`classify`); the rule, with ``g`` the guard of an event:

=====================  =====================================================  ==================
kind                   what is degenerate on the orbit at the bifurcation     paper's category
=====================  =====================================================  ==================
``grazing-sliding``    a slip phase's ``v - v0`` touches zero with zero       ``sliding`` (a
                       slope: at a stick or reverse event (the event is        sticking phase
                       about to vanish) or inside a slip arc (a new one is     appears or
                       about to appear)                                        vanishes)
``crossing-sliding``   at a stick event ``|R| -> fr``: the locus of sticking  ``border-collision``
                       phase starts on the boundary of its sliding region;
                       beyond, the stick turns into a reverse
``multi-sliding``      a stick phase's ``|R| - fr`` touches zero with zero    ``border-collision``
                       slope: the locus of sticking phase reaches the
                       boundary of its sliding region tangentially
``period-doubling``    same pattern, a real multiplier crosses ``-1``         ``fixed-point``
``fold``               same pattern, a real multiplier crosses ``+1``         ``fixed-point``
``torus``              same pattern, a complex pair crosses the unit circle   ``fixed-point``
``unclassified``       nothing on the orbits is degenerate (relative size     ``unknown``
                       above 1e-3): reported as such, never guessed
``event-order``        two events of different blocks coincide and swap;     ``none`` (not a
                       the orbit passes through continuously                   bifurcation)
=====================  =====================================================  ==================

The degeneracies are measured relative to their own scale (the guard rate
against the largest rate of the same guard on the orbit; the margin against
``fr``), and the smallest one names the kind; ``detail`` states it with its
value, which makes every classification checkable.
"""

from __future__ import annotations

import math
from collections import Counter
from dataclasses import dataclass
from typing import TYPE_CHECKING, Callable, cast

import numpy as np

from nsbench.periodic import degenerate
from nsbench.periodic.flow import HybridFlow, is_friction
from nsbench.periodic.shooting import PeriodicOrbit, anchor, resolve

if TYPE_CHECKING:  # pragma: no cover
    from nsbench.problems.oscillator import FrictionOscillator


@dataclass(frozen=True)
class Bifurcation:
    """A located bifurcation: parameter value, mechanism, the paper's category and a readable detail."""

    param: str
    value: float
    kind: str
    category: str
    detail: str
    bracket: float
    left_pattern: str
    right_pattern: str
    left_multipliers: str
    right_multipliers: str

    def row(self) -> dict:
        return dict(self.__dict__)


#: The paper's category of each kind (see the module docstring).
CATEGORY = {
    "grazing-sliding": "sliding",
    "crossing-sliding": "border-collision",
    "multi-sliding": "border-collision",
    "period-doubling": "fixed-point",
    "fold": "fixed-point",
    "torus": "fixed-point",
    "event-order": "none",
    "unknown": "border-collision",
    "unclassified": "unknown",
}
#: A degenerate quantity larger than this (relative to its scale) does not name a bifurcation.
UNCLEAR = 1e-3


def signature(orbit: PeriodicOrbit | None) -> tuple:
    return ("none",) if orbit is None else (orbit.pattern, orbit.unstable_count)


def _probe(flow: HybridFlow, problem_at: Callable, value: float, near: PeriodicOrbit) -> PeriodicOrbit | None:
    flow.rebind(problem_at(value))
    return resolve(flow, near)


def _reanchored(flow: HybridFlow, orbit: PeriodicOrbit) -> PeriodicOrbit:
    """The same orbit described from the middle of its longest arc (no new Newton solve)."""
    from nsbench.periodic.shooting import restart

    flow.rebind(orbit.problem)
    return restart(flow, orbit, *anchor(flow, orbit))


def locate(
    flow: HybridFlow,
    problem_at: Callable,
    param: str,
    a: float,
    orbit_a: PeriodicOrbit,
    b: float,
    orbit_b: PeriodicOrbit | None,
    xtol: float = 1e-11,
) -> tuple[Bifurcation, PeriodicOrbit, PeriodicOrbit | None]:
    """Bisect ``[a, b]`` where the orbit's signature changes; classify the change.

    ``orbit_b`` is ``None`` where the branch ends (no orbit of ``orbit_a``'s kind at ``b``).
    Returns the bifurcation and the orbits at the final bracket's ends.
    """
    sig_a = signature(orbit_a)
    far_end = b + (b - a)  # refine_end may look this far (the quantity's zero lies beyond Newton's reach)
    while abs(b - a) > xtol:
        m = 0.5 * (a + b)
        if m in (a, b):
            break
        orbit_m = _probe(flow, problem_at, m, orbit_a)
        if orbit_m is not None and signature(orbit_m) == sig_a:
            a, orbit_a = m, orbit_m  # its start point is the near orbit's anchor, still mid-arc
        else:
            b, orbit_b = m, orbit_m
    if orbit_b is not None and not continuous(orbit_a, orbit_b):
        orbit_b = None  # Newton jumped to another orbit: the near side's orbit ends here
    value = 0.5 * (a + b)
    if orbit_b is None:
        # No orbit beyond: where the first probe failed is not where the branch ends.
        flow.rebind(orbit_a.problem)
        found = survey(flow, orbit_a)
        near_one = orbit_a.multipliers.size and np.min(np.abs(orbit_a.multipliers - 1.0)) < 1e-2
        key = found[0][3] if found and found[0][0] < 0.1 else ("multiplier",) if near_one else None
        if key is not None:  # worth following to zero; classify() judges the result
            value, orbit_a = refine_end(flow, problem_at, a, orbit_a, key, far_end)
            a = b = value
            if not is_friction(orbit_a.problem) and key[0] != "multiplier":
                # Newton stops short of the zero (an impact's saltation grows like one over its speed,
                # and the shooting Jacobian's condition with it): the zero is extrapolated along the
                # smooth, near-linear quantity; the bracket is the extrapolated distance.
                value, a = extrapolate_end(flow, problem_at, orbit_a, key, value)
                b = value
    left, right = (orbit_a, orbit_b) if a < b else (orbit_b, orbit_a)
    if orbit_b is not None:
        kind, category, detail = classify(flow, orbit_a if a < b else orbit_b, orbit_b if a < b else orbit_a)
    else:
        kind, category, detail = classify(flow, orbit_a, None)
    bif = Bifurcation(
        param,
        value,
        kind,
        category,
        detail,
        abs(b - a),
        left.pattern_text() if left is not None else "",
        right.pattern_text() if right is not None else "",
        format_multipliers(left.multipliers) if left is not None else "",
        format_multipliers(right.multipliers) if right is not None else "",
    )
    return bif, orbit_a, orbit_b


def continuous(a: PeriodicOrbit, b: PeriodicOrbit, rel: float = 1e-6) -> bool:
    """Whether two orbits at nearly the same parameter value are the same orbit (equal periods)."""
    return abs(a.period - b.period) <= rel * max(a.period, b.period)


def format_multipliers(mu: np.ndarray, digits: int = 6) -> str:
    """Multipliers as ``re+imj`` text, largest modulus first (space separated)."""
    out = []
    for z in mu:
        if abs(z.imag) <= 1e-12 * max(1.0, abs(z)):
            out.append(f"{z.real:.{digits}g}")
        else:
            out.append(f"{z.real:.{digits}g}{z.imag:+.{digits}g}j")
    return " ".join(out)


def _arcs(orbit: PeriodicOrbit):
    """``(t_start, y_start, mode, duration)`` of each arc of one period."""
    t, y, mode = orbit.t0, orbit.y0, orbit.mode0
    for e in orbit.events:
        yield t, y, mode, e.t - t
        t, y, mode = e.t, e.y, e.mode_after
    yield t, y, mode, orbit.t0 + orbit.period - t


def _family(guard) -> tuple[str, int]:
    return ("velocity" if guard.kind == "velocity" else "static", guard.block)


def _event_rate(problem, e) -> float:
    return abs(float(e.guard.rate(e.t, e.y, problem.rhs(e.mode_before, e.t, e.y))))


def _margin(problem, e) -> float:
    return problem.coefficients.fr[e.block - 1] - abs(float(problem.restoring_force(e.block, e.t, e.y)))


def measure(flow: HybridFlow, orbit: PeriodicOrbit, key: tuple) -> float:
    """The degenerate quantity ``key`` of :func:`survey` on ``orbit``, as a function that is smooth
    and crosses zero at the bifurcation: the squared guard rate at an event (a grazing's rate
    goes like the square root of the distance), the margin ``fr - |R|``, or an arc's dip."""
    problem = flow.problem
    if key[0] != "multiplier" and not is_friction(problem):
        return degenerate.measure(orbit.problem, orbit, key)
    if key[0] == "multiplier":  # at a fold, 1 - mu goes like the square root of the distance
        z = orbit.multipliers[np.argmin(np.abs(orbit.multipliers - 1.0))]
        return float(1.0 - z.real) ** 2
    if key[0] == "rate":
        return _event_rate(problem, orbit.events[key[1]]) ** 2
    if key[0] == "margin":
        return _margin(problem, orbit.events[key[1]])
    _, arc, kind, block = key
    t0, y0, mode, dt = list(_arcs(orbit))[arc]
    g = next(g for g in problem.guards(mode) if g.kind == kind and g.block == block)

    return _dip(flow, g, t0, y0, mode, 1e-9 * dt, dt * (1 - 1e-9), 1e-12 * max(1.0, dt))[0]


def _dip(flow: HybridFlow, g, t0: float, y0, mode, lo: float, hi: float, xatol: float) -> tuple[float, float]:
    """Smallest ``expected_sign * g`` along the arc from ``(t0, y0, mode)`` at ``s`` in ``[lo, hi]``:
    ``(value, s)``."""
    import scipy.optimize

    def value(s):
        y = flow.states(t0, y0, mode, np.array([t0 + s]))[0]
        return g.expected_sign * float(g.value(t0 + s, y))

    res = scipy.optimize.minimize_scalar(value, bounds=(lo, hi), method="bounded", options={"xatol": xatol})
    return float(res.fun), float(res.x)


def refine_end(
    flow: HybridFlow,
    problem_at: Callable,
    value: float,
    orbit: PeriodicOrbit,
    key: tuple,
    toward: float,
    xtol: float = 1e-12,
    max_iter: int = 40,
) -> tuple[float, PeriodicOrbit]:
    """Where the degenerate quantity ``key`` of the orbit reaches zero, by secant steps on the near side.

    Newton's region of convergence shrinks near a grazing, so the first failing
    shooting step only brackets the end of a branch loosely; the quantity itself
    is smooth on the near side and is extrapolated to zero (each secant point a
    converged orbit of the same signature; a failed point is approached by halving).
    """
    sig = signature(orbit)
    flow.rebind(orbit.problem)
    pts = [(value, measure(flow, orbit, key))]
    step = (toward - value) / 4
    for _ in range(max_iter):
        if len(pts) >= 2:
            (x0, f0), (x1, f1) = pts[-2], pts[-1]
            guess_x = x1 - f1 * (x1 - x0) / (f1 - f0) if f1 != f0 else x1 + step
        else:
            guess_x = value + step
        lo, hi = sorted((pts[-1][0], toward))
        if not lo <= guess_x <= hi:  # a flat or noisy quantity extrapolates far: stay in the bracket
            guess_x = 0.5 * (pts[-1][0] + toward)
        nxt = None
        for _half in range(30):
            if abs(guess_x - pts[-1][0]) <= xtol:
                return guess_x, orbit
            cand = _probe(flow, problem_at, guess_x, orbit)
            if cand is not None and signature(cand) == sig:
                nxt = cand
                break
            guess_x = pts[-1][0] + 0.5 * (guess_x - pts[-1][0])
        if nxt is None:
            break
        orbit = nxt
        pts.append((guess_x, measure(flow, orbit, key)))
    return pts[-1][0], orbit


def extrapolate_end(flow: HybridFlow, problem_at: Callable, orbit: PeriodicOrbit, key: tuple, value: float):
    """``(zero, value)``: the zero of the quantity ``key`` by a secant through the converged orbit at
    ``value`` and one a little back towards the branch, where the quantity is smooth.

    The second point lies back by ``1e-4 max(|value|, 1e-3)``, halved until an orbit of the same
    signature converges there: Newton's reach ends where the shooting Jacobian's condition (an
    impact's saltation grows like one over its speed) eats the tolerance, so the second point
    must stay clear of it; the quantity is near linear there, so the secant is near exact.
    ``(value, value)`` if no second orbit is found or the zero is not ahead.
    """
    f1 = measure(flow, orbit, key)
    if f1 == 0.0:
        return value, value
    back = 1e-4 * max(abs(value), 1e-3)
    for _ in range(20):
        other = _probe(flow, problem_at, value - back, orbit)
        if other is not None and signature(other) == signature(orbit):
            break
        back *= 0.5
    else:
        return value, value
    f0 = measure(flow, other, key)
    f1 = measure(flow, orbit, key)
    x0 = value - back
    if f1 == f0:
        return value, value
    zero = value - f1 * (value - x0) / (f1 - f0)
    if (zero - value) * (value - x0) < 0:  # the zero is behind: no extrapolation
        return value, value
    return zero, value


def survey(flow: HybridFlow, orbit: PeriodicOrbit, samples: int = 65) -> list[tuple[float, str, str, tuple]]:
    """Every near-degenerate quantity of an orbit as ``(relative size, kind, text, key)``, smallest first.

    ``key`` names the quantity for :func:`measure`.

    - at each event, the rate of its guard (zero: the orbit touches the surface tangentially);
    - at each stick or reverse, the margin ``fr - |R|`` (zero: the locus of sticking phase
      starts on the boundary of its sliding region);
    - along each arc, the closest interior approach of each guard to zero (zero: a new
      event is about to appear). Minima at an arc's ends are its events and are skipped.

    Rates and values are measured against the largest rate and value of the same guard
    family (velocity or static limit, per block) sampled along the whole orbit.
    """
    problem = flow.problem
    if not is_friction(problem):
        return degenerate.survey(problem, orbit, samples)
    rate_scale: dict[tuple, float] = {}
    value_scale: dict[tuple, float] = {}
    dips = []
    for arc, (t0, y0, mode, dt) in enumerate(_arcs(orbit)):
        if dt <= 0:
            continue
        times = t0 + dt * np.linspace(0.0, 1.0, samples)[1:-1]
        ys = flow.states(t0, y0, mode, times)
        f = problem.rhs(mode, times, ys.T)
        for g in problem.guards(mode):
            fam = _family(g)
            vals = g.expected_sign * np.asarray(g.value(times, ys.T), dtype=float)
            rates = np.asarray(g.rate(times, ys.T, f), dtype=float)
            value_scale[fam] = max(value_scale.get(fam, 0.0), float(np.max(np.abs(vals))))
            rate_scale[fam] = max(rate_scale.get(fam, 0.0), float(np.max(np.abs(rates))))
            k = int(np.argmin(vals))
            if k == 0 or k == vals.size - 1:  # monotone towards an end: that end is an event
                continue
            low, s_low = _dip(flow, g, t0, y0, mode, times[k - 1] - t0, times[k + 1] - t0, 1e-10 * max(1.0, dt))
            dips.append((low, g, fam, t0 + s_low, ("dip", arc, g.kind, g.block)))
    out: list[tuple[float, str, str, tuple]] = []
    for v, g, fam, t, key in dips:
        rel = abs(v) / (value_scale[fam] or 1.0)
        if g.kind == "velocity":
            out.append(
                (
                    rel,
                    "grazing-sliding",
                    f"a slip arc of block {g.block} comes within {abs(v):.3g} of the "
                    f"belt speed without reaching it ({g.name} has an interior extremum at t = {t:.10g})",
                    key,
                )
            )
        else:
            out.append(
                (
                    rel,
                    "multi-sliding",
                    f"a sticking arc of block {g.block} comes within {abs(v):.3g} of its "
                    f"static limit without reaching it ({g.name} has an interior extremum at t = {t:.10g})",
                    key,
                )
            )
    for index, e in enumerate(orbit.events):
        rate = _event_rate(problem, e)
        rel = rate / (rate_scale.get(_family(e.guard)) or 1.0)
        if e.guard.kind == "velocity":
            out.append(
                (
                    rel,
                    "grazing-sliding",
                    f"block {e.block}'s velocity reaches the belt speed with slope "
                    f"{rate:.3g} at a {e.kind} event (t = {e.t:.10g})",
                    ("rate", index),
                )
            )
        else:
            out.append(
                (
                    rel,
                    "multi-sliding",
                    f"block {e.block}'s sticking phase reaches its static limit with "
                    f"slope {rate:.3g} at a slip event (t = {e.t:.10g})",
                    ("rate", index),
                )
            )
        if e.kind in ("stick", "reverse"):
            fr = problem.coefficients.fr[e.block - 1]
            margin = _margin(problem, e)
            out.append(
                (
                    abs(margin) / fr,
                    "crossing-sliding",
                    f"block {e.block} reaches the belt speed with fr - |R| = {margin:.3g} at a {e.kind} "
                    f"event (t = {e.t:.10g}): the locus of sticking phase starts on the boundary of its "
                    "sliding region",
                    ("margin", index),
                )
            )
    return sorted(out, key=lambda c: c[0])


def _closest_events(orbit: PeriodicOrbit) -> tuple[float, str]:
    """The two consecutive events (cyclically) closest in time, as ``(gap, text)``."""
    ev = orbit.events
    best = (math.inf, "")
    for k, e in enumerate(ev):
        nxt = ev[(k + 1) % len(ev)]
        gap = (nxt.t - e.t) % orbit.period if len(ev) > 1 else orbit.period
        if gap < best[0]:
            best = (gap, f"{e.kind}{e.block} and {nxt.kind}{nxt.block} are {gap:.3g} apart (t = {e.t:.10g})")
    return best


def _stick_counts(orbit: PeriodicOrbit | None, n_blocks: int) -> list[int]:
    if orbit is None:
        return [0] * n_blocks
    c = Counter(orbit.pattern)
    return [c.get(f"stick{b}", 0) for b in range(1, n_blocks + 1)]


def classify(flow: HybridFlow, near: PeriodicOrbit, far: PeriodicOrbit | None) -> tuple[str, str, str]:
    """``(kind, category, detail)`` of the change from orbit ``near`` to orbit ``far``.

    ``far`` is ``None`` where no orbit of ``near``'s kind exists (the end of a branch).
    With both given, ``near`` is the orbit at the smaller parameter value, so
    "gains" and "loses" read in the direction of a growing parameter.
    """
    friction = is_friction(near.problem)
    nb = cast("FrictionOscillator", near.problem).n_blocks if friction else 0
    if far is not None and far.pattern == near.pattern:
        lost = near.multipliers if near.unstable_count < far.unstable_count else far.multipliers
        other = far.multipliers if lost is near.multipliers else near.multipliers
        # the multiplier that crosses: the one closest to the unit circle on the stable side's orbit
        z = lost[np.argmin(np.abs(np.abs(lost) - 1.0))] if lost.size else complex(np.nan)
        if abs(z.imag) > 1e-6:
            kind = "torus"
        elif z.real < 0:
            kind = "period-doubling"
        else:
            kind = "fold"
        detail = (
            f"multiplier {format_multipliers(np.array([z]))} crosses the unit circle "
            f"(unstable multipliers {near.unstable_count} -> {far.unstable_count}; "
            f"{format_multipliers(lost)} -> {format_multipliers(other)})"
        )
        return kind, "fixed-point", detail
    if far is not None and Counter(far.pattern) == Counter(near.pattern):
        gaps = [_closest_events(o) for o in (near, far)]
        gap, text = min(gaps, key=lambda g: g[0])
        return (
            "event-order",
            CATEGORY["event-order"],
            f"{text}; the same events in another order, the orbit passes through continuously",
        )
    candidates = []
    for orbit in (near, far):
        if orbit is not None:
            flow.rebind(orbit.problem)
            candidates += survey(flow, orbit)
    if not candidates:
        return "unknown", "border-collision", "the event pattern changes; no degenerate event was found"
    rel, kind, text, _ = min(candidates, key=lambda c: c[0])
    if far is None and near.multipliers.size:
        z = near.multipliers[np.argmin(np.abs(near.multipliers - 1.0))]
        if abs(z - 1.0) < 1e-2 and (rel > UNCLEAR or abs(z - 1.0) < rel):
            return (
                "fold",
                CATEGORY["fold"],
                (
                    f"multiplier {format_multipliers(np.array([z]))} approaches +1 "
                    "where the branch ends (a turning point of the branch)"
                ),
            )
    if rel > UNCLEAR:
        return (
            "unclassified",
            CATEGORY["unclassified"],
            (
                f"no event or arc of the orbits at the bracket is degenerate (the closest: {text}, relative size "
                f"{rel:.2g}); the value is where Newton stops converging, not a located tangency"
            ),
        )
    if not friction:  # the text carries its relative size already
        category = degenerate.CATEGORY.get(kind, "unknown")
        if far is None:
            return kind, category, f"{text}; the branch ends (no orbit of this kind beyond)"
        return kind, category, f"{text}; the event pattern changes"
    if far is None:
        return kind, CATEGORY[kind], f"{text} [relative size {rel:.2g}]; the branch ends (no orbit of this kind beyond)"
    a, b = _stick_counts(near, nb), _stick_counts(far, nb)
    changes = [f"block {blk + 1} sticks {a[blk]} -> {b[blk]} times per period" for blk in range(nb) if a[blk] != b[blk]]
    what = "; " + ", ".join(changes) if changes else ""
    return kind, CATEGORY[kind], f"{text} [relative size {rel:.2g}]{what}"
