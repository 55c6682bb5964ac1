"""``exact``: the closed-form flow of each mode of a linear problem, the reference.

With ``h = 0`` every mode is affine with constant, linear-in-time (a stuck
neighbour moving with the belt) and harmonic forcing (MODEL.md section 5).
Stuck blocks move as ``x = x0 + v0 s``; the slipping blocks obey
``u' = A u + forcing`` and are solved as a particular solution (polynomial plus
harmonic) plus ``V exp(Lambda s) V^-1`` times the initial offset. The flow is
evaluated directly at any ``s`` from the arc's start, never chained step by
step, so no error accumulates inside an arc (``scipy.linalg.expm`` chained over
many periods drifts by ~1e-13 per period, MODEL.md section 6).

The arcs run in the compiled kernel :mod:`nsbench.integrators._exact_kernel`
(guards in modal form, a curvature bound that rules out crossings between scan
points, Newton kept in the bracket and a double-double polish, compensated event
times). This module builds the tables
of a mode, on the first visit of that mode only (the ``3^n`` modes of a problem
are never enumerated): the eigen-decomposition of the slipping sub-system, the
particular solution, the rows that express each guard of the mode in the
augmented state ``[y, 1, cos w t, sin w t]``, and the augmented matrix that
replaces the modal form when a mode is defective or resonant (critical damping,
undamped resonance).
"""

from __future__ import annotations

import math
from collections import OrderedDict
from dataclasses import dataclass

import numpy as np

from nsbench.integrators.base import Capabilities, CompiledArcs, Option

#: Eigenvector condition numbers beyond this make a mode "defective": the matrix exponential is used.
MAX_CONDITION = 1e4


def pair_weights(lam: np.ndarray, vec: np.ndarray, vinv: np.ndarray) -> np.ndarray:
    """Weights that sum each conjugate pair of modal terms as twice the real part of one.

    For a real system the terms of ``lam`` and ``conj(lam)`` are conjugate (their
    eigenvectors, inverse rows and hence coefficients are), so their sum is
    ``2 Re`` of the first: half the exponentials. Pairs whose vectors are not
    conjugate to rounding keep weight 1 each.
    """
    w = np.ones(lam.size)
    used: set[int] = set()
    for c in range(lam.size):
        if c in used or lam[c].imag <= 0:
            continue
        for d in range(lam.size):
            if d == c or d in used:
                continue
            scale = max(1.0, abs(lam[c]))
            if (
                abs(lam[d] - np.conj(lam[c])) <= 1e-12 * scale
                and np.allclose(vec[:, d], np.conj(vec[:, c]), rtol=0, atol=1e-13)
                and np.allclose(vinv[d], np.conj(vinv[c]), rtol=0, atol=1e-13 * max(1.0, np.abs(vinv).max()))
            ):
                w[c], w[d] = 2.0, 0.0
                used.update((c, d))
                break
    return w


@dataclass(frozen=True)
class ModalForm:
    """The modal form of a slipping sub-system ``u' = A u`` (what depends on ``A`` alone).

    ``defective`` (a singular, defective or, under forcing at ``w``, resonant
    system) means the other fields are not used: the kernel takes the matrix
    exponential of the augmented system instead.
    """

    lam: np.ndarray
    vec: np.ndarray
    defective: bool
    vinv: np.ndarray | None = None
    ainv: np.ndarray | None = None
    weights: np.ndarray | None = None
    lam_lo: np.ndarray | None = None
    vec_lo: np.ndarray | None = None


#: Modal forms by the bytes of ``A`` (and the forcing frequency), most recent last. A sweep over
#: a parameter that ``A`` does not hold (a belt speed, a force) meets the same few sub-systems at
#: every value: their eigen-decompositions and polish are computed once per process. The key is
#: the exact bytes, so a hit returns what the computation would (it is deterministic).
_MODAL: OrderedDict[tuple, ModalForm] = OrderedDict()
MODAL_CACHE_SIZE = 256


