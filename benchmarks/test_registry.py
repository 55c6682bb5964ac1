"""Every registered integrator on every benchmark problem, at its default options.

Each benchmark's ``extra_info`` holds the tidy row of the case, accuracy metrics
against the reference included (``switch_err_max``, ``switch_digits``,
``n_missed``, ``state_err_l2``, ...). Integrators that refuse a problem are skipped.
"""

from __future__ import annotations

import pytest

from nsbench.bench.pytest_bench import problem_params, registered_integrators


@pytest.mark.parametrize("integrator", registered_integrators())
@pytest.mark.parametrize("problem", problem_params())
def test_registry(nsbench_bench, problem, integrator):
    row = nsbench_bench(problem, integrator)
    assert row["status"] in ("success", "step budget exhausted", "event storm (Zeno)", "integrator failure")
