"""Nothing lost in the hybrid model: today's event logs, to the last bit.

``tests/data/event_logs_before_the_hybrid_model.csv.gz`` holds the event logs
of main before the problems became data and the core generic (f32c8b4): the
2-DOF cases 1-4, the 1-DOF case 1 and the five-block chain (cases 1-4) with
``exact``, ``reference``, ``ofapi`` and ``henon-rk4`` over tau in [0, 300],
times and states as the repr of the doubles. The same computation in the same
order gives the same doubles on a machine with IEEE arithmetic and the same
libm (numba compiles without fast-math, so no fused operation changes a bit),
whatever BLAS it has and whichever kernel BLAS picks (``OPENBLAS_CORETYPE``):
none of these integrators' arithmetic goes through BLAS. ``ofapi``'s rows were
computed again when its Chebyshev operators stopped being products in BLAS
(their doubles had depended on the kernel's order of summation; now each entry
is its exact value rounded once, :mod:`nsbench.integrators._chebyshev`): the
same events, times within 3.9e-12 of the old rows. ``exact`` and ``reference``
start from LAPACK's eigen-decomposition but polish it in double-double
(:mod:`nsbench.integrators._exact_polish`), which gave the same doubles on the
SkylakeX and Haswell kernels of OpenBLAS 0.3.31 (AMD EPYC, 2026-12-01).
"""

from __future__ import annotations

import functools
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import nsbench

LOGS = Path(__file__).parents[1] / "data" / "event_logs_before_the_hybrid_model.csv.gz"


@functools.lru_cache(maxsize=None)
def logs() -> pd.DataFrame:
    return pd.read_csv(LOGS, dtype={"state": str})


def _keys():
    keys = logs()[["problem", "case", "n", "integrator"]].drop_duplicates().itertuples(index=False)
    return [
        pytest.param(
            k.problem,
            int(k.case),
            int(k.n),
            k.integrator,
            id=f"{k.problem}{'-' + str(k.n) if k.problem == 'chain' else ''}-{k.case}-{k.integrator}",
        )
        for k in keys
    ]


@pytest.mark.parametrize("problem, case, n, integrator", _keys())
def test_the_event_log_is_unchanged_to_the_last_bit(problem, case, n, integrator):
    f = logs()
    old = f[(f["problem"] == problem) & (f["case"] == case) & (f["n"] == n) & (f["integrator"] == integrator)]
    params = {"n": n} if problem == "chain" else {}
    p = nsbench.get_problem(problem, case=case, **params)
    res = nsbench.simulate(p, integrator, 300.0)
    assert res.ok, res.message
    ev = res.events
    assert len(ev) == len(old)
    assert list(ev["kind"]) == list(old["kind"]) and list(ev["block"]) == list(old["block"])
    assert list(ev["mode"]) == list(old["mode"])
    assert np.array_equal(ev["t"].to_numpy(), old["t"].to_numpy(dtype=float))  # read back from repr: exact
    states = [" ".join(repr(float(v)) for v in row) for row in ev[list(p.state_names)].to_numpy()]
    assert states == list(old["state"])
