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
from nsbench.integrators._heyoka_model import Structure, _system, coefficient_values  # noqa: E402
from nsbench.problems.modes import STICK  # noqa: E402

RNG = np.random.default_rng(11)


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
    nb, n = st.n_blocks, st.n_mech
    w = problem.forcing_frequency
    for mode in problem.modes:
        pars = np.zeros(st.n_pars)
        pars[: len(coefficient_values(problem))] = coefficient_values(problem)
        for i, phase in enumerate(mode):
            pars[st.mode_offset + i] = 1.0 if phase == STICK else 0.0
            pars[st.mode_offset + nb + i] = float(phase)
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
