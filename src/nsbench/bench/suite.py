"""Benchmark suites: what to run, as a TOML file or the same thing as a Python object.

A :class:`Suite` lists problems (presets and parameter overrides), integrators
(with option grids, or their own ``accuracy_levels``), the time span, repeats,
per-case limits and the fixed targets. :meth:`Suite.cases` expands it into
:class:`Case` objects, each with a stable id used for storage and resume.
"""

from __future__ import annotations

import hashlib
import itertools
import json
import tomllib
from dataclasses import asdict, dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

from nsbench.bench.timing import MIN_REPEATS
from nsbench.errors import ConfigError

_SUITE_KEYS = {"name", "t_span", "repeats", "repeat_budget", "time_limit", "max_steps",
               "dense_points", "targets", "reference", "problems", "integrators"}
_PROBLEM_KEYS = {"name", "case", "cases", "params", "dimensional"}
_INTEGRATOR_KEYS = {"registered", "exclude", "only", "grids", "skip_levels"}


def stable_key(obj: Any) -> str:
    """A short hash of a JSON-serialisable object (sorted keys), stable across processes."""
    text = json.dumps(obj, sort_keys=True, separators=(",", ":"), default=float)
    return hashlib.sha1(text.encode()).hexdigest()[:16]


@dataclass(frozen=True)
class Case:
    """One (problem, integrator configuration) pair of a suite, with the run settings.

    ``level`` is the index into the integrator's ``accuracy_levels`` (or into the
    suite's explicit grid), loose to tight.
    """

    problem: dict[str, Any]
    integrator: str
    options: dict[str, Any]
    level: int
    t0: float
    t_end: float
    repeats: int
    time_limit: float
    max_steps: int
    dense_points: int

    @property
    def case_id(self) -> str:
        """Stable id of what is computed (not of how often it is timed)."""
        return stable_key({"problem": self.problem, "integrator": self.integrator,
                           "options": self.options, "t": [self.t0, self.t_end],
                           "dense": self.dense_points, "max_steps": self.max_steps})

    @property
    def label(self) -> str:
        opts = ",".join(f"{k}={v:g}" if isinstance(v, float) else f"{k}={v}"
                        for k, v in self.options.items())
        case = self.problem.get("case")
        return f"{self.problem['name']}/{case} {self.integrator}[{opts}]"

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)


def _number_list(value: Any, what: str) -> list[float]:
    if not isinstance(value, list) or not value:
        raise ConfigError(f"{what} must be a non-empty list of numbers, got {value!r}")
    out = []
    for v in value:
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            raise ConfigError(f"{what} must contain numbers only, got {v!r}")
        out.append(float(v))
    return out


def _unknown(keys: set[str], allowed: set[str], where: str) -> None:
    bad = sorted(keys - allowed)
    if bad:
        raise ConfigError(f"{where}: unknown key(s) {', '.join(bad)}; allowed: {', '.join(sorted(allowed))}")


