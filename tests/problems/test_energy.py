"""The energy balance holds along each integrator's trajectory, to its accuracy."""

from __future__ import annotations

import numpy as np
import pytest

import nsbench
from nsbench.problems.energy import energy_balance

GRID = np.linspace(0.0, 60.0, 6001)  # dt = 0.01: Simpson quadrature error ~1e-9


@pytest.mark.parametrize("case", [1, 2])
@pytest.mark.parametrize("name, options, tol", [
    ("exact", {}, 1e-8),
    ("scipy-dop853", {"rtol": 1e-11, "atol": 1e-13}, 1e-8),
    ("henon-rk4", {"h": 0.01}, 1e-7),
    ("scipy-rk45", {"rtol": 1e-6, "atol": 1e-9}, 1e-4),
])
def test_energy_balance_along_trajectory(case, name, options, tol):
    p = nsbench.get_problem("two-dof", case=case)
    res = nsbench.simulate(p, name, 60.0, options=options, t_eval=GRID)
    eb = energy_balance(res)
    scale = np.abs(eb["energy_change"]).max()
    assert scale > 0.5  # the check is not vacuous: energy changes by O(1)
    assert np.abs(eb["residual"]).max() <= tol * max(1.0, scale)


def test_energy_balance_on_cubic_case():
    p = nsbench.get_problem("two-dof", case=4)
    res = nsbench.simulate(p, "scipy-dop853", 60.0, options={"rtol": 1e-11, "atol": 1e-13}, t_eval=GRID)
    eb = energy_balance(res)
    assert np.abs(eb["residual"]).max() <= 1e-8


def test_energy_balance_detects_a_wrong_trajectory():
    # The trajectory of a problem with other friction levels, checked against the
    # work the claimed problem's friction would do: the residual must be large.
    wrong = nsbench.get_problem("two-dof", case=1, r_f=0.6)
    res = nsbench.simulate(wrong, "exact", 60.0, t_eval=GRID)
    claimed = nsbench.get_problem("two-dof", case=1)
    from dataclasses import replace

    eb = energy_balance(replace(res, problem=claimed))
    assert np.abs(eb["residual"]).max() > 1e-2
