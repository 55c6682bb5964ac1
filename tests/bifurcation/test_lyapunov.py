"""Largest Lyapunov exponent of the mapping points: negative on a periodic case, positive on a chaotic one.

The periodic case (case 1, v0 = 0.1) is checked to be periodic independently
(its peaks repeat); the chaotic one is case 2 with F = 0.1417, near the
border-collision the paper names, found by exploring the F sweep: its
stroboscopic points never repeat and two integrators both find a positive
exponent.
"""

from __future__ import annotations

import numpy as np

import nsbench
from nsbench.bifurcation import detect
from nsbench.bifurcation.lyapunov import largest_exponent
from nsbench.sections import peaks, stroboscopic


def test_negative_exponent_on_a_periodic_case():
    p = nsbench.get_problem("two-dof", case=1, v0=0.1)
    sec = nsbench.simulate(p, "exact-jit", 1300.0, sections=[peaks(p)]).sections
    x1 = sec[sec["t"] >= 1000.0]["x1"].to_numpy()[:, None]
    assert detect.period_of(x1, 1e-8) > 0
    res = largest_exponent(p, "exact-jit", iterations=800)
    assert res.status == "success" and res.converged
    assert res.exponent < -0.05 and res.exponent < -10 * res.standard_error


def test_positive_exponent_on_a_chaotic_case():
    p = nsbench.get_problem("two-dof", case=2, F=0.1417)
    sec = nsbench.simulate(p, "exact-jit", 1000.0 + 2 * np.pi * 200, sections=[stroboscopic(p)]).sections
    pts = sec[sec["t"] >= 1000.0][["x1", "v1", "x2", "v2"]].to_numpy()
    assert detect.period_of(pts, 1e-6) == 0
    res = largest_exponent(p, "exact-jit", iterations=10000)
    assert res.status == "success" and res.converged
    assert res.exponent > 10 * res.standard_error > 0  # clearly positive, not a fluctuation
    other = largest_exponent(p, "henon-rk4-jit", options={"h": 0.01}, iterations=4000)
    assert other.exponent > 5 * other.standard_error > 0


def test_lyapunov_command(capsys):
    from nsbench.cli import main

    assert main(["lyapunov", "two-dof", "--case", "1", "--param", "v0=0.1", "--iterations", "200"]) == 0
    assert "largest Lyapunov exponent -" in capsys.readouterr().out
    assert main(["lyapunov", "two-dof", "--case", "1", "--integrator", "exact"]) == 2