@dataclass
class Suite:
    """A benchmark suite.

    Attributes
    ----------
    name
        Label stored with every row.
    t_span
        ``(t0, t_end)`` in the problems' units.
    problems
        Tables with ``name`` and ``case`` (or ``cases``), optional ``params`` and ``dimensional``.
    integrators
        ``registered`` (bool: every registered integrator), ``only`` (names),
        ``exclude`` (names), ``grids`` (name -> ``{'options': [...]}`` or
        ``{'grid': {opt: [values]}, 'fixed': {...}}``), ``skip_levels``
        (name -> ``{'levels': [indices], 'reason': str}``, data that keeps known
        slow levels out of a suite).
    repeats
        Timed runs per case, all after an untimed warm-up; the wall time is their
        median. Fewer than :data:`~nsbench.bench.timing.MIN_REPEATS` (3) are raised to 3.
    repeat_budget
        Deprecated and ignored (accepted so that older suite files still load):
        every successful case is now timed on ``repeats`` warm runs.
    time_limit
        Wall-clock seconds per run (the warm-up run and each timed run; setup,
        i.e. compilation, is not limited). Past it the runner ends the worker
        process and the case is recorded with status ``time limit``.
    max_steps
        Step budget per run.
    dense_points
        States compared with the reference on an even grid over ``t_span``.
    targets
        Switching-time error targets of the fixed-target table.
    reference
        Registered integrators tried in order as the reference of a problem; the
        first that accepts the problem is used.
    """

    name: str = "suite"
    t_span: tuple[float, float] = (0.0, 300.0)
    problems: list[dict[str, Any]] = field(default_factory=list)
    integrators: dict[str, Any] = field(default_factory=lambda: {"registered": True})
    repeats: int = 3
    repeat_budget: float | None = None
    time_limit: float = 30.0
    max_steps: int = 2_000_000
    dense_points: int = 100
    targets: tuple[float, ...] = (1e-6, 1e-9, 1e-12)
    reference: tuple[str, ...] = ("exact", "reference")

    def __post_init__(self) -> None:
        self._unavailable: dict[str, str] = {}
        self.t_span = tuple(_number_list(list(self.t_span), "t_span"))  # type: ignore[assignment]
        if len(self.t_span) != 2 or not self.t_span[1] > self.t_span[0]:
            raise ConfigError(f"t_span = {list(self.t_span)} must be [t0, t_end] with t_end > t0")
        self.targets = tuple(sorted(_number_list(list(self.targets), "targets"), reverse=True))
        if any(t <= 0 for t in self.targets):
            raise ConfigError(f"targets = {list(self.targets)} must be positive")
        for key, low in (("repeats", 1), ("max_steps", 1), ("dense_points", 2)):
            value = getattr(self, key)
            if isinstance(value, bool) or not isinstance(value, int) or value < low:
                raise ConfigError(f"{key} = {value!r} must be an integer >= {low}")
        self.repeats = max(self.repeats, MIN_REPEATS)  # a median and a spread need three runs
        for key in ("repeat_budget", "time_limit"):
            value = getattr(self, key)
            if key == "repeat_budget" and value is None:
                continue
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not value > 0:
                raise ConfigError(f"{key} = {value!r} must be a positive number of seconds")
        if isinstance(self.reference, str):
            self.reference = (self.reference,)
        self.reference = tuple(self.reference)
        if not self.problems:
            raise ConfigError("a suite needs at least one entry in problems")
        for p in self.problems:
            if not isinstance(p, dict) or "name" not in p:
                raise ConfigError(f"each problem needs a 'name', got {p!r}")
            _unknown(set(p), _PROBLEM_KEYS, f"problem {p.get('name')!r}")
        if not isinstance(self.integrators, dict):
            raise ConfigError(f"integrators must be a table, got {self.integrators!r}")
        _unknown(set(self.integrators), _INTEGRATOR_KEYS, "integrators")

    # ------------------------------------------------------------------ loading
    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> "Suite":
        """Build a suite from a dict with the TOML layout (see ``docs`` in the README)."""
        _unknown(set(data), _SUITE_KEYS, "suite")
        return cls(**data)

    @classmethod
    def from_toml(cls, path: str | Path) -> "Suite":
        """Read a suite from a TOML file."""
        p = Path(path)
        if not p.is_file():
            raise ConfigError(f"suite file {str(path)!r} does not exist")
        try:
            data = tomllib.loads(p.read_text())
        except tomllib.TOMLDecodeError as exc:
            raise ConfigError(f"suite file {str(path)!r} is not valid TOML: {exc}") from None
        return cls.from_dict(data)

    def to_dict(self) -> dict[str, Any]:
        out = {k: v for k, v in asdict(self).items() if not k.startswith("_")}
        out["t_span"], out["targets"], out["reference"] = (
            list(self.t_span), list(self.targets), list(self.reference))
        return out

    # ------------------------------------------------------------------ expansion
    def problem_configs(self) -> list[dict[str, Any]]:
        """Problem config dicts (those of :meth:`FrictionOscillator.config`), validated."""
        from nsbench.problems import problem_from_config

        out = []
        for p in self.problems:
            cases = p.get("cases", [p.get("case", 1)])
            if not isinstance(cases, list):
                cases = [cases]
            params = dict(p.get("params", {}))
            # a list of values is a grid: one problem per value (per combination of lists)
            grid = [k for k, v in params.items() if isinstance(v, list)]
            for key in grid:
                if not params[key]:
                    raise ConfigError(f"problem {p['name']!r}: params.{key} is an empty list")
            for case in cases:
                for combo in itertools.product(*(params[k] for k in grid)):
                    config = {"name": p["name"], "case": case, "dimensional": bool(p.get("dimensional", False)),
                              "params": {**params, **dict(zip(grid, combo))}}
                    out.append(problem_from_config(config).config())  # validates early
        return out

    def integrator_names(self) -> list[str]:
        """Integrators of the suite, in registry order.

        A registered plug-in that fails to import is left out (and listed in
        :meth:`unavailable`) unless the suite names it explicitly.
        """
        from nsbench.errors import PluginLoadError
        from nsbench.integrators import canonical_name, integrator_class, list_integrators

        spec = self.integrators
        registered = list_integrators()
        if "only" in spec:
            names = list(spec["only"])
        elif spec.get("registered", True):
            names = []
            for name in registered:
                try:
                    integrator_class(name)
                except PluginLoadError as exc:
                    self._unavailable[name] = str(exc)
                    continue
                names.append(name)
        else:
            names = []
        names += [n for n in spec.get("grids", {}) if n not in names]
        names = list(dict.fromkeys(canonical_name(n) for n in names))  # old aliases name the same integrator
        unknown = [n for n in names if n not in registered]
        if unknown:
            raise ConfigError(f"unknown integrator(s) {', '.join(unknown)}; registered: {', '.join(registered)}")
        exclude = {canonical_name(n) for n in spec.get("exclude", [])}
        return [n for n in names if n not in exclude]

    def unavailable(self) -> dict[str, str]:
        """Registered integrators left out because they fail to import, with the reason."""
        self.integrator_names()
        return dict(self._unavailable)

    def option_sets(self, name: str) -> list[tuple[int, dict[str, Any]]]:
        """``(level, options)`` pairs for one integrator, loose to tight, after skips."""
        from nsbench.integrators import integrator_class

        cls = integrator_class(name)
        from nsbench.integrators import canonical_name

        grids = {canonical_name(k): v for k, v in self.integrators.get("grids", {}).items()}
        grid = grids.get(name)
        if grid is None:
            sets = [dict(o) for o in cls.accuracy_levels] or [{}]
        elif "options" in grid:
            sets = [dict(o) for o in grid["options"]]
        elif "grid" in grid:
            keys = list(grid["grid"])
            values = [grid["grid"][k] if isinstance(grid["grid"][k], list) else [grid["grid"][k]] for k in keys]
            fixed = dict(grid.get("fixed", {}))
            sets = [{**fixed, **dict(zip(keys, combo))} for combo in itertools.product(*values)]
        else:
            raise ConfigError(f"grid of {name!r} needs 'options' (a list of tables) or 'grid' (option -> values)")
        for options in sets:
            cls(**options)  # validate names and ranges now, not in a worker
        skip = set(self.integrators.get("skip_levels", {}).get(name, {}).get("levels", []))
        return [(i, o) for i, o in enumerate(sets) if i not in skip]

    def cases(self) -> list[Case]:
        """Every case of the suite, problems outermost, loose levels first."""
        problems = self.problem_configs()
        plan = [(name, self.option_sets(name)) for name in self.integrator_names()]
        out = []
        for problem in problems:
            for name, sets in plan:
                for level, options in sets:
                    out.append(Case(problem=problem, integrator=name, options=options, level=level,
                                    t0=self.t_span[0], t_end=self.t_span[1], repeats=self.repeats,
                                    time_limit=float(self.time_limit), max_steps=self.max_steps,
                                    dense_points=self.dense_points))
        return out


