"""Problems: the dry-friction oscillators of MODEL.md, built by name from the registry.

>>> from nsbench.problems import get_problem
>>> p = get_problem("two-dof", case=2)
>>> p.guards(p.initial_mode(0.0, p.initial_state()))  # doctest: +ELLIPSIS
(Guard(v1-v0, expected_sign=-1), Guard(v2-v0, expected_sign=-1))
"""

from __future__ import annotations

from typing import Any

from nsbench import registry
from nsbench.errors import ConfigError
from nsbench.problems.modes import (
    PHASE_NAMES,
    SLIP_NEG,
    SLIP_POS,
    STICK,
    Guard,
    Mode,
    Transition,
    mode_name,
)
from nsbench.problems.base import HybridProblem
from nsbench.problems.oscillator import FrictionOscillator
from nsbench.problems.parameters import Coefficients, Scales

__all__ = [
    "FrictionOscillator",
    "Guard",
    "Mode",
    "Transition",
    "Coefficients",
    "Scales",
    "STICK",
    "SLIP_POS",
    "SLIP_NEG",
    "PHASE_NAMES",
    "mode_name",
    "get_problem",
    "problem_from_config",
    "list_problems",
]


def get_problem(name: str, case: int | str | None = None, *, dimensional: bool = False, **params: Any) -> HybridProblem:
    """Build a registered problem by name.

    Parameters
    ----------
    name
        Registry name, e.g. ``'one-dof'`` or ``'two-dof'``.
    case
        Preset 1..4 (MODEL.md section 3); default 1.
    dimensional
        Whether ``params`` are dimensional (see the problem's factory).
    **params
        Parameter overrides.

    Raises
    ------
    ConfigError
        Unknown problem, case or parameter, a bad type (``name`` not a string,
        ``dimensional`` not a bool, a number too large for a double), or a
        nonphysical value.
    """
    if not isinstance(name, str):
        raise ConfigError(f"problem name must be a string (a registered problem), got {type(name).__name__} {name!r}")
    if not isinstance(dimensional, bool):
        raise ConfigError(f"dimensional = {dimensional!r} must be True or False")
    for key, value in params.items():
        if isinstance(value, int) and not isinstance(value, bool):
            try:
                float(value)
            except OverflowError:
                raise ConfigError(
                    f"parameter {key} = {str(value)[:20]}... is too large for a double (at most about 1.8e308)"
                ) from None
    factory = registry.load("problems", name)
    return factory(case=case, dimensional=dimensional, **params)


def problem_from_config(config: dict[str, Any]) -> HybridProblem:
    """Rebuild a problem from :meth:`FrictionOscillator.config`.

    Parameters go under ``params``; any other key is refused (a parameter put at
    the top level would otherwise be dropped without a word).
    """
    unknown = sorted(set(config) - {"name", "case", "dimensional", "params"})
    if unknown:
        raise ConfigError(
            f"problem config has unknown key(s) {', '.join(map(repr, unknown))}; allowed: "
            f"'name', 'case', 'dimensional', 'params' (parameters such as {unknown[0]!r} go "
            f"under 'params'): got {config!r}"
        )
    try:
        return get_problem(
            config["name"],
            case=config.get("case"),
            dimensional=bool(config.get("dimensional", False)),
            **dict(config.get("params", {})),
        )
    except KeyError as exc:
        raise ConfigError(f"problem config needs the key {exc.args[0]!r}: got {config!r}") from None


def list_problems() -> list[str]:
    """Names of the registered problems."""
    return registry.names("problems")
