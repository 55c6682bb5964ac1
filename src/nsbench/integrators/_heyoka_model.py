"""The friction oscillator as one heyoka Taylor integrator whose mode lives in runtime parameters.

Shared by the ``heyoka*`` integrators (and so by ``reference``). The compiled
object depends only on the problem's *structure* (number of blocks, which
springs are cubic, forced or not, number of section slots, precision and
tolerance); the coefficients, the mode and the sections are runtime
parameters, so a mode switch or a new parameter value never recompiles.

Parameter layout: ``m, c, k, h, fs, fr, fk, delta, vs, cv`` (one per block each; the
last four are the friction law's, whose slip level enters the field as an expression
when the law is not Coulomb's: the law code is part of the structure), ``F, w, v0, law``,
then per block a stick flag ``sigma_i`` (1 stuck, 0 slipping) and a slip sign
``s_i``, then per guard (three per block: velocity ``v_i - v0``, upper
``R_i - fr_i`` and lower ``R_i + fr_i`` static limit) an activation flag and
its expected sign, then per section slot ``active, level`` and one coefficient
per mechanical state. Each guard is a terminal event written as
``expected_sign * guard``, so that it ends its phase when it *decreases*
through zero; an inactive one is the constant 1 and can never fire.

With every block stuck the mechanical states are polynomials in time and say
nothing about the forcing ``F cos(w t)``, which drives the stick guards; a step
size chosen from the state's Taylor coefficients would then jump over a
force-driven slip. The forcing therefore enters through two extra states
``c = cos(w t)``, ``s = sin(w t)`` (``c' = -w s``, ``s' = w c``), which keep
the step at a fraction of the forcing period.
"""

from __future__ import annotations

import copy
import threading
import time
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import heyoka as hy
import numpy as np

from nsbench.integrators.base import SectionHit
from nsbench.problems.friction_laws import slip_level
from nsbench.problems.friction_spec import COULOMB, LAYOUT

if TYPE_CHECKING:  # pragma: no cover
    from nsbench.integrators.base import ArcRequest
    from nsbench.problems.oscillator import FrictionOscillator

GUARD_SLOT = {"velocity": 0, "upper": 1, "lower": 2}
#: The slots of a guard's record in the runtime parameters (at :meth:`Structure.guard_par`): the flag that
#: switches the guard on (1) or off (0), and its expected sign.
GUARD_ACTIVE, GUARD_SIGN, GUARD_RECORD = 0, 1, 2
#: The slots of a section's record (at :meth:`Structure.section_offset`): its flag, its level, then the
#: coefficients of the mechanical state.
SECTION_ACTIVE, SECTION_LEVEL, SECTION_COEFFS = 0, 1, 2
#: The coefficients' layout (the friction law's, whose head, the block count, is left out here).
COEFFICIENTS = LAYOUT

#: Floating-point types by the precision names of :class:`Capabilities`.
FP_TYPES: dict[str, Any] = {"double": float, "long double": np.longdouble, "quad": getattr(hy, "real128", None)}


@dataclass(frozen=True)
class Structure:
    """What the compiled code depends on; problems that share it share the code."""

    n_blocks: int
    cubic: tuple[bool, ...]
    forced: bool
    n_sections: int
    law: int = COULOMB

    @classmethod
    def of(cls, problem: "FrictionOscillator", n_sections: int) -> "Structure":
        c = problem.coefficients
        return cls(c.n_blocks, tuple(h != 0.0 for h in c.h), c.F != 0.0, n_sections, problem.law_spec.code)

    @property
    def n_mech(self) -> int:
        return 2 * self.n_blocks

    @property
    def n_states(self) -> int:
        return self.n_mech + (2 if self.forced else 0)

    @property
    def mode_offset(self) -> int:
        """After the coefficients (:func:`coefficient_values`)."""
        return len(COEFFICIENTS.fields) * self.n_blocks + len(COEFFICIENTS.tail)

    @property
    def guard_offset(self) -> int:
        return self.mode_offset + 2 * self.n_blocks

    def guard_par(self, guard) -> int:
        """Index of a guard's record (:data:`GUARD_ACTIVE`, :data:`GUARD_SIGN`) in the runtime parameters."""
        return self.guard_offset + GUARD_RECORD * (len(GUARD_SLOT) * (guard.block - 1) + GUARD_SLOT[guard.kind])

    def section_offset(self, slot: int) -> int:
        """After the guards' flags and signs (two entries per guard kind and block)."""
        return (
            self.guard_offset + GUARD_RECORD * len(GUARD_SLOT) * self.n_blocks + slot * (SECTION_COEFFS + self.n_mech)
        )

    def coefficient(self, name: str, block: int = 0) -> int:
        """Index of a coefficient (of ``block``, 0-based, for the per-block ones) in the runtime parameters."""
        return LAYOUT.offset(name, self.n_blocks, block) - LAYOUT.head_size

    @property
    def n_pars(self) -> int:
        return self.section_offset(self.n_sections)


