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


@functools.lru_cache(maxsize=None)
def conditioning_of(problem: str, case: int, t_end: float = 300.0) -> float:
    """The bench's conditioning of a preset: the largest switching-time change per unit change of the
    start positions, on the reference flow (:func:`nsbench.bench.reference.conditioning`)."""
    from nsbench.bench.reference import conditioning

    p = nsbench.get_problem(problem, case=case)
    kappa, note = conditioning(
        p, nsbench.get_integrator("reference").config(), 0.0, t_end, nsbench.simulate(p, "reference", t_end).events
    )
    assert np.isfinite(kappa), note
    return kappa


def precision_bound(times, kappa: float, eps: float, steps: int = 1) -> float:
    """What the arithmetic allows between the event times of two solutions of a case, both rounded to double.

    One of them is (at least) ``eps``-accurate per step over ``steps`` steps, the other far more
    accurate. Each step's relative error of at most ``eps`` reaches the switching times amplified
    by at most the case's conditioning ``kappa`` (:func:`conditioning_of`; a perturbation at the
    start has the whole span to grow), and at worst the errors of all steps add up: ``kappa * eps
    * steps``. Rounding each of the two times to double adds half an ulp of the latest time each,
    and a rounding boundary between them one more ulp: ``2 ulp(max |t|)``.
    """
    return 2.0 * float(np.spacing(np.abs(np.asarray(times, dtype=float)).max())) + kappa * eps * steps


def same_sequence(a, b) -> bool:
    """Whether two event logs have the same ``(kind, block)`` sequence."""
    return (
        len(a) == len(b)
        and (a["kind"].to_numpy() == b["kind"].to_numpy()).all()
        and (a["block"].to_numpy() == b["block"].to_numpy()).all()
    )


def max_time_error(a, b) -> float:
    return float(np.max(np.abs(a["t"].to_numpy() - b["t"].to_numpy())))


@pytest.fixture
def case1():
    return nsbench.get_problem("two-dof", case=1)


@pytest.fixture
def case2():
    return nsbench.get_problem("two-dof", case=2)
