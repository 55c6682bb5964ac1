"""The relay feedback system solved in mpmath, written from its equations alone (no nsbench code).

``x' = A x + B u``, ``u = -sign(C x)`` with Filippov sliding on ``C x = 0`` (Utkin's
equivalent control ``u_eq = -C A x / C B`` while ``|u_eq| < 1``), the plant of di
Bernardo, Johansson and Vasca (docs/problems.md). Every mode is linear with constant
forcing, so its flow is ``expm(M s)`` of the augmented matrix ``M = [[A_mode, b_mode],
[0, 0]]`` on ``z = [x, 1]``. One step ``expm(M h)`` per mode is computed by mpmath; the
state is marched on a grid of step ``h`` (shorter than any phase of the orbits checked:
the shortest slide of ``piiroinen-kuznetsov``'s orbit lasts 2.2e-3) and a guard's first
sign change is refined by the Illinois method, each value from the last grid state by the
Taylor series of the flow to the working precision. The transition rule is the
textbook's: reaching ``C x = 0`` the trajectory crosses if the far side's field carries
it on, else slides; sliding, it exits to the side whose field turns away when ``|u_eq|``
reaches 1.
"""

from __future__ import annotations

import mpmath as mp


def _plant(zeta, omega, lam, sigma, rho):
    a = [
        [-(2 * zeta * omega + lam), mp.mpf(1), mp.mpf(0)],
        [-(2 * zeta * omega * lam + omega**2), mp.mpf(0), mp.mpf(1)],
        [-lam * omega**2, mp.mpf(0), mp.mpf(0)],
    ]
    return a, [mp.mpf(1), -2 * sigma * rho, rho**2]


def _matvec(m, v):
    return [mp.fsum(m[i][j] * v[j] for j in range(len(v))) for i in range(len(m))]


def _flow_from(m, z, d, tol):
    """``expm(M d) z`` by its Taylor series (``|M| d`` is below 1 here)."""
    out, term, k = list(z), list(z), 0
    while True:
        k += 1
        term = [v * d / k for v in _matvec(m, term)]
        out = [a + b for a, b in zip(out, term)]
        if max(abs(v) for v in term) <= tol:
            return out


def relay_events(params: dict, x0, t_end: float, h: float = 5e-4, dps: int = 32):
    """``[(t, kind)]`` of the relay system from ``x0`` over ``[0, t_end]`` (``t`` as mpf), at ``dps`` digits.

    ``params``: ``zeta omega lam sigma rho`` as doubles (taken exactly).
    """
    mp.mp.dps = dps
    tol = mp.mpf(10) ** (-dps - 2)
    zeta, omega, lam, sigma, rho = (mp.mpf(float(params[k])) for k in ("zeta", "omega", "lam", "sigma", "rho"))
    a, b = _plant(zeta, omega, lam, sigma, rho)
    cb = b[0]  # C = [1, 0, 0]
    ca = a[0]
    a_slide = [[a[i][j] - b[i] * ca[j] / cb for j in range(3)] for i in range(3)]

    def augmented(mat, force):
        return [[*mat[i], force[i]] for i in range(3)] + [[mp.mpf(0)] * 4]

    mats = {
        "u+": augmented(a, b),
        "u-": augmented(a, [-v for v in b]),
        "slide": augmented(a_slide, [mp.mpf(0)] * 3),
    }
    hh = mp.mpf(h)
    steps = {k: mp.expm(mp.matrix(m) * hh).tolist() for k, m in mats.items()}

    def cax(x):
        return mp.fsum(ca[j] * x[j] for j in range(3))

    def guards(mode, z):
        if mode == "u+":
            return [-z[0]]
        if mode == "u-":
            return [z[0]]
        r = cax(z) / cb  # -u_eq
        return [1 + r, 1 - r]  # 1 - u_eq (exit to u+), 1 + u_eq (exit to u-)

    def on_surface(x):
        c = cax(x)
        if c - cb > 0:
            return "u-"
        if c + cb < 0:
            return "u+"
        return "slide"

    x = [mp.mpf(float(v)) for v in x0]
    mode = "u+" if x[0] < 0 else "u-" if x[0] > 0 else on_surface(x)
    t, t_end_mp, events = mp.mpf(0), mp.mpf(t_end), []
    while t < t_end_mp:
        m, step = mats[mode], steps[mode]
        z, s = [*x, mp.mpf(1)], mp.mpf(0)
        found = None
        while found is None and t + s < t_end_mp:
            z_next = _matvec(step, z)
            for q, g in enumerate(guards(mode, z_next)):
                if g <= 0:
                    lo, hi, g_lo, g_hi = mp.mpf(0), hh, guards(mode, z)[q], g
                    side = 0
                    for _ in range(200):  # Illinois on the flow from the grid state z
                        c = (lo * g_hi - hi * g_lo) / (g_hi - g_lo)
                        g_c = guards(mode, _flow_from(m, z, c, tol))[q]
                        if g_c > 0:
                            lo, g_lo = c, g_c
                            if side == 1:
                                g_hi /= 2
                            side = 1
                        else:
                            hi, g_hi = c, g_c
                            if side == -1:
                                g_lo /= 2
                            side = -1
                        if hi - lo <= tol:
                            break
                    d = hi if g_hi == 0 else (lo + hi) / 2
                    if found is None or d < found[1]:
                        found = (q, d)
            if found is None:
                z, s = z_next, s + hh
        if found is None:
            break
        q, d = found
        z = _flow_from(m, z, d, tol)
        x, t = z[:3], t + s + d
        if mode == "slide":
            kind, mode = "exit", ("u+" if q == 0 else "u-")
        else:
            new = on_surface(x)
            kind = "slide" if new == "slide" else "cross"
            mode = new
        events.append((t, kind))
    return events


def orbit_period(events, per_period: int, settle: float):
    """The time between the last event but ``per_period`` and the last, how much it differs from the
    same one period earlier, and the kinds of one period after ``settle``: ``(period, change, kinds)``."""
    late = [e for e in events if e[0] > settle]
    periods = [late[i + per_period][0] - late[i][0] for i in range(len(late) - per_period)]
    return periods[-1], abs(periods[-1] - periods[-1 - per_period]), [k for _, k in late[:per_period]]
