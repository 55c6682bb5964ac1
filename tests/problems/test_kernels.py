"""The compiled kernels agree with the reference (numpy) implementation of the model."""

from __future__ import annotations

import numpy as np
import pytest

import nsbench
from nsbench.problems import kernels

RNG = np.random.default_rng(7)


@pytest.mark.parametrize("name, case", [("two-dof", 4), ("two-dof", 2), ("one-dof", 4), ("one-dof", 1)])
def test_kernels_match_the_model(name, case):
    problem = nsbench.get_problem(name, case=case, v0=0.13)
    p = kernels.pack(problem)
    n = problem.n_states
    out = np.empty(n)
    jac = np.empty((n, n))
    for mode in problem.modes:
        m = kernels.mode_array(mode)
        kinds, blocks, _ = kernels.guard_codes(problem.guards(mode))
        for _ in range(4):
            y, t = RNG.normal(size=n) * 0.7, RNG.uniform(0, 20)
            kernels.rhs(p, m, t, y, out)
            np.testing.assert_allclose(out, problem.rhs(mode, t, y), rtol=1e-14, atol=1e-15)
            kernels.jacobian(p, m, t, y, jac)
            np.testing.assert_allclose(jac, problem.jacobian(mode, t, y), rtol=1e-14, atol=1e-15)
            dy = problem.rhs(mode, t, y)
            for g, kind, block in zip(problem.guards(mode), kinds, blocks):
                assert kernels.guard_value(p, kind, block, t, y) == pytest.approx(g.value(t, y), rel=1e-14, abs=1e-15)
                assert kernels.guard_rate(p, kind, block, t, y, dy) == pytest.approx(
                    g.rate(t, y, dy), rel=1e-13, abs=1e-14)
    assert kernels.v0_of(p) == problem.v0


def test_the_cache_guard_sees_every_import_of_a_compiled_file():
    """Consecutive one-line imports each count: the hybrid loop holds the arc kernels' machine code,
    so a change to any of them must drop the loop's numba cache (the guard missed every other one)."""
    text = ("from nsbench.hybrid.clock import monotonic_ns\n"
            "from nsbench.hybrid.rules import (\n    settle,\n    transition,\n)\n"
            "from nsbench.integrators._exact_kernel import exact_arc\n"
            "from nsbench.integrators._henon_kernel import henon_arc\n"
            "import nsbench.integrators._picard_arc\n")
    found = kernels._IMPORTS.findall(text)
    modules = [frm or plain for frm, _, _, plain in found]
    assert modules == ["nsbench.hybrid.clock", "nsbench.hybrid.rules", "nsbench.integrators._exact_kernel",
                       "nsbench.integrators._henon_kernel", "nsbench.integrators._picard_arc"]
    assert [g or n for _, g, n, _ in found][:2] == ["monotonic_ns", "\n    settle,\n    transition,\n"]