def packaged_suites() -> list[str]:
    """Names of the suites shipped with nsbench (``nsbench/suites/*.toml``)."""
    return sorted(f.name.removesuffix(".toml") for f in resources.files("nsbench.suites").iterdir()
                  if f.name.endswith(".toml"))


def packaged_suite(name: str) -> Suite:
    """A suite shipped with nsbench by name: ``'default'`` (``nsbench run``), ``'chain-scaling'``, ..."""
    if name not in packaged_suites():
        raise ConfigError(f"no packaged suite {name!r}; packaged: {', '.join(packaged_suites())} "
                          "(or give the path of a suite TOML file)")
    text = resources.files("nsbench.suites").joinpath(f"{name}.toml").read_text()
    return Suite.from_dict(tomllib.loads(text))


def default_suite() -> Suite:
    """The packaged suite of ``nsbench run`` (``nsbench/suites/default.toml``)."""
    return packaged_suite("default")


def load_suite(source: str | Path | dict[str, Any] | Suite) -> Suite:
    """A suite from a TOML path, a dict, an existing :class:`Suite`, or a packaged suite's name."""
    if isinstance(source, Suite):
        return source
    if isinstance(source, dict):
        return Suite.from_dict(source)
    if not Path(source).exists() and str(source) in packaged_suites():
        return packaged_suite(str(source))
    if not Path(source).exists() and not str(source).endswith(".toml"):
        raise ConfigError(f"suite {str(source)!r} is neither a file nor a packaged suite; packaged: "
                          f"{', '.join(packaged_suites())}")
    return Suite.from_toml(source)
