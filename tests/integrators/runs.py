"""Runs shared by several test modules (cached: every integrator here is deterministic)."""

from __future__ import annotations

import functools

import nsbench


@functools.lru_cache(maxsize=None)
def two_dof_run(name: str, case: int, t_end: float = 300.0, options: tuple = ()):
    """``nsbench.simulate`` of the standard 2-DOF run; ``options`` as a sorted tuple of pairs."""
    p = nsbench.get_problem("two-dof", case=case)
    return nsbench.simulate(p, name, t_end, options=dict(options) or None)
