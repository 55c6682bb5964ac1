"""The problems ``fesd`` runs, written as nosnoc models: Stewart's regions and switching functions.

nosnoc integrates a Filippov system ``x' = f_0(x) + sum_k F_k(x) theta_k``, one subsystem ``k`` per
switching function ``c_k(x)``, each with its regions (the columns of ``F_k``, the rows of its sign
matrix ``S_k``: region ``j`` is where ``S_k[j] c_k(x) > 0``) and its multipliers ``theta_k``
(``sum theta_k = 1``; a vertex of the simplex in a region, an interior point while sliding on
``c_k = 0``). This module writes each mappable problem in that form, once per problem, with what
``fesd`` needs to read the answer back: the mode code of each region and of sliding, per subsystem,
and the state a sliding subsystem is snapped to. Every subsystem here has one switching function and
two regions.

**Mapped.**

- ``relay-feedback``: ``x' = A x + B`` where ``C x < 0`` (mode ``u+``), ``A x - B`` where ``C x > 0``
  (``u-``); sliding on ``C x = 0`` is the relay's sliding mode.
- ``casella-sliding``: ``(a1, b2)`` where ``x > y``, ``(a2, b1)`` where ``x < y``, ``c = x - y``.
- ``circle-oscillator``: ``A_in x`` inside the circle, ``A_out x`` outside, ``c = x1^2 + x2^2 - R^2``
  (a nonlinear surface: casadi differentiates it). The problem has no sliding mode (its crossing is
  transversal); a sliding label would be read as the region of the larger ``theta``.
- The friction oscillators (``one-dof``, ``two-dof``, ``chain``, ``block-on-ground``,
  ``den-hartog``) with Coulomb's law and ``fs = fr`` on every block: ``f_0`` the smooth part
  (``x_i' = v_i``, ``m_i v_i' = -R_i``, cubic springs and the harmonic force included, time as an
  appended clock state ``tau' = 1`` where the problem is forced), one subsystem per block with
  ``c_i = v_i - v0`` and the two slip regions (``-fs_i / m_i`` added to ``v_i'`` where ``v_i > v0``,
  ``+fs_i / m_i`` where ``v_i < v0``). Filippov sliding on ``v_i = v0`` has ``|R_i| <= fs_i``:
  exactly MODEL.md's stick when the static limit ``fr_i`` equals ``fs_i``, so a sliding block is
  reported stuck and snapped to ``v_i = v0`` (the relaxation leaves a small offset there). With
  ``fs_i < fr_i`` a stuck block would break away at ``|R_i| = fs_i``, not at ``fr_i``: stiction is
  not a Filippov system, and those problems are refused with each block's values.

Anything else is refused with :class:`~nsbench.errors.UnsupportedProblemError` and the reason.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Callable

import numpy as np

from nsbench.errors import UnsupportedProblemError

if TYPE_CHECKING:  # pragma: no cover
    from nsbench.problems.base import HybridProblem

#: Relative difference of ``fs_i`` and ``fr_i`` taken as equal: rounding of a dimensional conversion, no more.
SAME_FRICTION = 1e-12
#: The sign matrix of a subsystem whose region 0 is ``c > 0`` and region 1 ``c < 0``, and its mirror.
POSITIVE_FIRST = np.array([[1.0], [-1.0]])
NEGATIVE_FIRST = np.array([[-1.0], [1.0]])

#: ``(x, f_0, [F_k], [c_k], [S_k])`` of nosnoc's model, from casadi (the module ``ca``).
Equations = tuple[Any, Any, list, list, list]


@dataclass(frozen=True)
class FesdModel:
    """A problem as a nosnoc model (module docstring), with what reads its answer back.

    Attributes
    ----------
    n_states
        The problem's states; the model's are these and, with ``clock``, the time after them.
    clock
        Whether time is an appended state (a forced problem: nosnoc's fields depend on the state only).
    codes
        Per subsystem, the problem's mode code of region 0 and region 1 (the mode vector's entry
        ``k`` is subsystem ``k``'s).
    slides
        Per subsystem, the mode code of sliding on its surface, or ``None`` (the problem has none).
    snaps
        Per subsystem, ``(state index, value)`` that a sliding subsystem's state is set to, or ``None``.
    equations
        Builds the model's expressions from casadi (:data:`Equations`), called once per solver.
    """

    n_states: int
    clock: bool
    codes: tuple[tuple[int, int], ...]
    slides: tuple[int | None, ...]
    snaps: tuple[tuple[int, float] | None, ...]
    equations: Callable[[Any], Equations]

    @property
    def n_switch(self) -> int:
        """The number of switching functions (subsystems)."""
        return len(self.codes)

    def nosnoc_model(self, nosnoc: Any, ca: Any) -> Any:
        """nosnoc's ``NosnocModel`` of this problem (its ``x0`` is set per step)."""
        x, f_0, fields, switches, signs = self.equations(ca)
        n_x = self.n_states + (1 if self.clock else 0)
        return nosnoc.NosnocModel(x=x, F=fields, c=switches, S=signs, f_0=f_0, x0=np.zeros(n_x))

    def start(self, t: float, y: np.ndarray) -> np.ndarray:
        """The model's state at ``(t, y)``: ``y``, and ``t`` with a clock."""
        y = np.asarray(y, dtype=float)
        return np.append(y, t) if self.clock else y.copy()

    def label(self, theta: np.ndarray, floor: float) -> np.ndarray:
        """The mode of ``theta`` (shape ``(n_switch, 2)``, one stage): per subsystem its sliding code where
        ``min theta > floor`` (both regions active), else the code of the region of the larger ``theta``."""
        out = np.empty(self.n_switch, dtype=np.int64)
        for k, (row, codes, slide) in enumerate(zip(theta, self.codes, self.slides)):
            if slide is not None and float(np.min(row)) > floor:
                out[k] = slide
            else:
                out[k] = codes[0] if row[0] >= row[1] else codes[1]
        return out

    def sliding(self, mode: np.ndarray) -> np.ndarray:
        """Per subsystem, whether ``mode`` slides on its surface (a stuck block)."""
        return np.array([slide is not None and int(m) == slide for m, slide in zip(mode, self.slides)])

    def state(self, x: np.ndarray, mode: np.ndarray) -> np.ndarray:
        """The problem's state from the model's ``x``: without the clock, each sliding subsystem snapped."""
        y = np.array(x[: self.n_states], dtype=float)
        for k, snap in enumerate(self.snaps):
            if snap is not None and self.slides[k] is not None and int(mode[k]) == self.slides[k]:
                y[snap[0]] = snap[1]
        return y


# ---------------------------------------------------------------------- the relay family
def _relay(problem: Any) -> FesdModel:
    from nsbench.problems import relay_feedback_spec as spec

    a, b, c = (np.asarray(m, dtype=float) for m in (problem.A, problem.B, problem.C))

    def equations(ca: Any) -> Equations:
        x = ca.SX.sym("x", 3)
        ax = ca.mtimes(ca.DM(a), x)
        fields = ca.horzcat(ax + ca.DM(b), ax - ca.DM(b))  # region 0 (C x < 0): u = +1; region 1: u = -1
        return x, None, [fields], [ca.mtimes(ca.DM(c).T, x)], [NEGATIVE_FIRST]

    return FesdModel(3, False, ((spec.UP, spec.DOWN),), (spec.SLIDE,), (None,), equations)


def _casella(problem: Any) -> FesdModel:
    from nsbench.problems import casella_sliding_spec as spec

    above, below = (problem.field((m,)) for m in (spec.ABOVE, spec.BELOW))

    def equations(ca: Any) -> Equations:
        x = ca.SX.sym("x", 2)
        fields = ca.horzcat(ca.DM(above), ca.DM(below))  # region 0: x > y; region 1: x < y
        return x, None, [fields], [x[0] - x[1]], [POSITIVE_FIRST]

    return FesdModel(2, False, ((spec.ABOVE, spec.BELOW),), (spec.SLIDE,), (None,), equations)


def _circle(problem: Any) -> FesdModel:
    from nsbench.problems import circle_oscillator_spec as spec

    inside, outside = (problem.matrix((m,)) for m in (spec.INSIDE, spec.OUTSIDE))
    radius = float(problem.radius)

    def equations(ca: Any) -> Equations:
        x = ca.SX.sym("x", 2)
        fields = ca.horzcat(ca.mtimes(ca.DM(inside), x), ca.mtimes(ca.DM(outside), x))  # region 0: inside
        return x, None, [fields], [x[0] * x[0] + x[1] * x[1] - radius * radius], [NEGATIVE_FIRST]

    return FesdModel(2, False, ((spec.INSIDE, spec.OUTSIDE),), (None,), (None,), equations)


# ---------------------------------------------------------------------- the friction family
def check_friction(problem: Any, name: str) -> None:
    """Refuse a friction problem that is not a Filippov system: a law other than Coulomb's, or ``fs < fr``
    on a block (its values named per block)."""
    law = getattr(problem, "law_spec", None)
    if law is not None and not law.is_coulomb:
        raise UnsupportedProblemError(
            f"{name}: Coulomb's law only (a constant slip force fs, whose Filippov sliding on v = v0 is the "
            f"stick); {problem.name} has the {law.name} friction law"
        )
    c = problem.coefficients
    unequal = [i for i in range(problem.n_blocks) if abs(c.fs[i] - c.fr[i]) > SAME_FRICTION * max(abs(c.fr[i]), 1.0)]
    if unequal:
        values = ", ".join(f"block {i + 1}: fs = {c.fs[i]:.6g}, fr = {c.fr[i]:.6g}" for i in unequal)
        raise UnsupportedProblemError(
            f"{name}: stiction (static friction fr above the kinetic fs) is not a Filippov system: its sliding on "
            f"v = v0 ends at |R| = fs, not fr. It runs friction problems with fs = fr on every block only; "
            f"{problem.name} has {values} (give fs = fr, e.g. r_f = 1 in the dimensionless form)"
        )


def _friction(problem: Any, name: str) -> FesdModel:
    from nsbench.problems.modes import SLIP_NEG, SLIP_POS, STICK

    check_friction(problem, name)
    c, nb, v0 = problem.coefficients, problem.n_blocks, float(problem.v0)
    clock = bool(problem.is_forced)
    n_x = 2 * nb + (1 if clock else 0)

    def equations(ca: Any) -> Equations:
        x = ca.SX.sym("x", n_x)
        pos, vel = [x[2 * i] for i in range(nb)], [x[2 * i + 1] for i in range(nb)]
        # R_i with casadi's arithmetic (restoring_forces is written for any); t is the clock, or unused
        r = problem.restoring_forces(x[2 * nb] if clock else 0.0, pos, vel, cos=ca.cos)
        rows = []
        for i in range(nb):
            rows += [vel[i], -r[i] / c.m[i]]
        f_0 = ca.vertcat(*rows, *([1.0] if clock else []))
        fields, switches = [], []
        for i in range(nb):
            slip = np.zeros((n_x, 2))
            slip[2 * i + 1] = (-c.fs[i] / c.m[i], c.fs[i] / c.m[i])  # region 0: v_i > v0 (slip+); 1: slip-
            fields.append(ca.DM(slip))
            switches.append(vel[i] - v0)
        return x, f_0, fields, switches, [POSITIVE_FIRST] * nb

    return FesdModel(
        n_states=2 * nb,
        clock=clock,
        codes=((SLIP_POS, SLIP_NEG),) * nb,
        slides=(STICK,) * nb,
        snaps=tuple((2 * i + 1, v0) for i in range(nb)),
        equations=equations,
    )


def fesd_model(problem: "HybridProblem", name: str = "fesd") -> FesdModel:
    """``problem`` as a nosnoc model (module docstring), or :class:`UnsupportedProblemError` with the reason.

    Builds no casadi expression (that is :attr:`FesdModel.equations`, called by the solver): a refusal
    needs neither nosnoc nor casadi.
    """
    from nsbench.problems.casella_sliding import CasellaSliding
    from nsbench.problems.circle_oscillator import CircleOscillator
    from nsbench.problems.oscillator import FrictionOscillator
    from nsbench.problems.relay_feedback import RelayFeedback

    if isinstance(problem, RelayFeedback):
        return _relay(problem)
    if isinstance(problem, CasellaSliding):
        return _casella(problem)
    if isinstance(problem, CircleOscillator):
        return _circle(problem)
    if isinstance(problem, FrictionOscillator):
        return _friction(problem, name)
    raise UnsupportedProblemError(
        f"{name}: nsbench writes as nosnoc models the relay feedback system, Casella's sliding test, the "
        f"circle oscillator and the friction oscillators with fs = fr (Filippov systems); {problem.name} "
        f"({problem.family or '?'} family) is not mapped"
    )


def default_elements(model: FesdModel) -> int:
    """``n_fe`` where not given: one element per switching function and one more, so that every block of a
    chain can switch at its own element boundary within one step."""
    return model.n_switch + 1


__all__ = ["FesdModel", "fesd_model", "check_friction", "default_elements", "SAME_FRICTION"]
