"""The energy balance holds along each integrator's trajectory, to its accuracy."""

from __future__ import annotations

import numpy as np
import pytest

import nsbench
from nsbench.energy import energy_balance

GRID = np.linspace(0.0, 60.0, 6001)  # dt = 0.01: Simpson quadrature error ~1e-9


@pytest.mark.parametrize("case", [1, 2])
@pytest.mark.parametrize(
    "name, options, tol",
    [
        ("exact", {}, 1e-8),
        ("scipy-dop853", {"rtol": 1e-11, "atol": 1e-13}, 1e-8),
        ("henon-rk4", {"h": 0.01}, 1e-7),
        ("scipy-rk45", {"rtol": 1e-6, "atol": 1e-9}, 1e-4),
    ],
)
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


@pytest.mark.parametrize("params", [{"case": "leine"}, {"case": 2, "law": "stribeck", "fk": 0.4, "vs": 0.2, "cv": 0.1}])
def test_energy_balance_under_a_friction_law(params):
    # friction's power uses the law's slip force: -s S(s (v - v0)) v. The weakening law's power varies
    # faster than Coulomb's (S'' = 2 fs delta^2 / (1 + delta u)^3), so Simpson's rule needs dt = 0.0025
    # for 1e-9 (seen on Leine's preset: 3.1e-7, 2.7e-8, 1.6e-9 at dt = 0.01, 0.005, 0.0025: order 4)
    p = nsbench.get_problem("one-dof", **params)
    grid = np.linspace(0.0, 60.0, 24001)
    res = nsbench.simulate(p, "scipy-dop853", 60.0, options={"rtol": 1e-12, "atol": 1e-14}, t_eval=grid)
    eb = energy_balance(res)
    assert np.abs(eb["energy_change"]).max() > 0.1
    assert np.abs(eb["residual"]).max() <= 1e-8