def coefficient_values(problem: "FrictionOscillator") -> list[float]:
    """The first parameters: the problem's coefficients, in the order of the friction law's layout
    (:data:`COEFFICIENTS`, without the block count)."""
    return [float(v) for v in problem.packed[LAYOUT.head_size :]]


class SectionLog:
    """Callback of one section slot: records ``(slot, t, direction, state)`` of each crossing."""

    def __init__(self, slot: int) -> None:
        self.slot = slot
        self.hits: list[tuple[int, Any, int, np.ndarray]] = []

    def __call__(self, ta, t, d_sgn) -> None:
        self.hits.append((self.slot, t, int(d_sgn), np.array(ta.update_d_output(t), copy=True)))


def _system(st: Structure):
    """State variables, equations, terminal and non-terminal event expressions."""
    sys, parts, sections = _system_parts(st)
    guards = [active * (expected * value) + (1.0 - active) for active, expected, value in parts]
    return sys, guards, sections


#: The kind of the native run's event that stands for a block's velocity guard or its upper static limit
#: (:func:`native_guards`): negative, so that no guard code of a problem is taken for it.
VELOCITY_OR_UPPER = -1


def native_guards(st: Structure):
    """The field, two terminal events per block, and the sections: the whole-run integrators' model.

    A block's guards are its velocity guard while it slips and its two static limits while it sticks
    (``friction_law.guards_of``), never the velocity guard and a limit at once. So the velocity guard
    and the upper limit share one event, ``a_v (e_v g_v) + a_u (e_u g_u) + (1 - a_v - a_u)``: the active
    one of them exactly (the other term is ``0 * ...`` and the constant ``0``), or the constant 1 when
    neither is active; the lower limit keeps its own. heyoka computes and searches every event on every
    step, active or not, so an event costs about a quarter of a step without events (2-DOF case 1, AMD
    EPYC: a step 0.33 us without events, 0.77 with six, 0.62 with these four); the callback tells the
    two guards apart by the mode (``_heyoka_native._guard_event``).

    Returns ``(sys, events, sections)``, ``events`` a list of ``(expression, kind, block)`` with ``kind``
    :data:`VELOCITY_OR_UPPER` or the lower limit's slot, ``block`` 0-based.
    """
    sys, parts, sections = _system_parts(st)
    events = []
    lower = GUARD_SLOT["lower"]
    for i in range(st.n_blocks):
        (av, ev, gv), (au, eu, gu), (al, el, gl) = parts[len(GUARD_SLOT) * i : len(GUARD_SLOT) * (i + 1)]
        events.append((av * (ev * gv) + au * (eu * gu) + (1.0 - av - au), VELOCITY_OR_UPPER, i))
        events.append((al * (el * gl) + (1.0 - al), lower, i))
    return sys, events, sections


def _system_parts(st: Structure):
    """The field, each guard as ``(active, expected_sign, value)`` in the order (block, velocity/upper/lower),
    and the sections."""
    nb = st.n_blocks
    mech = hy.make_vars(*[f"{q}{i}" for i in range(1, nb + 1) for q in ("x", "v")])
    x, v = mech[0::2], mech[1::2]
    par = hy.par
    m, c, k, h, fs, fr, fk, delta, vs, cv = (
        [par[st.coefficient(name, i)] for i in range(nb)] for name in LAYOUT.fields
    )
    F, w, v0 = (par[st.coefficient(name)] for name in ("F", "w", "v0"))
    sigma = [par[st.mode_offset + i] for i in range(nb)]
    sign = [par[st.mode_offset + nb + i] for i in range(nb)]
    cos_wt, sin_wt = hy.make_vars("cos_wt", "sin_wt") if st.forced else (None, None)

    tension = []
    for j in range(nb):
        d = x[j] - x[j - 1] if j > 0 else x[0]
        s = k[j] * d
        if st.cubic[j]:
            s = s + h[j] * (d * d * d)  # not d**3: its Taylor coefficients are NaN at d = 0
        tension.append(s)
    restoring = []
    for i in range(nb):
        r = c[i] * v[i] + tension[i]
        if i + 1 < nb:
            r = r - tension[i + 1]
        if i == nb - 1 and st.forced:
            r = r - F * cos_wt
        restoring.append(r)

    sys = []
    for i in range(nb):
        slipping = 1.0 - sigma[i]
        sys.append((x[i], sigma[i] * v0 + slipping * v[i]))
        if st.law == COULOMB:
            level = fs[i]
        else:  # the friction law's slip level at u = s (v - v0) (0 while stuck: s = 0 there)
            level = slip_level(st.law, sign[i] * (v[i] - v0), fs[i], fk[i], delta[i], vs[i], cv[i], exp=hy.exp)
        sys.append((v[i], slipping * (-restoring[i] - level * sign[i]) / m[i]))
    if st.forced:
        sys += [(cos_wt, -w * sin_wt), (sin_wt, w * cos_wt)]

    guards = []
    for i in range(nb):
        for slot, value in enumerate((v[i] - v0, restoring[i] - fr[i], restoring[i] + fr[i])):
            off = st.guard_offset + GUARD_RECORD * (len(GUARD_SLOT) * i + slot)
            guards.append((par[off + GUARD_ACTIVE], par[off + GUARD_SIGN], value))
    sections = []
    for q in range(st.n_sections):
        off = st.section_offset(q)
        value = par[off + SECTION_COEFFS] * mech[0]
        for j in range(1, st.n_mech):
            value = value + par[off + SECTION_COEFFS + j] * mech[j]
        active = par[off + SECTION_ACTIVE]
        sections.append(active * (value - par[off + SECTION_LEVEL]) + (1.0 - active))
    return sys, guards, sections


