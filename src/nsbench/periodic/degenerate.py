"""Degenerate events and arcs of the piecewise-linear problems (impact oscillator, relay), for naming
and locating their bifurcations.

The friction oscillators' quantities live in :mod:`nsbench.periodic.bifurcations`; the other
piecewise-linear families are measured here from their linear forms, without the integrator
(an arc is the frozen mode's closed form, ``expm`` of the augmented matrix), so that an orbit
that nearly grazes a surface can be measured without the integrator deciding about that graze.
Each quantity crosses zero at the bifurcation and is smooth on the near side:

- ``("rate", k)``: the rate of the guard that fired at event ``k``, just before it (an impact's
  speed: zero at a grazing impact). On the impact oscillator's impacting orbit it is linear in
  the parameter near the grazing (the impact moves the orbit by an amount proportional to its
  speed: the computed speeds at 5e-6, 1e-9 and 1e-11 from the grazing are in the same ratio to the
  distance within a few per cent), so it is used as it is, not squared as for the friction
  problems' sliding grazings;
- ``("out", k, kind)``: just after event ``k``, the guard ``kind`` of the new mode: its rate
  along the new field if the event left it on its surface (the relay's crossing point reaching
  the boundary of the sliding region), else its value (a sliding entry's margin ``1 - |u_eq|``);
- ``("dip", arc, kind, block)``: the closest interior approach of a guard to zero along an arc
  (a non-impacting orbit's ``sigma - max x``).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import scipy.linalg
import scipy.optimize

#: ``(family, guard kind) -> bifurcation kind`` of a degenerate quantity of that guard.
KIND = {
    ("impact", "gap"): "grazing",
    ("impact", "press"): "release-grazing",
    ("relay", "switch"): "crossing-sliding",
    ("relay", "limit+"): "crossing-sliding",
    ("relay", "limit-"): "crossing-sliding",
}
#: A dip of the relay's switching function inside an arc is a grazing of the surface, not a crossing.
DIP_KIND = {("relay", "switch"): "grazing-sliding", ("relay", "limit+"): "sliding-limit"}
DIP_KIND[("relay", "limit-")] = "sliding-limit"
#: Category of each kind for these families.
CATEGORY = {
    "grazing": "grazing",
    "release-grazing": "grazing",
    "crossing-sliding": "sliding",
    "grazing-sliding": "sliding",
    "sliding-limit": "sliding",
}


def _augmented(problem, mode) -> np.ndarray:
    """``M`` with ``z' = M z`` for ``z = [y, 1, cos w t, sin w t]`` in the frozen ``mode``."""
    a, b0, bc, bs = problem.linear_form(mode)
    n, w = problem.n_states, problem.forcing_frequency
    m = np.zeros((n + 3, n + 3))
    m[:n, :n], m[:n, n], m[:n, n + 1], m[:n, n + 2] = a, b0, bc, bs
    m[n + 1, n + 2], m[n + 2, n + 1] = -w, w
    return m


def frozen_states(problem, mode, t0: float, y0, s: np.ndarray) -> np.ndarray:
    """``[y, 1, cos w t, sin w t]`` at ``t0 + s`` of the flow frozen in ``mode`` (columns), closed form."""
    m = _augmented(problem, mode)
    w = problem.forcing_frequency
    z0 = np.concatenate([np.asarray(y0, dtype=float), [1.0, np.cos(w * t0), np.sin(w * t0)]])
    return np.column_stack([scipy.linalg.expm(m * float(si)) @ z0 for si in np.atleast_1d(s)])


def _guard_values(problem, mode, g, t0, y0, s) -> np.ndarray:
    q = np.asarray(problem.guard_row(mode, g.code, g.block - 1), dtype=float)
    return g.expected_sign * (q @ frozen_states(problem, mode, t0, y0, s))


def _arcs(orbit):
    t, y, mode = orbit.t0, orbit.y0, orbit.mode0
    for e in orbit.events:
        yield t, y, mode, e.t - t
        t, y, mode = e.t, e.y, e.mode_after
    yield t, y, mode, orbit.t0 + orbit.period - t


def _before(problem, e) -> np.ndarray:
    found = problem.event_linearisation(e.kind, e.t, e.y)
    return np.asarray(e.y if found is None else found[0], dtype=float)


def _rate(problem, g, mode, t, y) -> float:
    return float(g.rate(t, y, problem.rhs(mode, t, y)))


def _out(problem, e, kind):
    """``(value, on_surface)`` of the new mode's guard ``kind`` just after event ``e``."""
    g = next(g for g in problem.guards(e.mode_after) if g.kind == kind)
    value = g.expected_sign * float(g.value(e.t, e.y))
    scale = 1.0 + float(np.max(np.abs(e.y)))
    if abs(value) <= 1e-9 * scale:
        return g.expected_sign * _rate(problem, g, e.mode_after, e.t, e.y), True
    return value, False


