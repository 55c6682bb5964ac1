"""Units: Buckingham-pi groups and conversion of problems, event logs and trajectories.

A dimensional problem carries :class:`~nsbench.problems.parameters.Scales`
(length ``fr1/k1``, time ``sqrt(m1/k1)``, force ``fr1``); dividing by them gives the
dimensionless form of MODEL.md section 2.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import pandas as pd

from nsbench.errors import ConfigError
from nsbench.problems.parameters import (
    ONE_DOF_DIMENSIONAL,
    TABLE3_DIMENSIONAL_ONE_DOF,
    TABLE3_DIMENSIONAL_TWO_DOF,
    TWO_DOF_DIMENSIONAL,
    Scales,
    check_values,
    pi_groups_one_dof,
    pi_groups_two_dof,
)

if TYPE_CHECKING:  # pragma: no cover
    from nsbench.problems.oscillator import FrictionOscillator
    from nsbench.problems.base import HybridProblem

__all__ = ["pi_groups", "dimensionless_problem", "to_dimensionless", "to_dimensional", "Scales"]


def pi_groups(problem: str, **dimensional: float) -> dict[str, float]:
    """Dimensionless groups of a problem given dimensional parameters.

    Missing parameters take their Table 3 values.

    Examples
    --------
    >>> g = pi_groups("two-dof", m1=2, m2=1, c1=0.03, c2=0.03, k1=2, k2=1)
    >>> round(g["kappa"], 12), round(g["mu"], 12), round(g["c1"], 12)
    (0.5, 0.5, 0.015)
    """
    if problem == "two-dof":
        values = dict(TABLE3_DIMENSIONAL_TWO_DOF)
        values.update(check_values(problem, dimensional, TWO_DOF_DIMENSIONAL))
        return pi_groups_two_dof(**values)
    if problem == "one-dof":
        values = dict(TABLE3_DIMENSIONAL_ONE_DOF)
        values.update(check_values(problem, dimensional, ONE_DOF_DIMENSIONAL))
        return pi_groups_one_dof(**values)
    raise ConfigError(f"pi groups are defined for 'one-dof' and 'two-dof', not {problem!r}")


def dimensionless_problem(problem: "FrictionOscillator") -> "HybridProblem":
    """The dimensionless problem equivalent to ``problem`` (itself if already dimensionless)."""
    from nsbench.problems import get_problem

    if not problem.dimensional:
        return problem
    groups: dict[str, Any] = pi_groups(problem.name, **problem.parameters)
    return get_problem(problem.name, case=problem.case, **groups)


def _scale_frame(frame: pd.DataFrame, scales: Scales, power: int) -> pd.DataFrame:
    out = frame.copy()
    for col in out.columns:
        if col == "t":
            factor = scales.time
        elif len(col) > 1 and col[0] == "x" and col[1:].isdigit():
            factor = scales.length
        elif len(col) > 1 and col[0] == "v" and col[1:].isdigit():
            factor = scales.velocity
        else:
            continue
        out[col] = out[col] * factor**power
    return out


def to_dimensionless(frame: pd.DataFrame, scales: Scales) -> pd.DataFrame:
    """Convert an event log, section table or trajectory from problem units to dimensionless units."""
    return _scale_frame(frame, scales, -1)


def to_dimensional(frame: pd.DataFrame, scales: Scales) -> pd.DataFrame:
    """Convert a dimensionless event log, section table or trajectory to the units of ``scales``."""
    return _scale_frame(frame, scales, +1)
