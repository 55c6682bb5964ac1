"""The conformance check of a problem, built-in or plug-in: its config rebuilds it, and what it declares
of its states holds on its field.

Every path that moves a problem between processes or files (bench workers, stored cases and
references, resumed runs, sweeps) carries :meth:`~nsbench.problems.base.HybridProblem.config`
and rebuilds the problem with :func:`nsbench.problems.problem_from_config`. A problem whose
config loses something (a named case, an override) is rebuilt as another problem under the same
label, and nothing downstream can tell. :func:`config_round_trip` checks, at every case the
problem names (:attr:`~nsbench.problems.base.HybridProblem.cases`), in each unit system its
factory accepts, and with a few parameter overrides, that the rebuilt problem has the same
parameter vector (``packed``, bit for bit), start state and start mode, and that its config is
JSON text and comes back unchanged. :func:`rates_failure` checks a problem's declared
``position_rates`` (which a ``peaks`` section reads without running the field) against the field.
"""

from __future__ import annotations

import json
import math
from typing import Any

import numpy as np

from nsbench.errors import ConfigError

#: The factor each override multiplies a parameter by (one parameter at a time), and how many
#: parameters are overridden per case: a value the factory refuses is left out.
OVERRIDE_FACTOR = 1.25
OVERRIDES = 3


def _differences(problem, again) -> list[str]:
    """What ``again`` (the problem rebuilt from ``problem.config()``) does not share with ``problem``."""
    out = []
    if again.name != problem.name:
        out.append(f"name {again.name!r}")
    packed, packed_again = np.asarray(problem.packed, float), np.asarray(again.packed, float)
    # NaN slots equal (a law may mark an entry unused or singular with NaN: the woodpecker's impulse matrices)
    if packed.shape != packed_again.shape or not np.array_equal(packed, packed_again, equal_nan=True):
        where = (
            "shape"
            if packed.shape != packed_again.shape
            else f"{int(np.sum(~((packed == packed_again) | (np.isnan(packed) & np.isnan(packed_again)))))}"
            f" of {packed.size} entries"
        )
        out.append(f"parameter vector ({where} differ)")
    y0, y0_again = np.asarray(problem.initial_state(), float), np.asarray(again.initial_state(), float)
    if y0.shape != y0_again.shape or not np.array_equal(y0, y0_again):
        out.append(f"start state {y0_again.tolist()} for {y0.tolist()}")
    elif problem.initial_mode(0.0, y0) != again.initial_mode(0.0, y0):
        out.append("start mode")
    return out


def round_trip_failure(problem) -> str | None:
    """Why ``problem_from_config(problem.config())`` (through JSON text) is not ``problem``, or ``None``."""
    from nsbench.problems import problem_from_config

    config = problem.config()
    try:
        text = json.dumps(config)
    except (TypeError, ValueError) as exc:
        return f"{problem!r}: config() {config!r} is not JSON ({exc})"
    try:
        again = problem_from_config(json.loads(text))
    except ConfigError as exc:
        return f"{problem!r}: its config {config!r} is refused: {exc}"
    lost = _differences(problem, again)
    if lost:
        return f"{problem!r}: problem_from_config({config!r}) differs in its {', '.join(lost)}"
    if again.config() != json.loads(text):
        return f"{problem!r}: config() {config!r} comes back as {again.config()!r}"
    return None


def _numbers(problem, shared: dict[str, Any]) -> list[str]:
    """Up to :data:`OVERRIDES` parameter names with finite non-zero values the user did not give."""
    names = []
    for name, value in problem.parameters.items():
        if name in shared or isinstance(value, bool) or not isinstance(value, (int, float)):
            continue
        if isinstance(value, float) and math.isfinite(value) and value != 0.0:
            names.append(name)
    return names[:OVERRIDES]


