"""The bifurcation target of a suite, as written (``[[bifurcation_targets]]``): checked at load.

The specification only: what a target is and how a suite file's table becomes one
(:func:`parse_targets`). Locating the targets, their rows and figures are in
:mod:`nsbench.bench.targets`, which the suite file's loader need not import.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from typing import Any

from nsbench.bench.keys import got as _got
from nsbench.bench.keys import problem_label, stable_key
from nsbench.errors import ConfigError

#: Keys of one ``[[bifurcation_targets]]`` table.
TARGET_KEYS = {
    "name",
    "problem",
    "case",
    "params",
    "dimensional",
    "param",
    "origin",
    "bracket",
    "kind",
    "periods",
    "max_probes",
    "xtol",
    "exclude",
}
#: Defaults of the location settings (per target in the TOML).
DEFAULT_PERIODS = 8
DEFAULT_MAX_PROBES = 40
DEFAULT_XTOL = 1e-10
#: Tolerance of the reference location (``locate_target``'s bisection).
REFERENCE_XTOL = 1e-11


def _known_kinds() -> tuple[str, ...]:
    from nsbench.periodic.bifurcations import CATEGORY

    return tuple(CATEGORY)


# ---------------------------------------------------------------------- the target
@dataclass(frozen=True)
class BifurcationTarget:
    """One ``[[bifurcation_targets]]`` entry, validated (see :func:`parse_target`)."""

    name: str
    problem: str
    case: Any
    param: str
    origin: float
    low: float
    high: float
    params: dict[str, float] = field(default_factory=dict)
    dimensional: bool = False
    kind: str | None = None
    periods: int = DEFAULT_PERIODS
    max_probes: int = DEFAULT_MAX_PROBES
    xtol: float = DEFAULT_XTOL
    exclude: tuple[str, ...] = ()

    def config_at(self, value: float) -> dict[str, Any]:
        """The problem config (``problem_from_config``) with ``param = value``."""
        return {
            "name": self.problem,
            "case": self.case,
            "dimensional": self.dimensional,
            "params": {**self.params, self.param: float(value)},
        }

    def problem_at(self, value: float):
        from nsbench.problems import problem_from_config

        return problem_from_config(self.config_at(value))

    @property
    def near_is_low(self) -> bool:
        """The origin (the side of the reference orbit) is below the bracket."""
        return self.origin <= self.low

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)

    @property
    def key(self) -> str:
        """Stable id of the reference computation."""
        d = self.as_dict()
        for k in ("name", "periods", "max_probes", "xtol", "exclude"):
            d.pop(k)
        return stable_key({**d, "ref_xtol": REFERENCE_XTOL})

    def label(self) -> str:
        return problem_label(
            {"name": self.problem, "case": self.case, "dimensional": self.dimensional, "params": self.params}
        )


def _bad(where: str, text: str) -> ConfigError:
    return ConfigError(f"suite field {where!r} {text}")


def _number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


def parse_target(spec: Any, i: int) -> BifurcationTarget:
    """Check one ``[[bifurcation_targets]]`` table; the target.

    Raises
    ------
    ConfigError
        A missing or unknown key, a value of the wrong type, a bracket that is not
        ``[low, high]`` with ``low < high``, an origin inside the bracket, an
        unknown problem, case or parameter, an unknown kind.
    """
    where = f"bifurcation_targets[{i}]"
    if not isinstance(spec, dict):
        raise _bad(where, f"must be a table (name, problem, param, origin, bracket, ...), got {_got(spec)}")
    bad = sorted(set(spec) - TARGET_KEYS)
    if bad:
        raise ConfigError(f"{where}: unknown key(s) {', '.join(bad)}; allowed: {', '.join(sorted(TARGET_KEYS))}")
    missing = [k for k in ("name", "problem", "param", "origin", "bracket") if k not in spec]
    if missing:
        raise ConfigError(
            f"{where}: missing key(s) {', '.join(missing)} (a target needs name, problem, param, "
            "origin and bracket = [low, high])"
        )
    for key in ("name", "problem", "param"):
        if not isinstance(spec[key], str) or not spec[key]:
            raise _bad(f"{where}.{key}", f"must be a non-empty string, got {_got(spec[key])}")
    where = f"bifurcation_targets[{i}] ({spec['name']})"
    if not _number(spec["origin"]):
        raise _bad(f"{where}.origin", f"must be a finite number, got {_got(spec['origin'])}")
    br = spec["bracket"]
    if not (isinstance(br, (list, tuple)) and len(br) == 2 and all(_number(v) for v in br)):
        raise _bad(f"{where}.bracket", f"must be [low, high], two finite numbers, got {_got(br)}")
    low, high, origin = float(br[0]), float(br[1]), float(spec["origin"])
    if not low < high:
        raise ConfigError(f"{where}: bracket [{low:g}, {high:g}] must have low < high")
    if low <= origin <= high:
        raise ConfigError(
            f"{where}: origin {origin:g} lies in the bracket [{low:g}, {high:g}]; the origin is "
            "where the orbit is found from rest, outside the bracket (on its near side)"
        )
    params = spec.get("params", {})
    if not isinstance(params, dict) or not all(isinstance(k, str) and _number(v) for k, v in params.items()):
        raise _bad(f"{where}.params", f"must be a table of parameter = number, got {_got(params)}")
    if spec["param"] in params:
        raise ConfigError(f"{where}: param {spec['param']!r} is also fixed in params")
    case = spec.get("case", 1)
    if not (isinstance(case, str) or (isinstance(case, int) and not isinstance(case, bool))):
        raise _bad(f"{where}.case", f"must be a case number (1..4) or name, got {_got(case)}")
    dimensional = spec.get("dimensional", False)
    if not isinstance(dimensional, bool):
        raise _bad(f"{where}.dimensional", f"must be true or false, got {_got(dimensional)}")
    kind = spec.get("kind")
    if kind is not None and kind not in _known_kinds():
        raise _bad(f"{where}.kind", f"must be one of {', '.join(_known_kinds())}, got {_got(kind)}")
    periods = spec.get("periods", DEFAULT_PERIODS)
    if isinstance(periods, bool) or not isinstance(periods, int) or not 3 <= periods <= 10_000:
        raise _bad(f"{where}.periods", f"must be an integer from 3 to 10000, got {_got(periods)}")
    max_probes = spec.get("max_probes", DEFAULT_MAX_PROBES)
    if isinstance(max_probes, bool) or not isinstance(max_probes, int) or not 3 <= max_probes <= 1000:
        raise _bad(f"{where}.max_probes", f"must be an integer from 3 to 1000, got {_got(max_probes)}")
    xtol = spec.get("xtol", DEFAULT_XTOL)
    if not _number(xtol) or xtol <= 0:
        raise _bad(f"{where}.xtol", f"must be a positive number, got {_got(xtol)}")
    exclude = spec.get("exclude", [])
    if not (isinstance(exclude, list) and all(isinstance(x, str) for x in exclude)):
        raise _bad(f"{where}.exclude", f"must be a list of integrator names, got {_got(exclude)}")
    from nsbench.integrators import canonical_name, list_integrators

    unknown = [x for x in exclude if canonical_name(x) not in list_integrators()]
    if unknown:
        raise ConfigError(f"{where}: exclude names unknown integrator(s) {', '.join(unknown)}")
    target = BifurcationTarget(
        exclude=tuple(canonical_name(x) for x in exclude),
        name=spec["name"],
        problem=spec["problem"],
        case=case,
        param=spec["param"],
        origin=origin,
        low=low,
        high=high,
        params={k: float(v) for k, v in params.items()},
        dimensional=dimensional,
        kind=kind,
        periods=periods,
        max_probes=max_probes,
        xtol=float(xtol),
    )
    # the problem, case and parameter must exist: build the problem at both ends and at the origin
    for value in (origin, low, high):
        try:
            problem = target.problem_at(value)
        except ConfigError as exc:
            raise ConfigError(f"{where}: {exc}") from None
        except Exception as exc:  # noqa: BLE001 - a problem's own check, in words
            raise ConfigError(f"{where}: problem {spec['problem']!r} at {spec['param']} = {value:g}: {exc}") from None
    names = set(getattr(problem.coefficients, "__dataclass_fields__", {}) or ())
    if names and target.param not in names and target.param not in ("r_f", "omega_r", "inv_omega_r"):
        raise ConfigError(
            f"{where}: {target.problem!r} has no parameter {target.param!r}; parameters: {', '.join(sorted(names))}"
        )
    return target


def parse_targets(specs: Any) -> list[BifurcationTarget]:
    """Every ``[[bifurcation_targets]]`` table checked; names must be unique."""
    if not isinstance(specs, (list, tuple)):
        raise ConfigError(f"suite field 'bifurcation_targets' must be a list of tables, got {type(specs).__name__}")
    targets = [parse_target(s, i) for i, s in enumerate(specs)]
    names = [t.name for t in targets]
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise ConfigError(f"bifurcation_targets: name(s) {', '.join(dup)} used more than once")
    return targets


# ---------------------------------------------------------------------- the reference
