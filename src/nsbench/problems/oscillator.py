"""The dry-friction oscillator of MODEL.md as an explicit hybrid system.

One class serves the 1-DOF and 2-DOF problems: a chain of blocks on a belt,
block 1 tied to the ground, each further block tied to the previous one, the
harmonic force on the last block. It exposes the modes, the frozen-mode vector
field and Jacobian (vectorised over many states), the guards with their
expected signs, the transition map, the sliding-region functions and the
energy balance. It never hides a ``sign()`` inside a right-hand side.
"""

from __future__ import annotations

from typing import Any, Callable, Sequence

import numpy as np

from nsbench.problems.modes import (
    STICK,
    Guard,
    Mode,
    Transition,
    all_modes,
)
from nsbench.problems.parameters import Coefficients, Scales


class FrictionOscillator:
    """A chain of 1 or 2 blocks on a moving belt with Coulomb friction and stiction.

    Parameters
    ----------
    coefficients
        Masses, damping, springs, friction levels, forcing and belt speed, in
        the problem's own units (dimensionless unless ``dimensional``).
    name
        Registry name (``'one-dof'``, ``'two-dof'``).
    case
        Preset 1..4 the problem was built from, or ``None``.
    dimensional
        Whether ``coefficients`` are dimensional.
    params
        The user's parameter overrides (what rebuilds the problem with ``case``).
    parameters
        Every parameter value after presets and shorthands, in the user's vocabulary.
    scales
        Scales that convert this problem's units to the dimensionless form.

    Notes
    -----
    State ``y = [x1, v1, x2, v2, ...]``. Arrays of states are column-stacked:
    ``y`` of shape ``(n,)`` or ``(n, k)`` with ``t`` a scalar or shape ``(k,)``,
    the convention of ``scipy.integrate.solve_ivp(vectorized=True)``.
    """

    def __init__(
        self,
        coefficients: Coefficients,
        *,
        name: str,
        case: int | None,
        dimensional: bool,
        params: dict[str, float],
        parameters: dict[str, float],
        scales: Scales,
    ) -> None:
        self.coefficients = coefficients
        self.name = name
        self.case = case
        self.dimensional = dimensional
        self.params = dict(params)
        self.parameters = dict(parameters)
        self.scales = scales
        nb = coefficients.n_blocks
        self.n_blocks = nb
        self.n_states = 2 * nb
        self.state_names = tuple(f"{q}{i}" for i in range(1, nb + 1) for q in ("x", "v"))
        self._guards: dict[Mode, tuple[Guard, ...]] = {}
        self._packed: np.ndarray | None = None
        c = coefficients
        self._m = np.array(c.m)
        self._c = np.array(c.c)
        self._k = np.array(c.k)
        self._h = np.array(c.h)
        self._fs = np.array(c.fs)
        self._fr = np.array(c.fr)

    # ------------------------------------------------------------------ identity
    @property
    def modes(self) -> tuple[Mode, ...]:
        """All ``3**n_blocks`` modes (for small problems: tests, tables; the core never enumerates them)."""
        if self.n_blocks > 10:
            raise ValueError(f"{self.name} has 3**{self.n_blocks} modes: too many to list")
        return all_modes(self.n_blocks)

    @property
    def packed(self) -> np.ndarray:
        """The coefficients as the compiled kernels read them (:func:`nsbench.problems.kernels.pack`)."""
        if self._packed is None:
            from nsbench.problems.kernels import pack

            self._packed = pack(self)
        return self._packed

    @property
    def is_linear(self) -> bool:
        """True when every cubic coefficient is zero (the exact solver applies)."""
        return self.coefficients.is_linear

    @property
    def is_forced(self) -> bool:
        return self.coefficients.is_forced

    @property
    def v0(self) -> float:
        return self.coefficients.v0

    def config(self) -> dict[str, Any]:
        """The small dict that rebuilds this problem with :func:`nsbench.get_problem`."""
        return {
            "name": self.name,
            "case": self.case,
            "dimensional": self.dimensional,
            "params": dict(self.params),
        }

    def __repr__(self) -> str:
        units = "dimensional" if self.dimensional else "dimensionless"
        case = f", case={self.case}" if self.case is not None else ""
        extra = f", params={self.params}" if self.params else ""
        return f"<{self.name}{case}, {units}{extra}>"

    def initial_state(self) -> np.ndarray:
        """The standard initial condition: every block at rest at the origin."""
        return np.zeros(self.n_states)

    # ------------------------------------------------------------------ forces
    def link_forces(self, x: Sequence[Any]) -> list[Any]:
        """Tension of each spring link: link 0 ties block 1 to the ground.

        Written with plain arithmetic (cubes as ``d*d*d``) so the same code
        evaluates numpy arrays, floats or symbolic (heyoka) expressions.
        """
        c = self.coefficients
        out = []
        for j in range(self.n_blocks):
            d = x[j] - x[j - 1] if j > 0 else x[0]
            s = c.k[j] * d
            if c.h[j] != 0.0:
                s = s + c.h[j] * (d * d * d)
            out.append(s)
        return out

    def restoring_forces(self, t: Any, x: Sequence[Any], v: Sequence[Any],
                         cos: Callable[[Any], Any] = np.cos) -> list[Any]:
        """``R_i`` of MODEL.md: every force on block i except friction, moved left.

        Generic over the arithmetic of ``x``, ``v`` and ``t`` (see :meth:`link_forces`).
        """
        c = self.coefficients
        links = self.link_forces(x)
        nb = self.n_blocks
        out = []
        for i in range(nb):
            r = c.c[i] * v[i] + links[i]
            if i + 1 < nb:
                r = r - links[i + 1]
            if i == nb - 1 and c.F != 0.0:
                r = r - c.F * cos(c.w * t)
            out.append(r)
        return out

    def _split(self, y):
        y = np.asarray(y, dtype=float)
        return y, [y[2 * i] for i in range(self.n_blocks)], [y[2 * i + 1] for i in range(self.n_blocks)]

    def restoring_force(self, block: int, t, y):
        """``R_block`` (1-based block) at states ``y`` of shape ``(n,)`` or ``(n, k)``."""
        _, x, v = self._split(y)
        return self.restoring_forces(t, x, v)[block - 1]

    def belt_speed_restoring(self, t, x: Sequence[Any]) -> list[Any]:
        """The sliding-region functions: ``R_i`` with every ``v_i = v0``.

        Sliding region I is ``|R_1| <= fr_1``, region II ``|R_2| <= fr_2`` (it moves
        with ``t`` when forced), region III their overlap.
        """
        v = [self.v0 + 0.0 * np.asarray(xi, dtype=float) for xi in x]
        return self.restoring_forces(t, x, v)

    def in_sliding_region(self, block: int, t, x: Sequence[Any]):
        """Whether positions ``x`` lie in the sliding region of ``block`` (1-based)."""
        r = self.belt_speed_restoring(t, x)[block - 1]
        return np.abs(r) <= self.coefficients.fr[block - 1]

    def _link_stiffness(self, x):
        """Derivative of each link tension with respect to its extension."""
        c = self.coefficients
        out = []
        for j in range(self.n_blocks):
            if c.h[j] != 0.0:
                d = x[j] - x[j - 1] if j > 0 else x[0]
                out.append(c.k[j] + 3.0 * c.h[j] * d * d)
            else:
                out.append(c.k[j])
        return out

    def _restoring_gradient_x(self, x) -> list[dict[int, Any]]:
        """``dR_i/dx_j`` as ``{j: value}`` per block i (0-based indices)."""
        stiff = self._link_stiffness(x)
        nb = self.n_blocks
        grads = []
        for i in range(nb):
            g = {i: stiff[i] + (stiff[i + 1] if i + 1 < nb else 0.0)}
            if i > 0:
                g[i - 1] = -stiff[i]
            if i + 1 < nb:
                g[i + 1] = -stiff[i + 1]
            grads.append(g)
        return grads

    # ------------------------------------------------------------------ vector field
    def rhs(self, mode: Mode, t, y) -> np.ndarray:
        """Frozen-mode vector field. ``y`` of shape ``(n,)`` or ``(n, k)``."""
        y, x, v = self._split(y)
        out = np.empty_like(y)
        c = self.coefficients
        needs_r = any(p != STICK for p in mode)
        r = self.restoring_forces(t, x, v) if needs_r else None
        for i, phase in enumerate(mode):
            if phase == STICK:
                out[2 * i] = c.v0
                out[2 * i + 1] = 0.0
            else:
                out[2 * i] = v[i]
                out[2 * i + 1] = (-r[i] - c.fs[i] * phase) / c.m[i]
        return out

    def jacobian(self, mode: Mode, t, y) -> np.ndarray:
        """Jacobian of :meth:`rhs`: shape ``(n, n)`` or ``(n, n, k)`` for ``y`` of shape ``(n, k)``."""
        y, x, _ = self._split(y)
        n = self.n_states
        jac = np.zeros((n, n) + y.shape[1:])
        c = self.coefficients
        grads = None
        for i, phase in enumerate(mode):
            if phase == STICK:
                continue
            if grads is None:
                grads = self._restoring_gradient_x(x)
            jac[2 * i, 2 * i + 1] = 1.0
            for j, g in grads[i].items():
                jac[2 * i + 1, 2 * j] = -g / c.m[i]
            jac[2 * i + 1, 2 * i + 1] = -c.c[i] / c.m[i]
        return jac

    def linear_form(self, mode: Mode) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``(A, b0, bc, bs)`` with ``y' = A y + b0 + bc cos(w t) + bs sin(w t)``.

        Only for linear problems (every ``h = 0``), where each mode is affine.
        """
        if not self.is_linear:
            raise ValueError(f"{self.name}: linear_form needs h = 0 (the problem has cubic springs)")
        n = self.n_states
        a = self.jacobian(mode, 0.0, np.zeros(n))
        b0 = self.rhs(mode, 0.0, np.zeros(n))
        c = self.coefficients
        bc = np.zeros(n)
        bs = np.zeros(n)
        last = self.n_blocks - 1
        if c.F != 0.0 and mode[last] != STICK:
            # rhs(0, y=0) holds (F cos(0) - fs s) / m in the last velocity row; subtracting F / m
            # from it would round the friction term (fs = 0.81 came out as 0.8099999999999999), so
            # the constant is the friction term alone, as rhs forms it without the force.
            b0[2 * last + 1] = (-c.fs[last] * mode[last]) / c.m[last]
            bc[2 * last + 1] = c.F / c.m[last]
        return a, b0, bc, bs

    # ------------------------------------------------------------------ guards
    def guards(self, mode: Mode) -> tuple[Guard, ...]:
        """Guards of ``mode`` in the core's order: block by block, stick upper then lower (ties: lowest block).

        The list comes from :func:`nsbench.hybrid.rules.guards_of`, the one definition.
        """
        cached = self._guards.get(mode)
        if cached is None:
            from nsbench.hybrid.rules import guards_of

            gk, gb, gs = (np.empty(2 * self.n_blocks, np.int64) for _ in range(3))
            ng = guards_of(np.asarray(mode, np.int64), gk, gb, gs)
            kinds = ("velocity", "upper", "lower")
            cached = self._guards[mode] = tuple(
                Guard(self, int(gb[q]) + 1, kinds[int(gk[q])], int(gs[q])) for q in range(ng))
        return cached

    def guard_value(self, guard: Guard, t, y):
        """Value of ``guard`` at ``(t, y)`` (vectorised)."""
        i = guard.block - 1
        if guard.kind == "velocity":
            return np.asarray(y, dtype=float)[2 * i + 1] - self.v0
        r = self.restoring_force(guard.block, t, y)
        fr = self.coefficients.fr[i]
        return r - fr if guard.kind == "upper" else r + fr

    def guard_rate(self, guard: Guard, t, y, dydt):
        """d(guard)/dt along the direction ``dydt`` (vectorised)."""
        i = guard.block - 1
        dydt = np.asarray(dydt, dtype=float)
        if guard.kind == "velocity":
            return dydt[2 * i + 1]
        return self.restoring_rate(guard.block, t, y, dydt)

    def restoring_rate(self, block: int, t, y, dydt):
        """``dR_block/dt`` along ``dydt``, including the explicit time dependence."""
        i = block - 1
        y, x, _ = self._split(y)
        dydt = np.asarray(dydt, dtype=float)
        c = self.coefficients
        grad = self._restoring_gradient_x(x)[i]
        out = c.c[i] * dydt[2 * i + 1]
        for j, g in grad.items():
            out = out + g * dydt[2 * j]
        if i == self.n_blocks - 1 and c.F != 0.0:
            out = out + c.F * c.w * np.sin(c.w * np.asarray(t, dtype=float))
        return out

    # ------------------------------------------------------------------ transitions
    def initial_mode(self, t: float, y) -> Mode:
        """The mode of a state: slip with ``sign(v_i - v0)``, or stick if the friction holds.

        :func:`nsbench.hybrid.rules.initial_mode`, the one definition.
        """
        from nsbench.hybrid.rules import initial_mode

        mode = np.zeros(self.n_blocks, np.int64)
        initial_mode(self.packed, float(t), np.asarray(y, dtype=float), mode)
        return tuple(int(v) for v in mode)

    def transition(self, mode: Mode, guard: Guard, t: float, y) -> Transition:
        """Apply the transition map of MODEL.md when ``guard`` fires at ``(t, y)``.

        :func:`nsbench.hybrid.rules.transition`, the one definition: slip guard, ``v_i = v0``
        then stick if ``|R_i| <= fr_i`` else reverse with ``s_i = -sign(R_i)``; stick
        guard, slip with ``s_i = -sign(R_i)``.
        """
        from nsbench.hybrid.rules import transition
        from nsbench.problems.modes import EVENT_KINDS

        codes = {"velocity": 0, "upper": 1, "lower": 2}
        new = np.asarray(mode, np.int64).copy()
        y_new = np.array(y, dtype=float, copy=True)
        ev = transition(self.packed, new, codes[guard.kind], guard.block - 1, float(t), y_new)
        return Transition(tuple(int(v) for v in new), y_new, EVENT_KINDS[ev], guard.block)

    # ------------------------------------------------------------------ energy
    def energy(self, y):
        """Mechanical energy: kinetic plus spring potential (vectorised)."""
        y, x, v = self._split(y)
        c = self.coefficients
        e = 0.0
        for i in range(self.n_blocks):
            e = e + 0.5 * c.m[i] * v[i] * v[i]
            d = x[i] - x[i - 1] if i > 0 else x[0]
            e = e + 0.5 * c.k[i] * d * d + 0.25 * c.h[i] * d * d * d * d
        return e

    def friction_forces(self, mode: Mode, t, y) -> list[Any]:
        """Friction force on each block: ``-fs_i s_i`` in slip, ``R_i`` in stick."""
        y, x, v = self._split(y)
        r = self.restoring_forces(t, x, v)
        c = self.coefficients
        return [r[i] if p == STICK else -c.fs[i] * p + 0.0 * r[i] for i, p in enumerate(mode)]

    def power(self, mode: Mode, t, y) -> dict[str, Any]:
        """Power of friction, damping and the external force; they sum to dE/dt."""
        y, x, v = self._split(y)
        c = self.coefficients
        f = self.friction_forces(mode, t, y)
        friction = sum(f[i] * v[i] for i in range(self.n_blocks))
        damping = -sum(c.c[i] * v[i] * v[i] for i in range(self.n_blocks))
        force = c.F * np.cos(c.w * np.asarray(t, dtype=float)) * v[-1]
        return {"friction": friction, "damping": damping, "force": force}