def modal_form(a_ss: np.ndarray, w: float | None) -> ModalForm:
    """The (cached) :class:`ModalForm` of ``a_ss``; ``w``: the forcing frequency, or ``None`` unforced."""
    key = (a_ss.shape, a_ss.tobytes(), w)
    found = _MODAL.get(key)
    if found is not None:
        _MODAL.move_to_end(key)
        return found
    found = _modal_form(a_ss, w)
    _MODAL[key] = found
    if len(_MODAL) > MODAL_CACHE_SIZE:
        _MODAL.popitem(last=False)
    return found


def _modal_form(a_ss: np.ndarray, w: float | None) -> ModalForm:
    from nsbench.integrators import _exact_polish as polish

    ns = a_ss.shape[0]
    lam, vec = np.linalg.eig(a_ss)
    cond = np.linalg.cond(vec)
    # a singular system (a free body: x'' = const) has polynomial terms the modal form lacks
    singular = not np.abs(lam).min() > 1e-12 * max(1.0, np.abs(lam).max())
    defective = singular or not (math.isfinite(cond) and cond < MAX_CONDITION)
    if w is not None and not defective:
        shifted = 1j * w * np.eye(ns) - a_ss
        defective = not np.linalg.cond(shifted) < 1e8  # undamped resonance
    if defective:
        return ModalForm(lam, vec, True)
    vinv = np.linalg.inv(vec)
    ainv = np.linalg.inv(a_ss)
    lam_lo = vec_lo = None
    if ns <= polish.MAX_POLISH:
        lam_lo = np.zeros(ns, np.complex128)
        vec_lo = np.zeros((ns, ns), np.complex128)
        polish.refine_eigenpairs(a_ss, lam.copy(), np.ascontiguousarray(vec), lam_lo, vec_lo)
    return ModalForm(lam, vec, False, vinv, ainv, pair_weights(lam, vec, vinv), lam_lo, vec_lo)


