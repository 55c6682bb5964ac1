"""``den-hartog``: the forced Coulomb oscillator against Den Hartog's closed-form non-stop motion."""

from __future__ import annotations

import math

import numpy as np
import pytest

import nsbench
from nsbench.errors import ConfigError
from nsbench.problems.den_hartog import problem_steady_state, steady_state, stop_boundary
from nsbench.testing import parametrize_with_checks
from tests.testing.test_conformance import BUILTINS

#: exact's event times carry a double-double polish; over 48 reversals its error stays near 1e-14. 1e-10 is
#: the issue's bound.
BOUND = 1e-10


def den_hartog_undamped(r: float, friction: float) -> float:
    """Den Hartog's amplitude ratio ``X / (F / k)`` without viscous damping (his 1931 formula, written out):
    ``sqrt(1 / (1 - r^2)^2 - (fs / F)^2 U^2)`` with ``U = sin(pi / r) / (r (1 + cos(pi / r)))``."""
    u = math.sin(math.pi / r) / (r * (1.0 + math.cos(math.pi / r)))
    return math.sqrt(1.0 / (1.0 - r * r) ** 2 - (friction * u) ** 2)


@pytest.mark.parametrize("r, friction", [(0.6, 0.1), (0.6, 0.3), (1.5, 0.3), (2.0, 0.5), (3.0, 0.5)])
def test_the_undamped_amplitude_is_den_hartogs(r, friction):
    ss = steady_state(m=1.0, c=0.0, k=4.0, fs=4.0 * friction, fr=4.0 * friction, F=4.0, w=2.0 * r)
    assert ss is not None
    assert ss.amplitude == pytest.approx(den_hartog_undamped(r, friction), rel=1e-12)  # F / k = 1


@pytest.mark.parametrize("integrator", ["exact", "reference"])
def test_the_run_is_den_hartogs_periodic_motion(integrator):
    p = nsbench.get_problem("den-hartog")
    ss = problem_steady_state(p)
    assert ss is not None and ss.non_stop
    run = nsbench.simulate(p, integrator, 100.0, t_eval=np.linspace(0.0, 100.0, 401))
    ev = run.events
    half = math.pi / p.parameters["w"]
    first = ss.reversal_time % half  # the reversals are t_r + j pi / w, alternately at X and -X
    assert set(ev["kind"]) == {"reverse"} and len(ev) == math.floor((100.0 - first) / half) + 1
    j = np.round((ev["t"].to_numpy() - ss.reversal_time) / half)
    assert np.abs(ev["t"].to_numpy() - (ss.reversal_time + j * half)).max() <= BOUND
    assert np.abs(np.abs(ev["x1"].to_numpy()) - ss.amplitude).max() <= BOUND
    traj = run.trajectory
    closed = ss.state(traj["t"].to_numpy())
    assert np.abs(traj[["x1", "v1"]].to_numpy().T - closed).max() <= BOUND


def test_stops_appear_beyond_the_boundary():
    c, w = 0.1, 0.6
    fs_stop = stop_boundary(m=1.0, c=c, k=1.0, F=1.0, w=w)
    # with fr = fs the boundary is where the push beyond static friction at a reversal vanishes
    assert steady_state(1.0, c, 1.0, fs_stop, fs_stop, 1.0, w).push == pytest.approx(0.0, abs=1e-10)
    below = steady_state(1.0, c, 1.0, fs_stop * (1 - 1e-3), fs_stop * (1 - 1e-3), 1.0, w)
    x0, v0 = below.state(0.0)
    kinds = {}
    for factor in (1 - 1e-3, 1 + 1e-3):
        p = nsbench.get_problem("den-hartog", c=c, w=w, fs=fs_stop * factor, x1_0=x0, v1_0=v0)
        kinds[factor] = set(nsbench.simulate(p, "exact", 200.0).events["kind"])
    assert kinds[1 - 1e-3] == {"reverse"}
    assert kinds[1 + 1e-3] == {"stick", "slip"}


def test_static_friction_above_kinetic_moves_the_boundary_not_the_motion():
    a = steady_state(1.0, 0.1, 1.0, 0.3, 0.3, 1.0, 1.5)
    b = steady_state(1.0, 0.1, 1.0, 0.3, 0.6, 1.0, 1.5)
    assert a is not None and b is not None
    assert (a.amplitude, a.reversal_time) == (b.amplitude, b.reversal_time) and b.push < a.push


def test_the_factory_refuses_a_default_start_without_non_stop_motion():
    with pytest.raises(ConfigError, match="give the start x1_0 and v1_0"):
        nsbench.get_problem("den-hartog", fs=0.9)
    p = nsbench.get_problem("den-hartog", fs=0.9, x1_0=0.5, v1_0=0.0)
    assert p.parameters["fr"] == 0.9 and p.v0 == 0.0
    with pytest.raises(ConfigError, match="kinetic friction"):
        nsbench.get_problem("den-hartog", fs=0.5, fr=0.4)
    with pytest.raises(ConfigError, match="no cases"):
        nsbench.get_problem("den-hartog", case=1.5)


@parametrize_with_checks(
    ["exact", "reference", "henon-rk4", "scipy-radau", "heyoka", "cvode-bdf"], problem="den-hartog"
)
def test_conformance_on_den_hartogs_oscillator(integrator, check):
    check(integrator)


@pytest.mark.slow
@parametrize_with_checks(BUILTINS, problem="den-hartog")
def test_builtin_conformance_on_den_hartogs_oscillator(integrator, check):
    """Every built-in integrator: runs the checks, or is refused at setup with its reason."""
    check(integrator)
