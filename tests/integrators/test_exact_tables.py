"""``exact``'s mode tables within a sweep: rows served from the per-process cache, modes filled ahead.

A sweep over a parameter the modes' matrices do not hold (a belt speed) fills the same
few modes at every value; the parts of a row the constant force does not enter are
copied from the first fill, and the modes the last value visited are filled before a
run. Both must give exactly what filling each mode afresh gives.
"""

from __future__ import annotations

import itertools
import pickle

import numpy as np
import pytest

import nsbench
from nsbench.bifurcation.sweep import SweepSpec, point_columns
from nsbench.integrators import exact, get_integrator

MODES = [np.array(m, np.int64) for m in itertools.product((-1, 0, 1), repeat=2)]


def _rows(problem):
    """Every mode of a two-block problem filled into fresh tables: ``mode -> (tf, tc, ti)`` rows."""
    tables = exact.ModeTables(problem)
    for mode in MODES:
        tables.add(mode)
    t = tables.data
    return {tuple(m): (t.tf[s].copy(), t.tc[s].copy(), t.ti[s].copy()) for s, m in enumerate(tables.visited)}


def _same_bits(a, b):
    return a.dtype == b.dtype and np.array_equal(a.view(np.uint8), b.view(np.uint8))


# v0 enters the constant force only (every row is served); F the harmonic forcing and c1 the
# matrices too (the rows of modes with a slipping block are not)
@pytest.mark.parametrize(
    "case, name, values, served_all",
    [
        (1, "v0", (0.07, 0.19), True),
        (2, "v0", (0.05, 0.3), True),
        (1, "F", (0.5, 2.0), False),
        (1, "c1", (0.05, 0.07), False),
    ],
)
def test_rows_served_from_the_cache_are_the_rows_filled_afresh(case, name, values, served_all):
    first, second = (nsbench.get_problem("two-dof", case=case, **{name: v}) for v in values)
    exact._ROWS.clear()
    exact._MODAL.clear()
    fresh = _rows(second)
    exact._ROWS.clear()
    _rows(first)  # the cache now holds the rows of the first value
    exact._MODAL.clear()  # nothing but the rows' cache is shared
    served = _rows(second)
    assert (len(exact._ROWS) == len(MODES)) == served_all  # one entry per mode: the second value's were served
    for mode, rows in fresh.items():
        assert all(_same_bits(a, b) for a, b in zip(rows, served[mode])), mode


def test_a_sweeps_next_value_runs_the_same_with_the_last_values_modes_filled_ahead():
    spec = SweepSpec(problem="two-dof", case=1, name="v0", start=0.05, stop=0.2, count=4, transient=200.0, record=20)
    warm = get_integrator("exact")
    point_columns(spec, 0, warm)
    visited = list(warm._last_modes[1])
    assert visited  # the first value's run filled its modes
    assert pickle.loads(pickle.dumps(warm)).name == "exact"  # what it carries to the next value pickles
    warm.setup(spec.problem_at(spec.values[1]))
    assert warm._last_modes[1][: len(visited)] == visited  # filled ahead, before the run
    for i in (1, 2, 3):
        got, want = point_columns(spec, i, warm), point_columns(spec, i, get_integrator("exact"))
        assert got.keys() == want.keys()
        for key in want:
            if key != "wall_time":
                assert _same_bits(np.asarray(got[key]), np.asarray(want[key])) or list(got[key]) == list(want[key]), key