class ModeTables:
    """The closed forms of the modes of one problem visited so far, in the kernel's layout.

    The layout (:mod:`nsbench.integrators._exact_layout`): one row per mode in
    three packed arrays, found through a hash of the mode.
    """

    def __init__(self, problem, capacity: int = 16) -> None:
        from nsbench.integrators._exact_layout import S_FORCED, S_W, empty_tables

        if not problem.is_linear:
            raise ValueError("closed forms need a linear problem")
        self.problem = problem
        self.n_modes = 0
        self._visited: list[tuple[int, ...]] = []
        self.dims = (problem.n_states, problem.mode_size, problem.max_guards)
        self.data = empty_tables(capacity, *self.dims)
        w = problem.forcing_frequency
        self.data.scal[S_FORCED] = 1.0 if (problem.is_forced and w != 0.0) else 0.0
        self.data.scal[S_W] = w

    def add(self, mode: np.ndarray):
        """Build the tables of ``mode`` (int array of phases); return the (possibly grown) tables."""
        from nsbench.integrators._exact_kernel import find_mode, insert_mode
        from nsbench.integrators._exact_layout import I_READY

        mode = np.asarray(mode, np.int64)
        t = self.data
        if find_mode(t.keys, t.slots, t.ti, mode) >= 0:
            return t
        if self.n_modes == t.ti.shape[0]:
            self._grow()
            t = self.data
        slot = self.n_modes
        key = tuple(int(v) for v in mode)
        self._fill(slot, key)
        insert_mode(t.keys, t.slots, t.ti, mode, slot)
        t.ti[slot, I_READY] = 1
        self.n_modes += 1
        self._visited.append(key)
        return t

    @property
    def visited(self) -> list[tuple[int, ...]]:
        """The modes filled so far (a list that grows with the tables), in the order they were."""
        return self._visited

    def ensure_sections(self, n_sections: int):
        """The tables, with scratch for ``n_sections`` sections."""
        from nsbench.integrators._exact_layout import with_sections

        self.data = with_sections(self.data, n_sections)
        return self.data

    def _grow(self) -> None:
        from nsbench.integrators._exact_kernel import insert_mode
        from nsbench.integrators._exact_layout import I_MODE, empty_tables

        old = self.data
        n, m, g = self.dims
        new = empty_tables(2 * old.ti.shape[0], n, m, g, old.wr.shape[0] - g)
        for name in ("ti", "tf", "tc"):
            getattr(new, name)[: self.n_modes] = getattr(old, name)[: self.n_modes]
        new.scal[:] = old.scal
        for s in range(self.n_modes):
            insert_mode(new.keys, new.slots, new.ti, old.ti[s, I_MODE : I_MODE + m].copy(), s)
        self.data = new

    def _fill(self, s: int, mode: tuple[int, ...]) -> None:
        from nsbench.integrators import _exact_layout as lay

        t = self.data
        p = self.problem
        n, m, g = self.dims
        n3 = n + 3
        f_q, f_aug = lay.f_offsets(n, g)[9:11]
        tf, tc, ti = t.tf[s], t.tc[s], t.ti[s]
        a, b0, bc, bs = p.linear_form(mode)
        w = p.forcing_frequency
        forced = t.scal[lay.S_FORCED] != 0.0
        if p.is_forced and w == 0.0:
            b0 = b0 + bc  # cos(0 t) = 1: a constant force
            bc = np.zeros(n)
        # Everything but the constant force b0 (and the guards) depends on the mode's matrix and
        # harmonic forcing alone; a sweep over a belt speed or a force meets the same few of them
        # at every value. Those parts of the row are kept by the exact bytes they come from and
        # copied (the numbers the computation gives); the parts that b0 enters are computed anew.
        key = (self.dims, mode, a.tobytes(), bc.tobytes(), bs.tobytes(), float(w), bool(forced))
        rows = _ROWS.get(key)
        if rows is None:
            parts = self._fill_static(s, a, bc, bs, w, forced)
            _b0_parts(tf, n, g, b0, parts)
            rows = _Rows(tf.copy(), tc.copy(), ti.copy(), parts)
            _ROWS[key] = rows
            if len(_ROWS) > ROWS_CACHE_SIZE:
                _ROWS.popitem(last=False)
        else:
            _ROWS.move_to_end(key)
            tf[:], tc[:], ti[:] = rows.tf, rows.tc, rows.ti
            _b0_parts(tf, n, g, b0, rows.parts)
        aug_b0 = tf[f_aug + n : f_aug + n * n3 : n3]  # column n of the augmented matrix: b0
        aug_b0[:] = b0
        # the guards in the law's order, read as (kind, block) arrays: no Guard objects are needed here
        tf[f_q:f_aug] = 0.0
        kind, block = np.zeros(max(g, 1), np.int64), np.zeros(max(g, 1), np.int64)
        n_guards = p.law.guards_of(p.data.p, np.asarray(mode, np.int64), kind, block, np.zeros(max(g, 1), np.int64))
        for q in range(n_guards):
            tf[f_q + q * n3 : f_q + (q + 1) * n3] = p.guard_row(mode, int(kind[q]), int(block[q]))

    def _fill_static(self, s: int, a: np.ndarray, bc: np.ndarray, bs: np.ndarray, w: float, forced: bool) -> _Parts:
        """The parts of slot ``s``'s row that b0 does not enter (into a row of zeros); what b0's need."""
        from nsbench.integrators import _exact_layout as lay
        from nsbench.integrators import _exact_polish as polish

        t = self.data
        n, m, g = self.dims
        n3 = n + 3
        f_cw, f_ainv, f_ask, f_ass, _, _, _, _, f_rate, _, f_aug, _ = lay.f_offsets(n, g)
        c_lam, c_lamlo, c_z, c_zlo, c_vec, c_veclo, c_vinv, _ = lay.c_offsets(n)
        tf, tc, ti = t.tf[s], t.tc[s], t.ti[s]
        # A state whose row of A is zero and that no harmonic term drives moves at a constant rate
        # (a block stuck to the belt: x at v0, v at 0): it is "stuck"; the others form the modal system.
        still = [j for j in range(n) if not a[j].any() and bc[j] == 0.0 and bs[j] == 0.0]
        slip = [j for j in range(n) if j not in still]
        stuck = still
        ns, nst = len(slip), len(stuck)
        o_slip, o_stuck = lay.i_slip(m), lay.i_stuck(m, n)
        ti[o_slip : o_slip + ns], ti[o_stuck : o_stuck + nst] = slip, stuck
        rates = [w if forced else 0.0]
        defective = False
        polished = ns == 0  # every state stuck: nothing to refine, the polish is exact
        a_ss = a_sk = ainv = None

        def put(off: int, block: np.ndarray, target=tf) -> None:  # an ns x nc block at row stride n
            rows, cols = block.shape
            for r in range(rows):
                target[off + r * n : off + r * n + cols] = block[r]

        if ns:
            a_ss = np.ascontiguousarray(a[np.ix_(slip, slip)])
            a_sk = a[np.ix_(slip, stuck)]
            modal = modal_form(a_ss, w if forced else None)
            lam, vec = modal.lam, modal.vec
            rates.extend(np.abs(lam))
            defective = modal.defective
            if not defective:
                vinv, ainv = modal.vinv, modal.ainv
                assert vinv is not None and ainv is not None  # set whenever the form is not defective
                tc[c_lam : c_lam + ns] = lam
                put(c_vec, vec, tc)
                put(c_vinv, vinv, tc)
                tf[f_cw : f_cw + ns] = modal.weights
                put(f_ainv, ainv)
                put(f_ass, a_ss)
                if nst:
                    put(f_ask, a_sk)
                harmonic = bc[slip] - 1j * bs[slip]
                z = np.linalg.solve(1j * w * np.eye(ns) - a_ss, harmonic) if forced else np.zeros(ns, complex)
                tc[c_z : c_z + ns] = z
                if ns <= polish.MAX_POLISH:
                    assert modal.vec_lo is not None
                    tc[c_lamlo : c_lamlo + ns] = modal.lam_lo
                    put(c_veclo, modal.vec_lo, tc)
                    if forced:
                        z_lo = np.zeros(ns, np.complex128)
                        polish.refine_harmonic(a_ss, w, z.copy(), np.asarray(harmonic, np.complex128), z_lo)
                        tc[c_zlo : c_zlo + ns] = z_lo
                    polished = True
        ti[lay.I_NS], ti[lay.I_NST], ti[lay.I_DEFECTIVE] = ns, nst, int(defective)
        ti[lay.I_POLISH] = int(polished and not defective)
        tf[f_rate] = max(rates)
        aug = np.zeros((n3, n3))  # b0's column (n) is written with the other parts b0 enters
        aug[:n, :n], aug[:n, n + 1], aug[:n, n + 2] = a, bc, bs
        aug[n + 1, n + 2], aug[n + 2, n + 1] = -w, w
        tf[f_aug : f_aug + n3 * n3] = aug.ravel()
        modal_ok = bool(ns) and not defective
        return _Parts(slip, stuck, a_ss, a_sk, ainv, modal_ok, modal_ok and ns <= polish.MAX_POLISH)


