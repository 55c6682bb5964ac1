"""Dimensional problems: Config 1 and Config 2 of MODEL.md give the same dimensionless events."""

from __future__ import annotations

import numpy as np
import pytest

import nsbench
from nsbench.units import dimensionless_problem, to_dimensional, to_dimensionless
from tests.conftest import same_sequence

CONFIG1 = dict(m1=2, m2=1, c1=0.03, c2=0.03, k1=2, k2=1, fr1=2.4, fr2=2.4, fs1=2, fs2=2, v0=0.2)
CONFIG2 = dict(m1=2, m2=1, c1=0.09, c2=0.09, k1=18, k2=9, fr1=7.2, fr2=7.2, fs1=6, fs2=6, v0=0.2)


@pytest.mark.parametrize("name, options", [("exact", {}), ("scipy-dop853", {"rtol": 1e-12, "atol": 1e-13})])
def test_config1_config2_same_dimensionless_event_times(name, options):
    runs = []
    for cfg in (CONFIG1, CONFIG2):
        p = nsbench.get_problem("two-dof", case=1, dimensional=True, **cfg)
        t_end = 300.0 * p.scales.time  # tau in [0, 300]
        res = nsbench.simulate(p, name, t_end, options=options)
        assert res.ok
        runs.append(res.dimensionless())
    a, b = runs[0].events, runs[1].events
    assert len(a) > 20
    assert same_sequence(a, b)
    tol = 1e-9 if name == "exact" else 1e-7
    assert np.max(np.abs(a["t"].to_numpy() - b["t"].to_numpy())) <= tol
    np.testing.assert_allclose(a[["x1", "x2"]].to_numpy(), b[["x1", "x2"]].to_numpy(), atol=tol)


def test_config2_time_scale_is_one_third():
    p = nsbench.get_problem("two-dof", case=1, dimensional=True, **CONFIG2)
    assert p.scales.time == pytest.approx(1 / 3)
    assert p.scales.length == pytest.approx(7.2 / 18)


def test_dimensional_run_equals_dimensionless_run():
    dim = nsbench.get_problem(
        "two-dof",
        case=2,
        dimensional=True,
        m1=2.0,
        k1=3.0,
        fr1=1.5,
        fr2=1.5,
        fs1=1.2,
        fs2=1.2,
        v0=0.1,
        w=0.8,
        F=0.5,
        c1=0.1,
        c2=0.1,
        k2=2.0,
        m2=1.0,
    )
    nondim = dimensionless_problem(dim)
    assert not nondim.dimensional
    t_end_tau = 150.0
    a = nsbench.simulate(dim, "exact", t_end_tau * dim.scales.time).dimensionless().events
    b = nsbench.simulate(nondim, "exact", t_end_tau).events
    assert same_sequence(a, b)
    assert np.max(np.abs(a["t"] - b["t"])) < 1e-10


def test_frame_conversion_round_trip(case1):
    p = nsbench.get_problem("two-dof", case=1, dimensional=True, **CONFIG2)
    ev = nsbench.simulate(p, "exact", 20.0).events
    back = to_dimensional(to_dimensionless(ev, p.scales), p.scales)
    np.testing.assert_allclose(back[["t", "x1", "v1"]].to_numpy(), ev[["t", "x1", "v1"]].to_numpy(), rtol=1e-15)
    assert (back["kind"] == ev["kind"]).all()
