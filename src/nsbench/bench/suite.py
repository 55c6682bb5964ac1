"""Benchmark suites: what to run, as a TOML file or the same thing as a Python object.

A :class:`Suite` lists problems (presets and parameter overrides), integrators
(with option grids, or their own ``accuracy_levels``), the time span, repeats,
per-case limits and the fixed targets. :meth:`Suite.cases` expands it into
:class:`Case` objects, each with a stable id used for storage and resume.
"""

from __future__ import annotations

import itertools
import math
import tomllib
from dataclasses import asdict, dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

from nsbench.bench.keys import got as _got
from nsbench.bench.keys import stable_key
from nsbench.bench.timing import DEFAULT_SAMPLES, MIN_REPEATS, MIN_SAMPLE_TIME
from nsbench.errors import ConfigError

_SUITE_KEYS = {
    "name",
    "t_span",
    "repeats",
    "max_repeats",
    "min_sample_time",
    "repeat_budget",
    "time_limit",
    "setup_limit",
    "max_steps",
    "dense_points",
    "targets",
    "reference",
    "problems",
    "integrators",
    "bifurcation_targets",
}
_PROBLEM_KEYS = {"name", "case", "cases", "params", "dimensional", "t_span"}
_INTEGRATOR_KEYS = {"registered", "exclude", "only", "optional", "grids", "skip_levels"}

#: Most cases a suite may expand to. The count is computed from the TOML before
#: anything is expanded, so a grid of 10^9 cases is refused at once; split a
#: bigger study into several suites (or raise this bound).
MAX_CASES = 100_000
#: Most timed samples per case (``repeats``).
MAX_REPEATS = 1000
#: Most states compared with the reference per case (``dense_points``).
MAX_DENSE_POINTS = 1_000_000
#: Largest step budget per run (``max_steps``; compiled kernels count in 64-bit integers).
MAX_STEPS = 10**12


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
    setup_limit: float = 1800.0
    min_sample_time: float = MIN_SAMPLE_TIME
    max_repeats: int | None = None  # None: repeats (no samples beyond the planned ones)

    @property
    def case_id(self) -> str:
        """Stable id of what is computed (not of how often it is timed)."""
        return stable_key(
            {
                "problem": self.problem,
                "integrator": self.integrator,
                "options": self.options,
                "t": [self.t0, self.t_end],
                "dense": self.dense_points,
                "max_steps": self.max_steps,
            }
        )

    @property
    def label(self) -> str:
        opts = ",".join(f"{k}={v:g}" if isinstance(v, float) else f"{k}={v}" for k, v in self.options.items())
        case = self.problem.get("case")
        return f"{self.problem['name']}/{case} {self.integrator}[{opts}]"

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)


def _field(ok: object, path: str, expected: str, value: Any) -> None:
    """Raise ``suite field 'path' must be expected, got <type> <value>`` unless ``ok`` is true."""
    if not ok:
        raise ConfigError(f"suite field {path!r} must be {expected}, got {_got(value)}")