def _dip(problem, orbit, arc: int, kind: str, block: int, samples: int = 65):
    """``(low, s)``: smallest ``expected_sign * g`` inside arc ``arc`` (``None`` if at an end)."""
    t0, y0, mode, dt = list(_arcs(orbit))[arc]
    g = next(g for g in problem.guards(mode) if g.kind == kind and g.block == block)
    s = dt * np.linspace(0.0, 1.0, samples)
    vals = _guard_values(problem, mode, g, t0, y0, s)
    k = int(np.argmin(vals))
    if k == 0 or k == samples - 1:
        return None
    res = scipy.optimize.minimize_scalar(
        lambda x: float(_guard_values(problem, mode, g, t0, y0, [x])[0]),
        bounds=(s[k - 1], s[k + 1]),
        method="bounded",
        options={"xatol": 1e-12 * max(1.0, dt)},
    )
    return float(res.fun), t0 + float(res.x)


def measure(problem, orbit, key: tuple) -> float:
    """The quantity ``key`` (module docstring) on ``orbit``: smooth, zero at the bifurcation."""
    if key[0] == "rate":
        e = orbit.events[key[1]]
        return _rate(problem, e.guard, e.mode_before, e.t, _before(problem, e))
    if key[0] == "out":
        return _out(problem, orbit.events[key[1]], key[2])[0]
    found = _dip(problem, orbit, *key[1:])
    if found is None:  # the minimum moved to an end of the arc: the tangency is an event now
        return 0.0
    return found[0]


def survey(problem, orbit, samples: int = 65) -> list[tuple[float, str, str, tuple]]:
    """Every near-degenerate quantity of ``orbit`` as ``(relative size, kind, text, key)``, smallest first.

    Sizes are relative to the largest ``|value|`` (a dip, a sliding entry's margin) or ``|rate|``
    (an event's rate, a departure's slope) of the same guard kind sampled along the whole orbit:
    an impact speed against the largest speed, ``sigma - max x`` against the largest gap.
    """
    fam = problem.family
    scales: dict[tuple[str, str], float] = {}  # (guard kind, "value" or "rate") -> largest size
    # (size, guard kind, "value" or "rate", bifurcation kind, text, key)
    found: list[tuple[float, str, str, str, str, tuple[Any, ...]]] = []
    for arc, (t0, y0, mode, dt) in enumerate(_arcs(orbit)):
        if dt <= 0:
            continue
        s = dt * np.linspace(0.0, 1.0, samples)
        z = frozen_states(problem, mode, t0, y0, s)
        ys = z[: problem.n_states]
        f = problem.rhs(mode, t0 + s, ys)
        for g in problem.guards(mode):
            q = np.asarray(problem.guard_row(mode, g.code, g.block - 1), dtype=float)
            for what, size in (("value", np.abs(q @ z)), ("rate", np.abs(g.rate(t0 + s, ys, f)))):
                scales[g.kind, what] = max(scales.get((g.kind, what), 0.0), float(np.max(size)))
            dip = _dip(problem, orbit, arc, g.kind, g.block, samples)
            if dip is not None:
                low, t = dip
                kind = DIP_KIND.get((fam, g.kind), KIND.get((fam, g.kind), "unknown"))
                text = (
                    f"the {g.name} guard comes within {abs(low):.3g} of zero inside an arc "
                    f"(interior extremum at t = {t:.10g}) without reaching it"
                )
                found.append((low, g.kind, "value", kind, text, ("dip", arc, g.kind, g.block)))
    for index, e in enumerate(orbit.events):
        rate = abs(_rate(problem, e.guard, e.mode_before, e.t, _before(problem, e)))
        what = "impact speed" if e.kind == "impact" else "slope"
        text = f"{e.guard.name} reaches zero with {what} {rate:.3g} at a {e.kind} event (t = {e.t:.10g})"
        found.append((rate, e.guard.kind, "rate", KIND.get((fam, e.guard.kind), "unknown"), text, ("rate", index)))
        for g in problem.guards(e.mode_after):
            if e.mode_after == e.mode_before and g.kind == e.guard.kind:
                continue  # the same guard again (an impact): its speed is measured above
            value, on = _out(problem, e, g.kind)
            text = (
                f"after the {e.kind} event at t = {e.t:.10g} the {g.name} guard leaves its surface with slope {value:.3g}"
                if on
                else f"the {e.kind} event at t = {e.t:.10g} starts with the {g.name} guard at {value:.3g}"
            )
            kind = KIND.get((fam, g.kind), "unknown")
            found.append((value, g.kind, "rate" if on else "value", kind, text, ("out", index, g.kind)))
    ranked = []
    for size, gkind, what, kind, text, key in found:
        rel = abs(size) / (scales.get((gkind, what)) or 1.0)
        ranked.append((rel, kind, f"{text} [relative size {rel:.2g}]", key))
    return sorted(ranked, key=lambda c: c[0])
