"""The start state is a parameter of every problem, and a run starts from it.

The belt oscillators start at rest at the origin by default, but ``x{i}_0`` and
``v{i}_0`` move them anywhere; the other problems name their start state
(``x0 v0``, ``x1_0 v1_0``, ``x1_0 x2_0 x3_0``, ``x0 y0 px0 py0``). A run from a
start other than rest is checked against ``exact-mp`` (the closed form in 40
digits, built from the problem's coefficients by its own code), so the start
travels through ``exact``'s arcs and its mode rule, not only through
``initial_state``.
"""

from __future__ import annotations

import numpy as np
import pytest

import nsbench

#: One start per problem, every component away from its default.
STARTS = [
    ("two-dof", {"case": 2}, {"x1_0": 0.3, "v1_0": -0.2, "x2_0": 0.1, "v2_0": 0.05}),
    ("one-dof", {"case": 1}, {"x1_0": -0.4, "v1_0": 0.7}),
    ("chain", {"case": 1, "n": 3}, {"x2_0": 0.4, "v3_0": 0.1}),
    ("block-on-ground", {}, {"x1_0": -5.0, "v1_0": -1.0}),
    ("bouncing-ball", {}, {"x0": 0.5, "v0": 2.0}),
    ("impact-oscillator", {}, {"x0": -0.3, "v0": 0.4}),
    ("relay-feedback", {}, {"x1_0": 0.5, "x2_0": -0.2, "x3_0": 0.3}),
    ("henon-heiles", {}, {"x0": 0.1, "y0": 0.05, "px0": 0.2, "py0": -0.1}),
]


def _expected(name, preset, start):
    """The default start of the problem with the named components replaced."""
    y = nsbench.get_problem(name, **preset).initial_state()
    names = list(nsbench.get_problem(name, **preset).state_names)
    for key, value in start.items():
        # x{i}_0 / v{i}_0 name the state x{i} / v{i}; x0 / px0 ... name x / px
        y[names.index(key[:-2] if key.endswith("_0") else key[:-1])] = value
    return y


@pytest.mark.parametrize("name, preset, start", STARTS, ids=[s[0] for s in STARTS])
def test_the_start_state_is_a_parameter_and_the_run_starts_there(name, preset, start):
    p = nsbench.get_problem(name, **preset, **start)
    np.testing.assert_array_equal(p.initial_state(), _expected(name, preset, start))
    res = nsbench.simulate(p, "henon-rk4", 0.5, t_eval=[0.0])
    assert res.ok, res.message
    np.testing.assert_array_equal(np.asarray(res.trajectory[list(p.state_names)].iloc[0]), p.initial_state())


@pytest.mark.parametrize(
    "name, preset, start",
    [s for s in STARTS if s[0] in ("two-dof", "one-dof", "chain")],
    ids=["two-dof", "one-dof", "chain"],
)
def test_exact_from_a_moving_start_meets_the_closed_form_in_40_digits(name, preset, start):
    p = nsbench.get_problem(name, **preset, **start)
    got = nsbench.simulate(p, "exact", 50.0).events
    want = nsbench.simulate(p, "exact-mp", 50.0).events
    assert len(got) >= 5 and list(got["kind"]) == list(want["kind"]) and list(got["block"]) == list(want["block"])
    # exact against exact-mp: 6e-14 over [0, 300] from rest (docs/core.md); a start off rest changes no arithmetic
    assert np.abs(got["t"].to_numpy() - want["t"].to_numpy()).max() <= 1e-12