def _is_number(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _is_str_list(v: Any) -> bool:
    return isinstance(v, (list, tuple)) and all(isinstance(x, str) for x in v)


def _number_list(value: Any, what: str) -> list[float]:
    if not isinstance(value, (list, tuple)) or not value:
        raise ConfigError(f"suite field {what!r} must be a non-empty list of numbers, got {_got(value)}")
    out = []
    for v in value:
        if not _is_number(v):
            raise ConfigError(f"{what} must contain numbers only, got {v!r}")
        if not math.isfinite(v):
            raise ConfigError(f"{what} = {list(value)} must contain finite numbers only, got {v!r}")
        out.append(float(v))
    return out


def _check_problem(p: Any, i: int) -> None:
    """Types of one ``[[problems]]`` table (values are the problem's own check)."""
    where = f"problems[{i}]"
    _field(isinstance(p, dict) and "name" in p, where, "a table with a 'name'", p)
    _field(isinstance(p["name"], str), f"{where}.name", "a registered problem name (a string)", p["name"])
    _unknown(set(p), _PROBLEM_KEYS, f"problem {p['name']!r}")
    case_ok = lambda c: isinstance(c, str) or (isinstance(c, int) and not isinstance(c, bool))  # noqa: E731
    if "case" in p and "cases" in p:
        # one would be dropped in silence: the suite would measure another case than the one written
        raise ConfigError(
            f"{where} ({p['name']!r}) gives both 'case' = {p['case']!r} and 'cases' = {p['cases']!r}; "
            "give one: 'case' (one case) or 'cases' (a list)"
        )
    if "case" in p:
        _field(case_ok(p["case"]), f"{where}.case", "a case number (1..4) or name", p["case"])
    if "cases" in p:
        cases = p["cases"]
        _field(
            case_ok(cases) or (isinstance(cases, list) and cases and all(case_ok(c) for c in cases)),
            f"{where}.cases",
            "a non-empty list of case numbers",
            cases,
        )
    if "params" in p:
        params = p["params"]
        _field(
            isinstance(params, dict), f"{where}.params", "a table of parameter = number (or list of numbers)", params
        )
        for key, value in params.items():
            ok = _is_number(value) or (isinstance(value, list) and all(_is_number(v) for v in value))
            ok = ok or (key == "law" and isinstance(value, str))  # the friction law is a name
            _field(ok, f"{where}.params.{key}", "a number or a list of numbers (law: a name)", value)
    if "dimensional" in p:
        _field(isinstance(p["dimensional"], bool), f"{where}.dimensional", "true or false", p["dimensional"])
    if "t_span" in p:
        span = _number_list(p["t_span"], f"{where}.t_span")
        if len(span) != 2 or not span[1] > span[0]:
            raise ConfigError(f"{where}.t_span = {list(p['t_span'])} must be [t0, t_end] with t_end > t0")


def _check_integrators(spec: Any) -> None:
    """Types of the ``[integrators]`` table."""
    _field(
        isinstance(spec, dict), "integrators", "a table (registered, only, optional, exclude, grids, skip_levels)", spec
    )
    _unknown(set(spec), _INTEGRATOR_KEYS, "integrators")
    if "registered" in spec:
        _field(isinstance(spec["registered"], bool), "integrators.registered", "true or false", spec["registered"])
    for key in ("only", "optional", "exclude"):
        if key in spec:
            _field(_is_str_list(spec[key]), f"integrators.{key}", "a list of integrator names", spec[key])
    grids = spec.get("grids", {})
    _field(isinstance(grids, dict), "integrators.grids", "a table of integrator name = grid", grids)
    for name, grid in grids.items():
        where = f"integrators.grids.{name}"
        _field(isinstance(grid, dict), where, "a table with 'options' or 'grid'", grid)
        _unknown(set(grid), {"options", "grid", "fixed"}, where)
        if "options" in grid and ("grid" in grid or "fixed" in grid):
            other = "grid" if "grid" in grid else "fixed"
            raise ConfigError(
                f"{where} gives both 'options' and '{other}'; give 'options' (a list of option tables) "
                "or 'grid' (option -> values, with 'fixed' options)"
            )
        if "options" in grid:
            _field(
                isinstance(grid["options"], list) and all(isinstance(o, dict) for o in grid["options"]),
                f"{where}.options",
                "a list of option tables",
                grid["options"],
            )
        if "grid" in grid:
            _field(
                isinstance(grid["grid"], dict),
                f"{where}.grid",
                "a table of option = value or list of values",
                grid["grid"],
            )
            for key, values in grid["grid"].items():
                _field(not isinstance(values, list) or values, f"{where}.grid.{key}", "a non-empty list", values)
        if "fixed" in grid:
            _field(isinstance(grid["fixed"], dict), f"{where}.fixed", "a table of option = value", grid["fixed"])
    skips = spec.get("skip_levels", {})
    _field(isinstance(skips, dict), "integrators.skip_levels", "a table of integrator name = {levels, reason}", skips)
    for name, skip in skips.items():
        where = f"integrators.skip_levels.{name}"
        _field(isinstance(skip, dict), where, "a table with 'levels' (and 'reason')", skip)
        _unknown(set(skip), {"levels", "reason"}, where)
        levels = skip.get("levels", [])
        _field(
            isinstance(levels, list) and all(isinstance(v, int) and not isinstance(v, bool) for v in levels),
            f"{where}.levels",
            "a list of level indices",
            levels,
        )
        _field(all(v >= 0 for v in levels), f"{where}.levels", "a list of level indices >= 0", levels)
        if "reason" in skip:
            _field(isinstance(skip["reason"], str), f"{where}.reason", "a string", skip["reason"])


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
        Tables with ``name`` and ``case`` (or ``cases``), optional ``params``, ``dimensional``
        and ``t_span`` (the problem's own span, instead of the suite's).
    integrators
        ``registered`` (bool: every registered integrator that can run here), ``only`` (names),
        ``optional`` (names run where they can: an engine behind a pip extra that is not installed is
        left out and listed in :meth:`unavailable`), ``exclude`` (names), ``grids`` (name -> ``{'options': [...]}`` or
        ``{'grid': {opt: [values]}, 'fixed': {...}}``), ``skip_levels``
        (name -> ``{'levels': [indices], 'reason': str}``, data that keeps known
        slow levels out of a suite).
    repeats
        Timed samples per case (default 5), all after an untimed warm-up; the wall
        time is their median. At least :data:`~nsbench.bench.timing.MIN_REPEATS`
        (3): a median and a spread need three runs, and fewer is refused.
    max_repeats
        Most timed samples per case (default twice ``repeats``): a case whose
        planned samples spread by more than 25 % on the CPU clock
        (:func:`nsbench.bench.timing.needs_more`) gets more, one per round, up to
        this many. Equal to ``repeats``: never more.
    min_sample_time
        Seconds a timed sample lasts at least (default 0.05): a case whose run is
        shorter is run ``loops`` times back to back per sample, and the sample is
        their mean (:func:`nsbench.bench.timing.loops_for`); 0 times single runs.
    repeat_budget
        Deprecated and ignored (accepted so that older suite files still load):
        every successful case is now timed on ``repeats`` warm runs.
    time_limit
        Wall-clock seconds per run (the warm-up run and each timed run). Past it
        the runner ends the worker process and the case is recorded with status
        ``time limit``.
    setup_limit
        Wall-clock seconds of an integrator's setup in a worker (construction and
        ``setup``: compilation from a cold cache included; default 1800). Past it
        the case is recorded with status ``time limit`` (a plug-in whose setup
        never returns costs its cases, not the suite).
    max_steps
        Step budget per run.
    dense_points
        States compared with the reference on an even grid over ``t_span``.
    targets
        Switching-time error targets of the fixed-target table.
    reference
        Registered integrators tried in order as the reference of a problem; the
        first that accepts the problem is used.
    bifurcation_targets
        ``[[bifurcation_targets]]`` tables (name, problem, case, params, param,
        origin, bracket = [low, high], kind, periods, max_probes, xtol): each
        integrator configuration locates each of these bifurcations with its own
        flow (see :mod:`nsbench.bench.targets`).
    """

    name: str = "suite"
    t_span: tuple[float, float] = (0.0, 300.0)
    problems: list[dict[str, Any]] = field(default_factory=list)
    integrators: dict[str, Any] = field(default_factory=lambda: {"registered": True})
    repeats: int = DEFAULT_SAMPLES
    max_repeats: int | None = None
    min_sample_time: float = MIN_SAMPLE_TIME
    repeat_budget: float | None = None
    time_limit: float = 30.0
    setup_limit: float = 1800.0
    max_steps: int = 2_000_000
    dense_points: int = 100
    targets: tuple[float, ...] = (1e-6, 1e-9, 1e-12)
    reference: tuple[str, ...] = ("exact", "reference")
    bifurcation_targets: list[dict[str, Any]] = field(default_factory=list)

    def __post_init__(self) -> None:
        self._unavailable: dict[str, str] = {}
        _field(isinstance(self.name, str) and self.name.strip() != "", "name", "a non-empty string", self.name)
        self.t_span = tuple(_number_list(self.t_span, "t_span"))  # type: ignore[assignment]
        if len(self.t_span) != 2 or not self.t_span[1] > self.t_span[0]:
            raise ConfigError(f"t_span = {list(self.t_span)} must be [t0, t_end] with t_end > t0")
        self.targets = tuple(sorted(_number_list(self.targets, "targets"), reverse=True))
        if any(t <= 0 for t in self.targets):
            raise ConfigError(f"targets = {list(self.targets)} must be positive")
        for key, low, high, bound in (
            ("repeats", MIN_REPEATS, MAX_REPEATS, "MAX_REPEATS"),
            ("max_steps", 1, MAX_STEPS, "MAX_STEPS"),
            ("dense_points", 2, MAX_DENSE_POINTS, "MAX_DENSE_POINTS"),
        ):
            value = getattr(self, key)
            if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= high:
                why = " (a median and a spread need three timed runs)" if key == "repeats" else ""
                raise ConfigError(
                    f"{key} = {value!r} must be an integer >= {low} and <= {high}{why} "
                    f"(the upper bound is nsbench.bench.suite.{bound})"
                )
        if self.max_repeats is None:
            self.max_repeats = min(2 * self.repeats, MAX_REPEATS)
        value = self.max_repeats
        if isinstance(value, bool) or not isinstance(value, int) or not self.repeats <= value <= MAX_REPEATS:
            raise ConfigError(
                f"max_repeats = {value!r} must be an integer >= repeats ({self.repeats}) and <= "
                f"{MAX_REPEATS} (the bound is nsbench.bench.suite.MAX_REPEATS)"
            )
        for key in ("repeat_budget", "time_limit", "setup_limit"):
            value = getattr(self, key)
            if key == "repeat_budget" and value is None:
                continue
            if not _is_number(value) or not (value > 0 and math.isfinite(value)):
                raise ConfigError(f"{key} = {value!r} must be a positive, finite number of seconds")
        value = self.min_sample_time
        if not _is_number(value) or not 0 <= value < self.time_limit:
            raise ConfigError(
                f"min_sample_time = {value!r} must be a number of seconds >= 0 and below time_limit "
                f"= {self.time_limit:g} (a timed sample loops runs shorter than it)"
            )
        if isinstance(self.reference, str):
            self.reference = (self.reference,)
        _field(
            _is_str_list(self.reference) and len(self.reference) > 0,
            "reference",
            "a list of registered integrator names",
            self.reference,
        )
        self.reference = tuple(self.reference)
        _field(isinstance(self.problems, list), "problems", "a list of tables (each with a 'name')", self.problems)
        if not self.problems:
            raise ConfigError("a suite needs at least one entry in problems")
        for i, p in enumerate(self.problems):
            _check_problem(p, i)
        _check_integrators(self.integrators)
        self._check_reference()
        self._check_selection()
        from nsbench.bench.target_spec import parse_targets

        if self.bifurcation_targets is None:
            self.bifurcation_targets = []
        self._bif_targets = parse_targets(self.bifurcation_targets)  # checked now, not in a worker
        self.bifurcation_targets = [dict(t) for t in self.bifurcation_targets]

    def target_list(self):
        """The bifurcation targets, checked (:class:`nsbench.bench.target_spec.BifurcationTarget`)."""
        return list(self._bif_targets)

    def _check_reference(self) -> None:
        from nsbench.integrators import canonical_name, list_integrators

        registered = list_integrators()
        unknown = [n for n in self.reference if canonical_name(n) not in registered]
        if unknown:
            raise ConfigError(
                f"suite field 'reference': unknown integrator(s) {', '.join(unknown)}; "
                f"registered: {', '.join(registered)}"
            )

    def _check_selection(self) -> None:
        """Names in ``exclude``, ``grids`` and ``skip_levels`` that select nothing, and skipped levels that do not exist.

        Each of these would otherwise be dropped (or an integrator added) in silence, so the
        suite would measure another set of configurations than the one written.
        """
        from nsbench.errors import PluginLoadError
        from nsbench.integrators import canonical_name, integrator_class, list_integrators

        spec = self.integrators
        registered = list_integrators()
        for key in ("exclude", "optional", "grids", "skip_levels"):
            unknown = [n for n in spec.get(key, []) if canonical_name(n) not in registered]
            if unknown:
                raise ConfigError(
                    f"suite field 'integrators.{key}': unknown integrator(s) {', '.join(unknown)}; "
                    f"registered: {', '.join(registered)}"
                )
        if "only" in spec and not spec["only"]:
            raise ConfigError("suite field 'integrators.only' is empty: the suite would run no integrator")
        if not spec.get("registered", True) and "only" not in spec and not spec.get("grids"):
            raise ConfigError(
                "suite field 'integrators': registered = false with no 'only' and no 'grids' selects no integrator"
            )
        exclude = {canonical_name(n) for n in spec.get("exclude", [])}
        only = {canonical_name(n) for n in spec["only"]} if "only" in spec else None
        if only is not None:  # the engines run where installed are selected as well
            only |= {canonical_name(n) for n in spec.get("optional", [])}
        for key in ("grids", "skip_levels"):
            for n in spec.get(key, {}):
                name = canonical_name(n)
                if name in exclude:
                    raise ConfigError(
                        f"suite field 'integrators.{key}.{n}' names an integrator that "
                        "'integrators.exclude' leaves out; remove one of the two"
                    )
                if only is not None and name not in only:
                    raise ConfigError(
                        f"suite field 'integrators.{key}.{n}' names an integrator outside "
                        f"'integrators.only' ({', '.join(spec['only']) or 'empty'}) and 'optional'; add it to "
                        "'only' or remove its entry"
                    )
        grids = {canonical_name(k): v for k, v in spec.get("grids", {}).items()}
        for n, skip in spec.get("skip_levels", {}).items():
            name = canonical_name(n)
            grid = grids.get(name)
            if grid is None:
                try:
                    count = max(1, len(integrator_class(name).accuracy_levels))
                except PluginLoadError:
                    continue  # left out of the suite, with its reason (Suite.unavailable)
            elif "options" in grid:
                count = len(grid["options"])
            elif "grid" in grid:
                count = math.prod(len(v) if isinstance(v, list) else 1 for v in grid["grid"].values())
            else:
                continue  # refused by option_sets with its own message
            bad = [i for i in skip.get("levels", []) if i >= count]
            if bad:
                raise ConfigError(
                    f"suite field 'integrators.skip_levels.{n}.levels' = {skip['levels']}: level(s) "
                    f"{', '.join(map(str, bad))} do not exist; {n} has {count} level(s) here, 0..{count - 1}"
                )

    # ------------------------------------------------------------------ loading
    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> "Suite":
        """Build a suite from a dict with the TOML layout (see ``docs`` in the README)."""
        _field(isinstance(data, dict), "suite", "a table", data)
        _unknown(set(data), _SUITE_KEYS, "suite")
        return cls(**data)

    @classmethod
    def from_toml(cls, path: str | Path) -> "Suite":
        """Read a suite from a TOML file.

        Raises
        ------
        ConfigError
            The file is missing, a folder, unreadable, not UTF-8 text (binary),
            not valid TOML, or a field is of the wrong type or out of range.
        """
        p = Path(path)
        if p.is_dir():
            raise ConfigError(f"suite file {str(path)!r} is a folder, not a TOML file")
        if not p.is_file():
            raise ConfigError(f"suite file {str(path)!r} does not exist")
        try:
            raw = p.read_bytes()
        except OSError as exc:
            raise ConfigError(f"cannot read suite file {str(path)!r}: {exc.strerror or exc}") from None
        try:
            text = raw.decode("utf-8")
        except UnicodeDecodeError as exc:
            raise ConfigError(
                f"suite file {str(path)!r} is not UTF-8 text (a binary file?): byte "
                f"{raw[exc.start]:#04x} at offset {exc.start}"
            ) from None
        try:
            data = tomllib.loads(text)
        except tomllib.TOMLDecodeError as exc:
            raise ConfigError(f"suite file {str(path)!r} is not valid TOML: {exc}") from None
        except RecursionError:  # tomllib parses nested arrays and tables recursively
            raise ConfigError(f"suite file {str(path)!r} is nested too deeply to be a suite") from None
        return cls.from_dict(data)

    def to_dict(self) -> dict[str, Any]:
        out = {k: v for k, v in asdict(self).items() if not k.startswith("_")}
        out["t_span"], out["targets"], out["reference"] = (list(self.t_span), list(self.targets), list(self.reference))
        return out

    # ------------------------------------------------------------------ size
    def n_problems(self) -> int:
        """Problems the suite expands to (cases times parameter grids), counted without expanding."""
        total = 0
        for p in self.problems:
            cases = p.get("cases", [p.get("case", 1)])
            n_cases = len(cases) if isinstance(cases, list) else 1
            lists = [len(v) for v in dict(p.get("params", {})).values() if isinstance(v, list)]
            total += n_cases * math.prod(lists)
        return total

    def _n_option_sets(self, name: str) -> int:
        from nsbench.integrators import canonical_name, integrator_class

        grids = {canonical_name(k): v for k, v in self.integrators.get("grids", {}).items()}
        grid = grids.get(name)
        if grid is None:
            n = max(1, len(integrator_class(name).accuracy_levels))
        elif "options" in grid:
            n = len(grid["options"])
        elif "grid" in grid:
            n = math.prod(len(v) if isinstance(v, list) else 1 for v in grid["grid"].values())
        else:
            return 0  # option_sets names the problem
        skip = set(self.integrators.get("skip_levels", {}).get(name, {}).get("levels", []))
        return n - sum(1 for i in skip if 0 <= i < n)

    def n_cases(self) -> int:
        """Cases the suite expands to (before duplicates are merged), counted without expanding it."""
        n_sets = sum(self._n_option_sets(name) for name in self.integrator_names())
        return self.n_problems() * n_sets

    def check_size(self) -> None:
        """Refuse a suite of more than :data:`MAX_CASES` cases before it is expanded.

        Raises
        ------
        ConfigError
            Naming the count, its factors and the bound.
        """
        n_problems = self.n_problems()
        if n_problems > MAX_CASES:
            raise ConfigError(
                f"the suite has {n_problems} problems (cases x parameter grids), more than the "
                f"{MAX_CASES} cases a suite may have (nsbench.bench.suite.MAX_CASES); "
                "split it into several suites"
            )
        n = self.n_cases()
        if n > MAX_CASES:
            raise ConfigError(
                f"the suite expands to {n} cases ({n_problems} problems x {n // max(n_problems, 1)} "
                f"integrator settings), more than the {MAX_CASES} allowed "
                "(nsbench.bench.suite.MAX_CASES); split it into several suites"
            )

    # ------------------------------------------------------------------ expansion
    def problem_configs(self) -> list[dict[str, Any]]:
        """Problem config dicts (those of :meth:`FrictionOscillator.config`), validated."""
        return [config for config, _ in self.problem_spans()]

    def problem_spans(self) -> list[tuple[dict[str, Any], tuple[float, float]]]:
        """``(config, (t0, t_end))`` of every problem: its own ``t_span`` if its table has one, else the suite's."""
        from nsbench.problems import problem_from_config

        if self.n_problems() > MAX_CASES:
            self.check_size()
        out = []
        for p in self.problems:
            t0, t_end = (float(v) for v in p.get("t_span", self.t_span))  # two numbers (checked on load)
            span = (t0, t_end)
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
                    config = {
                        "name": p["name"],
                        "case": case,
                        "dimensional": bool(p.get("dimensional", False)),
                        "params": {**params, **dict(zip(grid, combo))},
                    }
                    out.append((problem_from_config(config).config(), span))  # validates early
        return out

    def integrator_names(self) -> list[str]:
        """Integrators of the suite, in registry order.

        A registered integrator that cannot run here (a plug-in that fails to import, an engine
        whose pip extra or external program is missing: :func:`nsbench.registry.unavailable_reason`)
        is left out, and listed in :meth:`unavailable`, when the suite takes every registered one or
        names it under ``optional``; one named under ``only`` or ``grids`` alone stays in (its
        cases then say why it did not run).
        """
        from nsbench import registry
        from nsbench.integrators import canonical_name, list_integrators

        spec = self.integrators
        registered = list_integrators()
        optional = [canonical_name(n) for n in spec.get("optional", [])]
        if "only" in spec:
            names, where_it_can = list(spec["only"]), set(optional)
        elif spec.get("registered", True):
            names, where_it_can = list(registered), set(registered)
        else:
            names, where_it_can = [], set(optional)
        names += [n for n in optional if n not in names]
        names += [n for n in spec.get("grids", {}) if n not in names]
        names = list(dict.fromkeys(canonical_name(n) for n in names))  # old aliases name the same integrator
        unknown = [n for n in names if n not in registered]
        if unknown:
            raise ConfigError(f"unknown integrator(s) {', '.join(unknown)}; registered: {', '.join(registered)}")
        exclude = {canonical_name(n) for n in spec.get("exclude", [])}
        out = []
        for name in names:
            if name in exclude:
                continue
            reason = registry.unavailable_reason("integrators", name) if name in where_it_can else None
            if reason:
                self._unavailable[name] = reason
                continue
            out.append(name)
        return out

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
        """Every case of the suite, problems outermost, loose levels first.

        Raises
        ------
        ConfigError
            A bad problem or integrator setting, more than :data:`MAX_CASES` cases, or none
            (every level skipped, every integrator excluded or unavailable).
        """
        self.check_size()
        problems = self.problem_spans()
        plan = [(name, self.option_sets(name)) for name in self.integrator_names()]
        if not any(sets for _, sets in plan):  # nothing to run: refused here, not a KeyError after the run
            skipped = [name for name, _ in plan]
            why = (
                f"integrators.skip_levels skips every level of {', '.join(skipped)}"
                if skipped
                else "every integrator is excluded or unavailable here"
                + "".join(f"; {n}: {r}" for n, r in self._unavailable.items())
            )
            raise ConfigError(f"the suite has no case to run: {why}; keep at least one level of one integrator")
        out = []
        for problem, (t0, t_end) in problems:
            for name, sets in plan:
                for level, options in sets:
                    out.append(
                        Case(
                            problem=problem,
                            integrator=name,
                            options=options,
                            level=level,
                            t0=t0,
                            t_end=t_end,
                            repeats=self.repeats,
                            time_limit=float(self.time_limit),
                            max_steps=self.max_steps,
                            dense_points=self.dense_points,
                            min_sample_time=float(self.min_sample_time),
                            max_repeats=self.max_repeats,
                            setup_limit=float(self.setup_limit),
                        )
                    )
        return out


def packaged_suites() -> list[str]:
    """Names of the suites shipped with nsbench (``nsbench/suites/*.toml``)."""
    return sorted(
        f.name.removesuffix(".toml") for f in resources.files("nsbench.suites").iterdir() if f.name.endswith(".toml")
    )


def packaged_suite(name: str) -> Suite:
    """A suite shipped with nsbench by name: ``'default'`` (``nsbench run``), ``'chain-scaling'``, ..."""
    if name not in packaged_suites():
        raise ConfigError(
            f"no packaged suite {name!r}; packaged: {', '.join(packaged_suites())} "
            "(or give the path of a suite TOML file)"
        )
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
        raise ConfigError(
            f"suite {str(source)!r} is neither a file nor a packaged suite; packaged: {', '.join(packaged_suites())}"
        )
    return Suite.from_toml(source)
