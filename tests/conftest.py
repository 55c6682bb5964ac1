"""Shared fixtures: problems and cached reference runs (the exact solver is deterministic)."""

from __future__ import annotations

import functools

import numpy as np
import pytest

import nsbench


@functools.lru_cache(maxsize=None)
def exact_events(problem: str, case: int, t_end: float = 300.0):
    """Event log of ``exact`` on a preset (cached across tests)."""
    p = nsbench.get_problem(problem, case=case)
    return nsbench.simulate(p, "exact", t_end).events


def same_sequence(a, b) -> bool:
    """Whether two event logs have the same ``(kind, block)`` sequence."""
    return (len(a) == len(b)
            and (a["kind"].to_numpy() == b["kind"].to_numpy()).all()
            and (a["block"].to_numpy() == b["block"].to_numpy()).all())


def max_time_error(a, b) -> float:
    return float(np.max(np.abs(a["t"].to_numpy() - b["t"].to_numpy())))


@pytest.fixture
def case1():
    return nsbench.get_problem("two-dof", case=1)


@pytest.fixture
def case2():
    return nsbench.get_problem("two-dof", case=2)
