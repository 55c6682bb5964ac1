"""heyoka's expressions of the friction family against the compiled law, the one written form of the field.

The heyoka integrators cannot call numba code: they integrate an expression system
(:func:`nsbench.integrators._heyoka_model._system`) with the mode, the guards'
activation and the sections in runtime parameters. Here those expressions are
compiled with ``heyoka.cfunc`` and evaluated at random states, times and modes,
next to the law (``problem.rhs``, ``Guard.value``). Both are a few operations in
double on values of order one, so they agree to a few ulps: bound 1e-14 relative.
"""

from __future__ import annotations

import numpy as np
import pytest

hy = pytest.importorskip("heyoka")

import nsbench  # noqa: E402
from nsbench.integrators._heyoka_model import GUARD_SLOT, VELOCITY_OR_UPPER, Structure, _system  # noqa: E402
from nsbench.integrators._heyoka_model import coefficient_values, native_guards  # noqa: E402
from nsbench.integrators._heyoka_native import event_name  # noqa: E402
from nsbench.problems.modes import STICK  # noqa: E402

RNG = np.random.default_rng(11)


def _mode_pars(problem, st, mode) -> np.ndarray:
    """The runtime parameters of ``mode``: the coefficients, each block's stick flag and slip sign; every guard
    inactive (the caller switches on the mode's guards)."""
    pars = np.zeros(st.n_pars)
    pars[: len(coefficient_values(problem))] = coefficient_values(problem)
    for i, phase in enumerate(mode):
        pars[st.mode_offset + i] = 1.0 if phase == STICK else 0.0
        pars[st.mode_offset + st.n_blocks + i] = float(phase)
    return pars


@pytest.mark.parametrize(
    "name, params",
    [
        ("two-dof", {"case": 4}),
        ("two-dof", {"case": 1}),
        ("one-dof", {"case": 2}),
        ("chain", {"case": 4, "n": 3}),
        ("one-dof", {"case": "leine"}),
        ("two-dof", {"case": 2, "law": "stribeck", "fk": 0.5, "vs": 0.2, "cv": 0.1}),
        ("chain", {"case": 4, "n": 3, "law": "weakening", "delta": 1.5}),
    ],
)
def test_heyoka_field_and_guards_are_the_law(name, params):
    problem = nsbench.get_problem(name, **params)
    st = Structure.of(problem, 0)
    system, guards, _ = _system(st)
    variables = [lhs for lhs, _ in system]
    field = hy.cfunc([rhs for _, rhs in system], variables)
    guard_fn = hy.cfunc(guards, variables)
    n = st.n_mech
    w = problem.forcing_frequency
    for mode in problem.modes:
        pars = _mode_pars(problem, st, mode)
        for guard in problem.guards(mode):  # active, expected sign +1: the bare guard value
            pars[st.guard_par(guard)] = 1.0
            pars[st.guard_par(guard) + 1] = 1.0
        for _ in range(3):
            y, t = RNG.normal(size=n) * 0.7, float(RNG.uniform(0, 20))
            if not problem.law_spec.is_coulomb:  # slip speeds s (v - v0) >= 0, as while a phase holds
                for i, phase in enumerate(mode):
                    if phase != STICK:
                        y[2 * i + 1] = problem.v0 + phase * abs(y[2 * i + 1])
            inputs = np.concatenate([y, [np.cos(w * t), np.sin(w * t)]]) if st.forced else y
            got = field(inputs, pars=pars[: st.guard_offset])  # the field reads the mode, not the guards
            np.testing.assert_allclose(got[:n], problem.rhs(mode, t, y), rtol=1e-14, atol=1e-14)
            if st.forced:
                np.testing.assert_allclose(got[n:], [-w * inputs[n + 1], w * inputs[n]], rtol=1e-14, atol=1e-14)
            values = guard_fn(inputs, pars=pars)
            for guard in problem.guards(mode):
                slot = (st.guard_par(guard) - st.guard_offset) // 2
                assert values[slot] == pytest.approx(guard.value(t, y), rel=1e-14, abs=1e-14)


@pytest.mark.parametrize(
    "name, params",
    [
        ("two-dof", {"case": 1}),
        ("one-dof", {"case": 2}),
        ("chain", {"case": 4, "n": 3}),
        ("two-dof", {"case": 2, "law": "stribeck", "fk": 0.5, "vs": 0.2, "cv": 0.1}),
    ],
)
def test_native_events_are_the_active_guards_bit_for_bit(name, params):
    """The whole-run integrators' two events per block (``native_guards``: the velocity guard and the upper limit
    in one) equal, in every mode, the active guard's own event of the per-arc model exactly (``0 * g`` and the
    constant 0 add nothing), and the constant 1 where that block has neither; the expected signs are the
    law's (``guards_of``), as the run writes them."""
    problem = nsbench.get_problem(name, **params)
    st = Structure.of(problem, 0)
    system, guards, _ = _system(st)
    _, events, _ = native_guards(st)
    assert [(kind, block) for _, kind, block in events] == [
        (k, b) for b in range(st.n_blocks) for k in (VELOCITY_OR_UPPER, GUARD_SLOT["lower"])
    ]
    variables = [lhs for lhs, _ in system]
    separate = hy.cfunc(guards, variables)
    merged = hy.cfunc([e for e, _, _ in events], variables)
    nb, n = st.n_blocks, st.n_mech
    for mode in problem.modes:
        pars = _mode_pars(problem, st, mode)
        active = {}
        for guard in problem.guards(mode):
            pars[st.guard_par(guard)] = 1.0
            pars[st.guard_par(guard) + 1] = float(guard.expected_sign)
            active[(guard.block - 1, GUARD_SLOT[guard.kind])] = True
        for _ in range(3):
            y = RNG.normal(size=n) * 0.7
            inputs = np.concatenate([y, [0.3, 0.9]]) if st.forced else y
            each, both = separate(inputs, pars=pars), merged(inputs, pars=pars)
            for b in range(nb):
                v, u, low = (each[len(GUARD_SLOT) * b + s] for s in range(3))
                assert not (active.get((b, 0)) and active.get((b, 1)))  # never both: what the merge relies on
                want = v if active.get((b, 0)) else u if active.get((b, 1)) else 1.0
                assert both[2 * b] == want, (mode, b)
                assert both[2 * b + 1] == low, (mode, b)


def test_a_bad_event_is_named():
    assert event_name((GUARD_SLOT["lower"] + 1) + (len(GUARD_SLOT) + 1) * 1) == "the lower guard of block 2"
    assert event_name(VELOCITY_OR_UPPER + 1) == "the velocity or upper guard of block 1"
