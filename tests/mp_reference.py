"""A 32-digit closed-form reference for the linear 2-DOF cases, independent of nsbench's integrators.

Each mode of a linear problem is ``z' = M z`` on the augmented state
``z = [y, 1, cos(w t), sin(w t)]``, so its flow is ``expm(M s) z0``; mpmath
evaluates it at 32 digits and refines each event time with the secant method,
carrying time and state in 32 digits from event to event (no rounding to
double anywhere). A double-precision event log serves only as a guide to the
next event's kind, block and approximate time; every arc is checked for an
earlier crossing of any guard of its mode on a grid of 64 points, and every
event's kind is recomputed from the transition rule.

``tests/data/two_dof_closed_form.csv`` holds the result for cases 1 and 2 over
``[0, 300]``; ``test_reference.py`` regenerates it in a slow test.
"""

from __future__ import annotations

from pathlib import Path

import mpmath as mp
import numpy as np
import pandas as pd

import nsbench
from nsbench.problems.modes import STICK

DATA = Path(__file__).parent / "data" / "two_dof_closed_form.csv"


def closed_form_events(case: int, t_end: float = 300.0, dps: int = 32) -> pd.DataFrame:
    """Events ``(t, kind, block)`` of the standard 2-DOF run of a linear case, ``t`` as strings."""
    mp.mp.dps = dps
    p = nsbench.get_problem("two-dof", case=case)
    c = p.coefficients
    guide = nsbench.simulate(p, "scipy-dop853", t_end, options={"rtol": 1e-12, "atol": 1e-14}).events
    f = lambda x: mp.mpf(float(x))  # noqa: E731 - the problem's coefficients are doubles
    v0, F, w = f(c.v0), f(c.F), f(c.w)
    mats: dict = {}

    def matrix(mode):
        if mode not in mats:
            a, b0, bc, bs = p.linear_form(mode)
            m = mp.zeros(7, 7)
            for i in range(4):
                for j in range(4):
                    m[i, j] = f(a[i, j])
                m[i, 4], m[i, 5], m[i, 6] = f(b0[i]), f(bc[i]), f(bs[i])
            m[5, 6], m[6, 5] = -w, w
            mats[mode] = m
        return mats[mode]

    def restoring(block, t, y):
        x1, v1, x2, v2 = y
        if block == 1:
            return f(c.c[0]) * v1 + f(c.k[0]) * x1 + f(c.k[1]) * (x1 - x2)
        return f(c.c[1]) * v2 + f(c.k[1]) * (x2 - x1) - F * mp.cos(w * t)

    def guards(mode, t, y):
        out = []
        for i, phase in enumerate(mode, start=1):
            if phase == STICK:
                r = restoring(i, t, y)
                out += [f(c.fr[i - 1]) - r, r + f(c.fr[i - 1])]
            else:
                out.append(phase * (y[2 * i - 1] - v0))
        return out

    t, y, mode = mp.mpf(0), [mp.mpf(0)] * 4, (-1, -1)
    rows = []
    for ev in guide.itertuples(index=False):
        z0 = mp.matrix([*y, 1, mp.cos(w * t), mp.sin(w * t)])
        m, b = matrix(mode), ev.block

        def state(s, m=m, z0=z0):
            z = mp.expm(m * s) * z0
            return [z[k] for k in range(4)]

        if mode[b - 1] == STICK:
            limit = f(c.fr[b - 1])
            after = [f(getattr(ev, k)) for k in ("x1", "v1", "x2", "v2")]
            sign = 1 if ev.kind == "slip" and restoring(b, f(ev.t), after) > 0 else -1
            g = lambda s, sign=sign: restoring(b, t + s, state(s)) - sign * limit  # noqa: E731
        else:
            g = lambda s: state(s)[2 * b - 1] - v0  # noqa: E731
        guess = f(ev.t) - t
        s = mp.findroot(g, (guess * (1 - mp.mpf("1e-9")), guess * (1 + mp.mpf("1e-9"))), solver="secant")
        for u in np.linspace(0.0, 1.0, 65)[1:-1]:  # no guard of the mode crossed earlier
            assert min(guards(mode, t + s * u, state(s * u))) > 0, (case, float(t), mode)
        y, t = state(s), t + s
        y[2 * b - 1] = v0
        r = restoring(b, t, y)
        new = list(mode)
        if mode[b - 1] == STICK:
            new[b - 1], kind = (-1 if r > 0 else 1), "slip"
        elif abs(r) <= f(c.fr[b - 1]):
            new[b - 1], kind = STICK, "stick"
        else:
            new[b - 1], kind = (-1 if r > 0 else 1), "reverse"
        assert kind == ev.kind, (case, float(t), kind, ev.kind)
        mode = tuple(new)
        rows.append((case, mp.nstr(t, dps - 2, strip_zeros=False), kind, b))
    return pd.DataFrame(rows, columns=["case", "t", "kind", "block"])


def stored_events(case: int) -> pd.DataFrame:
    """The stored reference of ``case`` with ``t`` as floats (rounded once) and as mpf strings."""
    table = pd.read_csv(DATA, dtype={"t": str})
    table = table[table["case"] == case].reset_index(drop=True)
    table["t_float"] = [float(mp.mpf(x)) for x in table["t"]]
    return table


def max_error(events: pd.DataFrame, reference: pd.DataFrame) -> float:
    """Largest event-time error against the stored 30-digit times (same sequence required)."""
    assert list(events["kind"]) == list(reference["kind"])
    assert list(events["block"]) == list(reference["block"])
    mp.mp.dps = 32
    return max(abs(float(mp.mpf(float(t)) - mp.mpf(r))) for t, r in zip(events["t"], reference["t"]))


if __name__ == "__main__":  # regenerate the data file
    DATA.parent.mkdir(exist_ok=True)
    pd.concat([closed_form_events(1), closed_form_events(2)]).to_csv(DATA, index=False)
    print(f"wrote {DATA}")