def variants(name: str, shared: dict[str, Any] | None = None) -> list[Any]:
    """The problems the round trip is checked on: ``name`` with the parameters ``shared``, at its default
    and every case it names, dimensionless and dimensional where the factory accepts both, and each of
    those with a few parameters overridden (:data:`OVERRIDES`, by :data:`OVERRIDE_FACTOR`).

    Raises
    ------
    ConfigError
        The problem as given (default case, default units) is refused.
    """
    from nsbench.problems import get_problem

    shared = dict(shared or {})
    shared.pop("case", None)
    first = get_problem(name, **shared)  # a bad problem: the caller's error, raised here
    out = [first]
    for case in (None, *first.cases):
        for dimensional in (False, True):
            try:
                base = get_problem(name, case=case, dimensional=dimensional, **shared)
            except ConfigError:  # a case that takes no dimensional form, or shared values of the other units
                continue
            out.append(base)
            for param in _numbers(base, shared):
                try:
                    out.append(
                        get_problem(
                            name,
                            case=case,
                            dimensional=dimensional,
                            **{**shared, param: base.parameters[param] * OVERRIDE_FACTOR},
                        )
                    )
                except ConfigError:  # a value the factory refuses
                    continue
    return out


def config_round_trip(name: str, shared: dict[str, Any] | None = None) -> list[str]:
    """Every way the configs of :func:`variants` fail to rebuild their problem (empty: none)."""
    failures = []
    for problem in variants(name, shared):
        why = round_trip_failure(problem)
        if why is not None:
            failures.append(why)
    return failures


def rates_failure(problem) -> str | None:
    """Why ``problem``'s declared ``position_rates`` disagree with its field (``None``: they agree, or it
    declares none).

    The field's answer is :func:`nsbench.sections.rate_on_field` for every state: a declared pair must
    be confirmed there, and a pair the field confirms must be declared (else a ``peaks`` section
    would miss a position the field has).
    """
    from nsbench.sections import rate_on_field

    declared = getattr(problem, "position_rates", None)
    if declared is None:
        return None
    names = tuple(problem.state_names)
    unknown = sorted((set(declared) | set(declared.values())) - set(names))
    if unknown:
        return f"{problem.name}: position_rates name {', '.join(unknown)}, not states ({', '.join(names)})"
    found = {n: r for n in names if (r := rate_on_field(problem, n)) is not None}
    if found != dict(declared):
        return f"{problem.name}: position_rates declares {dict(declared)}, its field gives {found}"
    return None


def problem_failures(name: str, shared: dict[str, Any] | None = None) -> list[str]:
    """Every variant whose config does not rebuild it (:func:`config_round_trip`) or whose declared
    ``position_rates`` its field contradicts (:func:`rates_failure`); empty: none."""
    failures = []
    for variant in variants(name, shared):  # built once: a variant is both rebuilt and its rates checked
        failures += [why for why in (round_trip_failure(variant), rates_failure(variant)) if why is not None]
    return failures


def check_problem(problem: str | dict[str, Any]) -> None:
    """Check that a registered problem (built-in or plug-in) is rebuilt whole from its config, and that
    its declared ``position_rates`` hold on its field (:func:`rates_failure`).

    Parameters
    ----------
    problem
        A registry name, or a dict of the name and parameters every variant shares
        (``{"name": "chain", "n": 5}``).

    Raises
    ------
    AssertionError
        Listing every variant whose config does not rebuild it (:func:`config_round_trip`) or whose
        declared rates its field contradicts.
    ConfigError
        The problem as given is refused.
    """
    if isinstance(problem, str):
        name, shared = problem, {}
    elif isinstance(problem, dict) and isinstance(problem.get("name"), str):
        name, shared = problem["name"], {k: v for k, v in problem.items() if k != "name"}
    else:
        raise ConfigError(f"a problem to check is a registry name or a dict with 'name', got {problem!r}")
    failures = problem_failures(name, shared)
    if failures:
        raise AssertionError(f"{len(failures)} variant(s) of {name} fail the problem checks: " + "; ".join(failures))