#: The field, guards and sections of a structure (the native run's integrator is built from them too).
system = _system

_CACHE: dict[tuple, tuple[Any, float]] = {}
_LOCK = threading.Lock()


def compiled(
    st: Structure, precision: str, tol: float | None, high_accuracy: bool, compact_mode: bool
) -> tuple[Any, float]:
    """A fresh copy of the compiled integrator for ``st`` and the seconds its compilation took.

    Compilations are cached per process; a cache hit costs a copy (about a
    millisecond) and reports a compile time of 0.
    """
    key = (st, precision, tol, high_accuracy, compact_mode)
    with _LOCK:
        hit = _CACHE.get(key)
        if hit is None:
            fp = FP_TYPES[precision]
            tic = time.perf_counter()
            sys, guards, sections = _system(st)
            neg = hy.event_direction.negative
            # No cooldown: each arc is a fresh propagation that ends at its first
            # event, and a cooldown could only hide a genuine event (MODEL.md).
            t_events = [hy.t_event(g, direction=neg, cooldown=fp(0.0), fp_type=fp) for g in guards]
            nt_events = [hy.nt_event(e, SectionLog(q), fp_type=fp) for q, e in enumerate(sections)]
            kwargs = {} if tol is None else {"tol": fp(tol)}
            ta = hy.taylor_adaptive(
                sys,
                np.zeros(st.n_states, dtype=fp),
                pars=np.zeros(st.n_pars, dtype=fp),
                fp_type=fp,
                t_events=t_events,
                nt_events=nt_events,
                high_accuracy=high_accuracy,
                compact_mode=compact_mode,
                **kwargs,
            )
            hit = _CACHE[key] = (ta, time.perf_counter() - tic)
            return copy.deepcopy(ta), hit[1]
    return copy.deepcopy(hit[0]), 0.0


def guard_index(request: "ArcRequest", event: int) -> int | None:
    """Index in ``request.guards`` of heyoka terminal event ``event``, or ``None`` if inactive."""
    block, slot = divmod(event, 3)
    for q, guard in enumerate(request.guards):
        if guard.block == block + 1 and GUARD_SLOT[guard.kind] == slot:
            return q
    return None


def section_hits(ta, request: "ArcRequest", t0, t_stop, logs=None) -> list[SectionHit]:
    """Crossings recorded by the section callbacks in ``(t0, t_stop]``, in their direction.

    ``logs``: the callbacks of ``ta``'s non-terminal events, if the caller has them at hand.
    """
    n = request.problem.n_states
    hits = []
    for log in [ev.callback for ev in ta.nt_events] if logs is None else logs:
        for slot, t, d_sgn, y in log.hits:
            if slot >= len(request.sections) or not (t0 < t <= t_stop) or d_sgn == 0:
                continue  # starting on a section is not a crossing; touches are not either
            direction = request.sections[slot].direction
            if direction == 0 or direction == d_sgn:
                hits.append(SectionHit(slot, float(t), np.asarray(y[:n]).astype(float)))
    hits.sort(key=lambda h: h.t)
    return hits


def illinois(f, a, fa, b, fb, iterations: int = 100):
    """Root of ``f`` in ``[a, b]`` with ``fa > 0 >= fb`` (Illinois regula falsi), in ``a``'s precision."""
    side = 0
    for _ in range(iterations):
        if fb == 0:
            break
        c = (a * fb - b * fa) / (fb - fa)
        if not a < c < b:
            # the secant lands on an end: one end is at the root to rounding (fa ~ 0) while the other is
            # still far, so halve instead (returning b here could leave it 1e-6 past the root)
            c = a + (b - a) / 2
            if not a < c < b:
                break  # [a, b] is two adjacent numbers: b is the root, on the guard's far side
        fc = f(c)
        if fc > 0:
            a, fa = c, fc
            if side == 1:
                fb = fb / 2
            side = 1
        else:
            b, fb = c, fc
            if side == -1:
                fa = fa / 2
            side = -1
    return b