@dataclass(frozen=True)
class _Parts:
    """What the parts of a mode's row that the constant force b0 enters are computed from."""

    slip: list[int]
    stuck: list[int]
    a_ss: np.ndarray | None
    a_sk: np.ndarray | None
    ainv: np.ndarray | None
    modal: bool  # the modal form is used (slipping states, not defective)
    polish: bool  # and its double-double polish


@dataclass(frozen=True)
class _Rows:
    """A mode's rows as filled for one b0 (the parts b0 enters are overwritten for another)."""

    tf: np.ndarray
    tc: np.ndarray
    ti: np.ndarray
    parts: _Parts


#: At most this many modes of a sweep's last value are filled before the next value's run.
PREFILL_MODES = 16

#: Mode rows by the exact bytes of what they come from besides b0 (see ``ModeTables._fill``).
_ROWS: OrderedDict[tuple, _Rows] = OrderedDict()
ROWS_CACHE_SIZE = 256


def _b0_parts(tf: np.ndarray, n: int, g: int, b0: np.ndarray, parts: _Parts) -> None:
    """Write the parts of a mode's float row that the constant force ``b0`` enters (not the augmented
    matrix's column): the stuck states' rates, the slipping states' force and the particular
    solution's slope, with its double-double low part."""
    from nsbench.integrators import _exact_layout as lay
    from nsbench.integrators import _exact_polish as polish

    _, _, _, _, f_b0s, f_p1, f_p1lo, f_b0k, _, _, _, _ = lay.f_offsets(n, g)
    slip, stuck = parts.slip, parts.stuck
    ns, nst = len(slip), len(stuck)
    tf[f_b0k : f_b0k + nst] = b0[stuck]
    if not parts.modal:
        return
    assert parts.a_ss is not None and parts.a_sk is not None and parts.ainv is not None
    tf[f_b0s : f_b0s + ns] = b0[slip]
    # slope of the particular solution, from the stuck blocks moving at v0
    drive = parts.a_sk @ b0[stuck] if nst else np.zeros(ns)
    p1 = -parts.ainv @ drive
    tf[f_p1 : f_p1 + ns] = p1
    if parts.polish:
        bh, bl = polish.product_dd(parts.a_sk, np.asarray(b0[stuck], float), -1.0)
        p1_lo = np.zeros(ns)
        polish.refine_linear(parts.a_ss, parts.ainv, bh, bl, p1.copy(), p1_lo, np.zeros(ns))
        tf[f_p1lo : f_p1lo + ns] = p1_lo


