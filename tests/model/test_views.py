"""The :class:`nsbench.model.native.Views` table: each slot is its array's address and shape.

The core's slots are written by one compiled call (``_fill_core``), the integrator's own in Python;
both must give what numpy itself reports (``ndarray.ctypes.data``, ``shape``), or the compiled
callbacks of a native run would read another array's memory.
"""

from __future__ import annotations

import math

import numpy as np

from nsbench.hybrid.run import _run_state
from nsbench.model import abi, native
from nsbench.model.kernel import section_bundle
from nsbench.model.records import Records
from nsbench.problems import get_problem
from nsbench.sections import StateSection


def _views(grid, sections, own):
    problem = get_problem("two-dof", case=1)
    st = _run_state(problem, problem.initial_state(), np.zeros(problem.mode_size, np.int64), 16)
    rec = Records(problem.n_states, problem.mode_size, grid)
    sec = section_bundle(sections, problem.n_states, 0.0, 3)
    lim = abi.RunLimits(10.0, 100, 100, 1e-9, -math.inf, -1, 0, 1e-14)
    return native.Views(rec, st, sec, lim, own), rec


def _expected(a):
    shape = a.shape + (0,) * (2 - a.ndim)
    return [a.ctypes.data, shape[0], shape[1]]


def test_every_slot_is_its_arrays_address_and_shape():
    sections = [StateSection("x1", (1.0, 0.0, 0.0, 0.0), 0.0, 1), StateSection("v2", (0.0, 0.0, 0.0, 1.0), 0.5, -1)]
    own = [np.zeros(7), np.zeros((3, 5), np.int64), np.zeros(2, np.int64)]
    views, rec = _views(np.linspace(0.0, 1.0, 11), sections, own)
    arrays = views.arrays()
    assert views.table.shape == (native.S_OWN + len(own), 3)
    for k, a in enumerate(arrays):
        assert views.table[k].tolist() == _expected(a), k
    # after a buffer was replaced (grown), the table follows it
    rec.grow_events(0)
    views.refresh()
    assert views.table[native.S_EVENTS].tolist() == _expected(rec.events[0])
    assert views.table[native.S_EVENTS + 3].tolist() == _expected(rec.events[3])


def test_a_run_without_sections_or_requested_states():
    views, _ = _views(np.empty(0), [], [])
    for k, a in enumerate(views.arrays()):
        assert views.table[k].tolist() == _expected(a), k
