"""An independent event-driven solution of Glocker's woodpecker toy in 40 digits (mpmath), for the tests.

Written from the equations of motion in SI (docs/problems.md, the ``woodpecker``
sheet), not from nsbench's law: each contact mode is the full constrained system
with Lagrange multipliers,

    free:            M a = h(q)
    sliding, sign s: [[M, -(w_N - s mu w_T)], [w_N^T, 0]] [a; lambda_N] = [h; 0]
    jammed:          [[M, -w_N, -w_T], [w_N^T, 0, 0], [w_T^T, 0, 0]] [a; lambda_N; lambda_T] = [h; 0; 0]

(nsbench solves reduced systems with the constrained accelerations removed),
and the guards are the physical ones: the gaps ``g_N``, the normal force
``lambda_N``, the slip velocity ``gamma_T`` and the friction cone ``mu lambda_N
-+ lambda_T`` (nsbench writes gaps as angle margins and forces as accelerations).
Every mode is affine in ``z = (q, q', 1)``, so its flow is ``expm(A s) z``,
evaluated in mpmath; the guards are scanned on a grid of ``h`` and each sign change
is refined by bisection and the secant method to the working precision. An impact
enumerates every status of the contacts involved (closed and stuck, closed and
sliding either way, open), requires exactly one consistent combination (so the
reference also checks that the impact law has a unique solution), and then the
sleeve's contact mode is chosen by enumeration too (free, stuck, sliding either
way), again requiring a unique consistent one. Time and state stay in 40 digits
from the start to the end.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field

import mpmath

#: The mode names of nsbench's woodpecker (the event logs are compared by them).
CONTACT = {1: "tilt-", 2: "tilt+"}
STATUS = {1: "slip+", -1: "slip-", 0: "stick"}


@dataclass
class Event:
    t: mpmath.mpf
    kind: str
    contact: int  # 0 beak, 1 and 2 the sleeve's diagonals
    mode: str
    z: list = field(repr=False)


class Woodpecker:
    """Glocker's model in SI, in ``ctx``'s precision (parameters: the SI values of ``nsbench``'s factory)."""

    def __init__(self, v: dict[str, float], dps: int = 40) -> None:
        ctx = self.ctx = mpmath.MPContext()
        ctx.dps = dps
        f = {k: ctx.mpf(x) for k, x in v.items()}  # the doubles, exactly
        mM, JM, mS, JS, c, g = (f[k] for k in ("mM", "JM", "mS", "JS", "c_phi", "g"))
        r0, rM, hM, lM, lG, hS, lS = (f[k] for k in ("r0", "rM", "hM", "lM", "lG", "hS", "lS"))
        self.mu = f["mu"]
        self.e = [f["e_beak"], f["e_sleeve"], f["e_sleeve"]]
        self.M = ctx.matrix(
            [
                [mS + mM, mS * lM, mS * lG],
                [mS * lM, JM + mS * lM**2, mS * lM * lG],
                [mS * lG, mS * lM * lG, JS + mS * lG**2],
            ]
        )
        self.K = ctx.matrix([[0, 0, 0], [0, -c, c], [0, c, -c]])
        self.h0 = ctx.matrix([-(mS + mM) * g, -mS * lM * g, -mS * lG * g])
        self.wn = [ctx.matrix([0, 0, -hS]), ctx.matrix([0, hM, 0]), ctx.matrix([0, -hM, 0])]
        self.wt = [ctx.matrix([1, lM, lG - lS]), ctx.matrix([1, rM, 0]), ctx.matrix([1, rM, 0])]
        self.g0 = [lM + lG - lS - r0, rM - r0, rM - r0]
        self._modes: dict = {}

    # -------------------------------------------------------------- the modes
    def _dot(self, a, b) -> mpmath.mpf:
        return self.ctx.fsum(a[i] * b[i] for i in range(3))

    def maps(self, mode: tuple[int, int]):
        """``(A, lam)``: ``z' = A z`` (7 x 7) and the multipliers as rows on ``z`` (``{'N': row, 'T': row}``).

        ``mode = (contact, status)``: ``(0, 0)`` free, ``(j, s)`` sliding with sign ``s``, ``(j, 0)`` jammed.
        """
        if mode in self._modes:
            return self._modes[mode]
        ctx = self.ctx
        j, s = mode
        cols = []  # the generalised forces as columns of [q (3), u (3), 1]
        if j == 0:
            sys, extra = self.M, 0
        else:
            wn, wt = self.wn[j], self.wt[j]
            sliding = s != 0
            extra = 1 if sliding else 2
            sys = ctx.zeros(3 + extra, 3 + extra)
            for r in range(3):
                for k in range(3):
                    sys[r, k] = self.M[r, k]
                if sliding:
                    sys[r, 3] = -(wn[r] - s * self.mu * wt[r])
                else:
                    sys[r, 3], sys[r, 4] = -wn[r], -wt[r]
            for k in range(3):
                sys[3, k] = wn[k]
                if not sliding:
                    sys[4, k] = wt[k]
        for col in range(7):
            rhs = ctx.zeros(3 + extra, 1)
            for r in range(3):
                rhs[r] = self.K[r, col] if col < 3 else (self.h0[r] if col == 6 else 0)
            cols.append(ctx.lu_solve(sys, rhs))
        A = ctx.zeros(7, 7)
        for i in range(3):
            A[i, 3 + i] = 1
            for col in range(7):
                A[3 + i, col] = cols[col][i]
        lam = {}
        if j:
            lam["N"] = [cols[col][3] for col in range(7)]
            lam["T"] = [cols[col][4] for col in range(7)] if s == 0 else [-s * self.mu * x for x in lam["N"]]
        self._modes[mode] = (A, lam)
        return self._modes[mode]

    def guards(self, mode: tuple[int, int]) -> list[tuple[str, int, list, int]]:
        """``[(kind, contact, row on z, expected sign)]`` of a mode."""
        j, s = mode
        gap = [(c, [*self.wn[c], 0, 0, 0, self.g0[c]]) for c in range(3)]
        out = [("gap", 0, gap[0][1], 1)]
        if j == 0:
            return out + [("gap", c, gap[c][1], 1) for c in (1, 2)]
        _, lam = self.maps(mode)
        out.append(("force", j, lam["N"], 1))
        if s != 0:
            out.append(("slip", j, [0, 0, 0, *self.wt[j], 0], s))
        else:
            out.append(("limit+", j, [self.mu * a - b for a, b in zip(lam["N"], lam["T"])], 1))
            out.append(("limit-", j, [self.mu * a + b for a, b in zip(lam["N"], lam["T"])], 1))
        return out

    # -------------------------------------------------------------- the transitions
    def impact(self, z: list, contacts: list[int]) -> tuple[list, dict[int, str]]:
        """The velocities after an impact of ``contacts`` and each contact's status; exactly one consistent."""
        ctx = self.ctx
        u = ctx.matrix(z[3:6])
        minv = ctx.inverse(self.M)
        pre = {c: (self._dot(self.wn[c], u), self._dot(self.wt[c], u)) for c in contacts}
        tol = ctx.mpf(10) ** (-(ctx.dps - 8))
        found = []
        for combo in itertools.product(("stick", "slip+", "slip-", "open"), repeat=len(contacts)):
            n = 2 * len(contacts)
            a, b = ctx.zeros(n, n), ctx.zeros(n, 1)
            for k, (c, st) in enumerate(zip(contacts, combo)):
                if st == "open":
                    a[2 * k, 2 * k] = a[2 * k + 1, 2 * k + 1] = 1
                    continue
                for q, cq in enumerate(contacts):  # post-impact velocities xi+ = xi- + W^T M^-1 W Lambda
                    a[2 * k, 2 * q] = self._dot(self.wn[c], minv * self.wn[cq])
                    a[2 * k, 2 * q + 1] = self._dot(self.wn[c], minv * self.wt[cq])
                b[2 * k] = -(1 + self.e[c]) * pre[c][0]
                if st == "stick":
                    for q, cq in enumerate(contacts):
                        a[2 * k + 1, 2 * q] = self._dot(self.wt[c], minv * self.wn[cq])
                        a[2 * k + 1, 2 * q + 1] = self._dot(self.wt[c], minv * self.wt[cq])
                    b[2 * k + 1] = -pre[c][1]
                else:
                    a[2 * k + 1, 2 * k + 1], a[2 * k + 1, 2 * k] = 1, (self.mu if st == "slip+" else -self.mu)
            try:
                lam = ctx.lu_solve(a, b)
            except ZeroDivisionError:
                continue
            du = ctx.zeros(3, 1)
            for k, c in enumerate(contacts):
                du += minv * (self.wn[c] * lam[2 * k] + self.wt[c] * lam[2 * k + 1])
            post = u + du
            ok = True
            for k, (c, st) in enumerate(zip(contacts, combo)):
                gn, gt = self._dot(self.wn[c], post), self._dot(self.wt[c], post)
                ln, lt = lam[2 * k], lam[2 * k + 1]
                if st == "open":
                    ok &= gn + self.e[c] * pre[c][0] >= -tol
                else:
                    ok &= ln >= -tol
                    ok &= (
                        (abs(lt) <= self.mu * ln + tol)
                        if st == "stick"
                        else ((gt >= -tol) if st == "slip+" else (gt <= tol))
                    )
            if ok:
                found.append((combo, post))
        assert len(found) == 1, (
            f"the impact of {contacts} has {len(found)} consistent solutions: {[c for c, _ in found]}"
        )
        combo, post = found[0]
        return [*z[:3], *post, z[6]], dict(zip(contacts, combo))

    def contact_mode(self, z: list, j: int) -> tuple[int, int]:
        """The consistent mode of the sleeve with contact ``j`` closed (gap and normal velocity zero)."""
        ctx = self.ctx
        tol = ctx.mpf(10) ** (-(ctx.dps - 8))
        gt = self._dot(self.wt[j], z[3:6])

        def value(row):
            return ctx.fsum(r * x for r, x in zip(row, z))

        def acceleration(A):
            return [ctx.fsum(A[3 + i, col] * z[col] for col in range(7)) for i in range(3)]

        A_free, _ = self.maps((0, 0))
        candidates = []
        if self._dot(self.wn[j], acceleration(A_free)) >= 0:  # the free motion opens it
            candidates.append((0, 0))
        for s in (1, -1):
            A, lam = self.maps((j, s))
            tangential = self._dot(self.wt[j], acceleration(A))
            if value(lam["N"]) > 0 and (s * gt > tol or (abs(gt) <= tol and s * tangential > 0)):
                candidates.append((j, s))
        if abs(gt) <= tol:
            _, lam = self.maps((j, 0))
            ln, lt = value(lam["N"]), value(lam["T"])
            if ln > 0 and abs(lt) < self.mu * ln:
                candidates.append((j, 0))
        assert len(candidates) == 1, f"contact {j}: {len(candidates)} consistent modes {candidates}"
        return candidates[0]


def mode_name(mode: tuple[int, int]) -> str:
    j, s = mode
    return "free" if j == 0 else f"{CONTACT[j]}/{STATUS[s]}"


def _series(ctx, A, z, length, dps: int) -> list[list]:
    """Taylor coefficients ``A^k z / k!`` of the flow from ``z``, to below ``10^-(dps+5)`` of ``z`` over ``length``."""
    terms, term = [list(z)], ctx.matrix(z)
    scale = max(abs(x) for x in z)
    k = 0
    while True:
        k += 1
        term = A * term / k
        terms.append(list(term))
        if max(abs(x) for x in term) * length**k < ctx.mpf(10) ** (-(dps + 5)) * scale:
            return terms


def _guard_poly(ctx, series, guard) -> list:
    """The expected-sign guard as polynomial coefficients in the time from the series' start."""
    _, _, row, sign = guard
    return [sign * ctx.fsum(r * x for r, x in zip(row, term)) for term in series]


def _horner(poly, s):
    out = poly[-1]
    for c in reversed(poly[:-1]):
        out = out * s + c
    return out


def _first_zero(ctx, poly, length, dps: int):
    """A zero of ``poly`` in ``(0, length]`` (negative at ``length``): bisection to the working precision from the
    last point of a fine grid where it is positive (robust at double zeros), the leftmost bracket first."""
    lo = ctx.zero
    for j in range(1, 65):  # the leftmost sign change on a grid of 64 (a guard that dips and returns inside)
        if _horner(poly, length * j / 64) < 0:
            hi = length * j / 64
            break
        lo = length * j / 64
    for _ in range(4 * dps):
        mid = (lo + hi) / 2
        if _horner(poly, mid) < 0:
            hi = mid
        else:
            lo = mid
        if hi - lo <= ctx.mpf(10) ** (-(dps - 2)) * length:
            break
    return hi


def _evaluate(ctx, series, s) -> list:
    return [ctx.fsum(term[i] * s**k for k, term in enumerate(series)) for i in range(len(series[0]))]


def solve(v: dict[str, float], z0: list[float], t_end: float, step: float, dps: int = 40) -> list[Event]:
    """The events of the woodpecker from ``z0 = (q, q')`` (SI, sleeve on contact 1 if ``phiM`` is at its limit)
    over ``[0, t_end]`` seconds, scanned on a grid of ``step`` seconds."""
    w = Woodpecker(v, dps)
    ctx = w.ctx
    z = [ctx.mpf(x) for x in z0] + [ctx.one]
    theta = w.g0[1] / w.wn[1][1]
    if abs(z[1] + theta) <= ctx.mpf(10) ** -12 and z[4] == 0:  # the start is on the lower tilt: in contact
        z[1] = -theta
        mode = w.contact_mode(z, 1)
    else:
        mode = (0, 0)
    t, t_end, h = ctx.zero, ctx.mpf(t_end), ctx.mpf(step)
    events: list[Event] = []
    fresh: set[tuple[str, int]] = set()
    tiny = ctx.mpf(10) ** (-(dps - 10))

    def values(guards, z):
        return [sign * ctx.fsum(r * x for r, x in zip(row, z)) for _, _, row, sign in guards]

    while t < t_end:
        A, _ = w.maps(mode)
        phi = ctx.expm(A * h)
        guards = w.guards(mode)
        start_fresh = {k for k, (kind, c, _, _) in enumerate(guards) if (kind, c) in fresh}
        s, zs, hit = ctx.zero, z, None
        while hit is None and t + s < t_end:
            step_len = min(h, t_end - t - s)
            ze = list(phi * ctx.matrix(zs)) if step_len == h else list(ctx.expm(A * step_len) * ctx.matrix(zs))
            ve = values(guards, ze)
            series = None
            for k, val in enumerate(ve):
                if k in start_fresh and s == 0 and val > -tiny:
                    continue  # a guard that starts on its surface and leaves it on its own side
                if val < 0:
                    series = series or _series(ctx, A, zs, step_len, dps)
                    root = _first_zero(ctx, _guard_poly(ctx, series, guards[k]), step_len, dps)
                    if hit is None or s + root < hit[0]:
                        hit = (s + root, k, series, root)
            if hit is None:
                s, zs = s + step_len, ze
        if hit is None:
            break
        s_hit, k, series, root = hit
        z = _evaluate(ctx, series, root)
        t = t + s_hit
        kind, c, _, _ = guards[k]
        j = mode[0]
        fresh = set()
        if kind == "gap":
            contacts = [c] + ([j] if j and c == 0 else [])
            if c == 0:
                z[2] = w.g0[0] / -w.wn[0][2]
            else:
                z[1] = -theta if c == 1 else theta
            z, statuses = w.impact(z, contacts)
            fresh.add(("gap", c))
            sleeve = j if c == 0 else c
            if sleeve and statuses[sleeve] != "open" and not (w.e[sleeve] > 0 and c == sleeve):
                z[4] = ctx.zero
                if statuses[sleeve] == "stick":
                    z[3] = ctx.zero
                mode = w.contact_mode(z, sleeve)
            elif sleeve:
                mode = (0, 0)
            if mode[0] == 0 and sleeve:
                fresh.add(("gap", sleeve))
            event = "peck" if c == 0 else "impact"
        elif kind == "force":
            mode, event = (0, 0), "release"
            fresh.add(("gap", c))
        elif kind == "slip":
            z[3] = ctx.zero
            new = w.contact_mode(z, c)
            event = "release" if new[0] == 0 else "stick" if new[1] == 0 else "reverse"
            mode = new
            fresh.update({("limit+", c), ("limit-", c), ("slip", c), ("force", c)})
        else:
            mode, event = (c, -1 if kind == "limit+" else 1), "slip"
            fresh.update({("slip", c), ("force", c)})
        events.append(Event(t, event, c, mode_name(mode), z))
    return events