def closed_form_states(problem, mode, t0: float, y0, times) -> np.ndarray:
    """States of ``mode``'s closed-form flow from ``(t0, y0)`` at ``times`` (no guard stops it): ``(n, k)``."""
    from nsbench.integrators.base import ArcRequest

    times = np.asarray(times, dtype=float)
    integ = ExactIntegrator()
    integ.setup(problem)
    arc = integ.advance(
        ArcRequest(
            problem=problem,
            mode=tuple(mode),
            t0=float(t0),
            y0=np.asarray(y0, float),
            t_end=float(times.max()),
            guards=(),
            t_eval=times,
        )
    )
    return arc.y_eval


class ExactIntegrator(CompiledArcs):
    """Exact event times for linear problems: closed-form flow, curvature-bounded scan, Newton, double-double polish."""

    name = "exact"
    capabilities = Capabilities(
        event_location="exact-root",
        order=None,
        adaptive=False,
        needs_jacobian=False,
        supports_nonlinear=False,
        precision="double",
        step_option=None,
        reference_grade=True,
        checks_steps=True,
    )
    options = {
        "scan": Option(
            0.25, float, lower=0.0, upper=4.0, doc="scan step as a fraction of the shortest time scale of the mode"
        ),
        "max_scan": Option(1.0, float, lower=0.0, doc="longest scan step (time units)"),
    }
    counter_names = ("roots", "expm_fallback_arcs", "polished_events")

    def build_kernel(self, problem):
        from nsbench.integrators._exact_kernel import OPTIONS, exact_arc
        from nsbench.integrators._exact_layout import kernel_data
        from nsbench.model.kernel import ArcKernel, arc_table

        tables = ModeTables(problem)
        # The modes the last problem of this family visited are filled now: a sweep's next value
        # visits the same few, and its run then never leaves the compiled loop to have one filled
        # (each return costs a Python round trip and numba's dispatch). A mode filled ahead is
        # what its first visit would fill; the run is the same. Only a few: the modes filled ahead
        # are carried on too, and a system of many blocks may visit many modes, each a fill.
        family = (getattr(problem.law_module, "__name__", problem.law_module), tables.dims)  # picklable
        last = getattr(self, "_last_modes", None)
        if last is not None and last[0] == family and len(last[1]) <= PREFILL_MODES:
            for mode in last[1]:
                tables.add(np.array(mode, np.int64))
        self._last_modes = (family, tables.visited)
        return ArcKernel(
            arc_table(exact_arc, problem),
            kernel_data(tables.data),
            np.array([float(self.settings[name]) for name in OPTIONS]),
            self.counter_names,
            prepare_mode=lambda mode: kernel_data(tables.add(mode)),
            prepare_run=lambda k: kernel_data(tables.ensure_sections(k)),
            name=self.name,
        )
