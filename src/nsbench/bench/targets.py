"""Bifurcation targets: the bifurcation-point error of an integrator (issue 12, item 5).

A suite may name bifurcation targets (``[[bifurcation_targets]]``: a problem, one
parameter, a bracket ``[low, high]`` and an ``origin`` outside it). For each
target:

1. **The reference value.** :func:`nsbench.periodic.locate_target` follows the
   periodic orbit reached from rest at ``origin`` (shooting and continuation on
   the reference flow, event times to machine precision) into the bracket and
   locates its first bifurcation there. It also gives the converged orbit just
   before it, on the origin's side (the *near side*), and that orbit's cyclic
   event pattern. Computed once per target and cached in
   ``OUT/bifurcation_references/``.
2. **The integrator's own value.** For every configuration of the suite (each
   integrator at each accuracy level; reference-grade integrators excluded as in
   the ranking), bisection in ``[low, high]`` on a predicate computed from the
   integrator's own simulations (:func:`locate_with`): at a probe value ``p``
   the problem is simulated for ``periods`` orbit periods from a point on the
   orbit, and ``p`` is on the near side iff the events of the last two periods
   repeat the reference's near-side pattern (``canonical_pattern`` of the
   ``kind+block`` names, e.g. ``('slip2', 'stick2')``). The first probe starts
   on the reference orbit; every later probe starts where the latest near-side
   probe ended (the integrator's own orbit at the near end of the current
   bracket), so that the transient left to decay is of the size of the bracket.
   Both ends are probed first: if they are on the same side, there is no
   bracket (status ``no bracket``). The bisection stops when the bracket is
   narrower than ``xtol`` (``success``) or after ``max_probes`` probes (status
   ``probe budget``, the midpoint still recorded).

Every configuration gives one row per target (:data:`COLUMNS`), stored as
``OUT/bifurcation_targets/<row_id>.parquet`` when it finishes and exported to
``bifurcation_targets.parquet`` and ``bifurcation_targets.csv``; a resumed run
computes only the missing rows. A probe whose simulation fails ends the
location with that status and the reason; an integrator that refuses the
problem gives an ``unsupported`` row; a worker that crashes or passes the time
limit of a probe gives a ``crashed`` or ``time limit`` row. Cost columns sum over
the probes: ``integrator_time`` (the integrator's own clock), ``wall_time``
(the whole run, setup apart), ``nfev``; ``setup_time`` (compilation, per probe)
is kept apart.
"""

from __future__ import annotations

import datetime as _dt
import json
import math
import statistics
import time
import traceback
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any, Callable, TextIO

import numpy as np
import pandas as pd

from nsbench.bench.target_spec import REFERENCE_XTOL, BifurcationTarget  # the specification: parse_targets
from nsbench.status import OutcomeKind, ReferenceStatus, Status

#: Wall-clock seconds the reference of one target may take in a worker.
REFERENCE_LIMIT = 600.0
#: Periods of the last probe window compared with the reference pattern.
WINDOW_PERIODS = 2

STATUS_OK = Status.SUCCESS.value


@dataclass(frozen=True)
class TargetReference:
    """The reference bifurcation of a target, and the orbit on its near side (as plain data)."""

    key: str
    status: str  # 'ok' or why not
    value: float = math.nan
    kind: str = ""
    category: str = ""
    detail: str = ""
    orbit_value: float = math.nan
    t0: float = math.nan
    y0: tuple[float, ...] = ()
    mode0: tuple[int, ...] = ()
    period: float = math.nan
    pattern: tuple[str, ...] = ()
    max_multiplier: float = math.nan
    seconds: float = math.nan

    @property
    def ok(self) -> bool:
        return self.status == ReferenceStatus.OK

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> "TargetReference":
        d = dict(d)
        for k in ("y0", "mode0", "pattern"):
            d[k] = tuple(d.get(k, ()))
        return cls(**d)


def compute_target_reference(target: BifurcationTarget) -> TargetReference:
    """Locate the target on the reference flow (:func:`nsbench.periodic.locate_target`); never raises."""
    from nsbench.periodic import canonical_pattern, locate_target

    tic = time.perf_counter()
    try:
        bif, orbit = locate_target(
            target.problem_at,
            target.param,
            origin=target.origin,
            low=target.low,
            high=target.high,
            kind=target.kind,
            xtol=REFERENCE_XTOL,
        )
    except Exception as exc:  # noqa: BLE001 - a reference that cannot be computed is a status
        return TargetReference(
            target.key, ReferenceStatus.failed(f"{type(exc).__name__}: {exc}"), seconds=time.perf_counter() - tic
        )
    value = float(getattr(orbit.problem.coefficients, target.param, math.nan))
    return TargetReference(
        key=target.key,
        status=ReferenceStatus.OK.value,
        value=float(bif.value),
        kind=bif.kind,
        category=bif.category,
        detail=bif.detail,
        orbit_value=value,
        t0=float(orbit.t0),
        y0=tuple(float(v) for v in orbit.y0),
        mode0=tuple(int(m) for m in orbit.mode0),
        period=float(orbit.period),
        pattern=tuple(canonical_pattern(tuple(orbit.pattern))),
        max_multiplier=float(orbit.max_multiplier),
        seconds=time.perf_counter() - tic,
    )


def reference_job(target: dict[str, Any], *, stage: Callable = None, emit: Callable = None) -> dict[str, Any]:
    """A :mod:`nsbench.workers.jobs` job: the reference of ``target`` (a :class:`BifurcationTarget` as a dict)."""
    if stage is not None:
        stage("reference location", REFERENCE_LIMIT)
    return compute_target_reference(BifurcationTarget(**target)).as_dict()


def _reference_path(out: Path, key: str) -> Path:
    return out / "bifurcation_references" / f"{key}.json"


def load_target_reference(out: Path, key: str) -> TargetReference | None:
    p = _reference_path(out, key)
    try:
        ref = TargetReference.from_dict(json.loads(p.read_text()))
    except (OSError, ValueError, TypeError):
        return None
    return ref if ref.key == key and ref.ok else None


def save_target_reference(out: Path, ref: TargetReference) -> None:
    from nsbench.files import write_atomic

    p = _reference_path(out, ref.key)
    p.parent.mkdir(parents=True, exist_ok=True)
    write_atomic(p, json.dumps(ref.as_dict(), indent=1))


# ---------------------------------------------------------------------- the integrator's location
def event_names(events: pd.DataFrame) -> list[str]:
    """``kind + block`` of each logged event (``'stick2'``)."""
    if events is None or len(events) == 0:
        return []
    return [f"{k}{int(b)}" for k, b in zip(events["kind"], events["block"])]


def near_side(names: list[str], pattern: tuple[str, ...], periods: int = WINDOW_PERIODS) -> bool:
    """Whether the last ``periods`` periods of events repeat the cyclic ``pattern``.

    The last ``periods * len(pattern)`` events must be one rotation of the
    pattern, repeated: a motion with an extra (or a missing) event per period,
    or no events at all, is on the far side.
    """
    from nsbench.periodic import canonical_pattern

    n = len(pattern)
    if n == 0 or len(names) < periods * n:
        return False
    tail = names[-periods * n :]
    first = tuple(tail[:n])
    return canonical_pattern(first) == tuple(pattern) and all(tail[k] == tail[k % n] for k in range(len(tail)))


def _start_state(problem, y: np.ndarray, mode: tuple[int, ...]) -> np.ndarray:
    """``y`` with the velocity of every sticking block set to this problem's belt speed.

    The engine takes the mode of a start state from the state: a block sticks
    only if its velocity equals ``v0`` exactly, and ``v0`` changes with the probe.
    """
    y = np.array(y, dtype=float)
    v0 = float(problem.coefficients.v0)
    for i, m in enumerate(mode):
        if int(m) == 0:
            y[2 * i + 1] = v0
    return y


@dataclass
class _Probe:
    value: float
    near: bool
    t_end: float
    y_end: np.ndarray
    mode_end: tuple[int, ...]
    n_events: int


class ProbeFailed(Exception):
    """A probe's simulation did not succeed: ``status`` and ``message`` for the row."""

    def __init__(self, status: str, message: str) -> None:
        super().__init__(message)
        self.status, self.message = status, message


def locate_with(
    target: BifurcationTarget,
    ref: TargetReference,
    integrator: str,
    options: dict[str, Any],
    *,
    max_steps: int = 2_000_000,
    stage: Callable[[str, float | None], None] | None = None,
    time_limit: float | None = None,
    setup_limit: float | None = None,
) -> dict[str, Any]:
    """Bisection for ``target`` with the flow of ``integrator(**options)``; the row's result columns.

    Never raises for the integrator's sake: a refusal is ``unsupported``, a
    failing probe its simulation's status with the probe named in ``message``,
    anything else ``error``.
    """
    from nsbench.engine import simulate
    from nsbench.errors import UnsupportedProblemError
    from nsbench.integrators import get_integrator

    out: dict[str, Any] = dict(
        n_probes=0,
        integrator_time=0.0,
        wall_time=0.0,
        setup_time=0.0,
        nfev=0,
        nsteps=0,
        bifurcation_value=math.nan,
        bifurcation_error=math.nan,
        bracket_width=math.nan,
        bracket_low_found=math.nan,
        bracket_high_found=math.nan,
        message="",
    )
    pattern = tuple(ref.pattern)
    start = (ref.t0, np.array(ref.y0, dtype=float), tuple(ref.mode0))
    near_value = target.low if target.near_is_low else target.high
    far_value = target.high if target.near_is_low else target.low
    integ = None

    def probe(value: float, frm: tuple[float, np.ndarray, tuple[int, ...]]) -> _Probe:
        nonlocal integ
        k = out["n_probes"] + 1
        problem = target.problem_at(value)
        if integ is None:
            integ = get_integrator(integrator, **options)
            if stage is not None:
                stage("setup", setup_limit)  # as for the cases: the suite's setup_limit
            integ.setup(problem)
        if stage is not None:
            stage(f"probe {k} at {target.param} = {value:.12g}", time_limit)
        t0, y0, mode0 = frm
        span = target.periods * ref.period
        res = simulate(
            problem, integ, t0 + span, t0=t0, y0=_start_state(problem, y0, mode0), max_steps=max_steps, check_points=0
        )
        out["n_probes"] = k
        out["wall_time"] += float(res.wall_time)
        out["setup_time"] += float(res.setup_time)
        inner = float(getattr(res, "integrator_time", math.nan))
        out["integrator_time"] += inner
        counters = res.counters.as_dict()
        out["nfev"] += int(counters.get("nfev", 0))
        out["nsteps"] += int(counters.get("nsteps", 0))
        if not res.ok:
            raise ProbeFailed(
                res.status.value, f"probe {k} at {target.param} = {value:.12g}: {res.status.value}: {res.message}"
            )
        names = event_names(res.events)
        return _Probe(
            value,
            near_side(names, pattern),
            float(res.t_final),
            np.array(res.y_final, dtype=float),
            tuple(int(m) for m in res.mode_final),
            len(names),
        )

    try:
        if not ref.ok:
            return {
                **out,
                "status": Status.NO_REFERENCE.value,
                "message": f"the target's {ref.status}",  # its status reads "reference failed: why"
            }
        near = probe(near_value, start)
        if not near.near:
            return {
                **out,
                "status": Status.NO_BRACKET.value,
                "message": (
                    f"at the near end {target.param} = {near_value:g} the last {WINDOW_PERIODS} periods do not repeat "
                    f"the reference pattern {' '.join(pattern)} ({near.n_events} events)"
                ),
            }
        far = probe(far_value, start)
        if far.near:
            return {
                **out,
                "status": Status.NO_BRACKET.value,
                "message": (
                    f"at the far end {target.param} = {far_value:g} the motion still repeats the near-side pattern "
                    f"{' '.join(pattern)}: no change of the pattern in the bracket"
                ),
            }
        a, b = near.value, far.value  # a: near side (with its end state), b: far side
        last_near = near

        def closest(value: float) -> tuple[float, np.ndarray, tuple[int, ...]]:
            """Start where the orbit is known nearest to ``value``: the reference orbit or the latest near probe."""
            if abs(value - last_near.value) < abs(value - ref.orbit_value):
                return last_near.t_end, last_near.y_end, last_near.mode_end
            return start

        while abs(b - a) > target.xtol and out["n_probes"] < target.max_probes:
            mid = 0.5 * (a + b)
            if mid in (a, b):  # the bracket is as narrow as doubles allow
                break
            p = probe(mid, closest(mid))
            if p.near:
                a, last_near = mid, p
            else:
                b = mid
        value = 0.5 * (a + b)
        width = abs(b - a)
        status = STATUS_OK if width <= target.xtol or 0.5 * (a + b) in (a, b) else Status.PROBE_BUDGET.value
        out.update(
            bifurcation_value=value,
            bifurcation_error=abs(value - ref.value),
            bracket_width=width,
            bracket_low_found=min(a, b),
            bracket_high_found=max(a, b),
            status=status,
        )
        if status != STATUS_OK:
            out["message"] = (
                f"probe budget of {target.max_probes} used with the bracket still {width:.3g} wide "
                f"(xtol {target.xtol:g})"
            )
        return out
    except ProbeFailed as exc:
        return {**out, "status": exc.status, "message": exc.message}
    except UnsupportedProblemError as exc:
        return {**out, "status": Status.UNSUPPORTED.value, "message": str(exc)}
    except Exception as exc:  # noqa: BLE001 - a row, never a lost run
        return {
            **out,
            "status": Status.ERROR.value,
            "message": (
                f"{type(exc).__name__}: {exc} | " + traceback.format_exc(limit=3).strip().splitlines()[-2].strip()
            ),
        }


# ---------------------------------------------------------------------- rows
#: ``(column, meaning)`` of a bifurcation-target row.
COLUMNS: tuple[tuple[str, str], ...] = (
    ("row_id", "stable id of (target, integrator config): the row's file name"),
    ("suite", "suite name"),
    ("target", "target name"),
    ("problem", "registered problem name"),
    ("case", "problem preset"),
    ("problem_label", "the problem with its fixed overrides"),
    ("param", "the parameter varied"),
    ("bracket_low", "the bracket searched, low end"),
    ("bracket_high", "the bracket searched, high end"),
    ("origin", "where the reference orbit is found from rest (the near side)"),
    ("integrator", "registered integrator name"),
    ("integrator_config", "JSON: the dict that rebuilds the integrator"),
    ("options", "JSON: the options the suite set"),
    ("level", "index of the option set, loose to tight"),
    ("step_option", "name of the integrator's step/tolerance option"),
    ("step_value", "value of that option"),
    (
        "status",
        "success, probe budget, no bracket, no reference, unsupported, error, time limit, crashed, "
        "or the status of the probe simulation that failed",
    ),
    ("message", "why, when not success"),
    ("bifurcation_value", "the integrator's bifurcation: midpoint of its final bracket"),
    ("bifurcation_error", "|bifurcation_value - reference_value|"),
    ("bracket_width", "width of the final bracket"),
    ("n_probes", "simulations (probes) run, the two ends included"),
    ("periods", "reference periods simulated per probe"),
    ("xtol", "bracket width at which the bisection stops"),
    ("integrator_time", "seconds inside the integrator, summed over the probes (its own clock)"),
    ("wall_time", "seconds of the probes' runs, summed (setup apart)"),
    ("setup_time", "seconds of setup (compilation, operators), summed over the probes"),
    ("nfev", "right-hand-side evaluations, summed over the probes"),
    ("nsteps", "steps or segments, summed over the probes"),
    ("reference_value", "the bifurcation located on the reference flow (nsbench.periodic.locate_target)"),
    ("reference_kind", "its kind (grazing-sliding, ...)"),
    ("reference_pattern", "the cyclic event pattern of the orbit on the near side"),
    ("reference_status", "'ok' or why the reference could not be computed"),
    ("timestamp", "UTC time the row finished"),
)
COLUMN_NAMES = tuple(c for c, _ in COLUMNS)
_FLOATS = (
    "bracket_low",
    "bracket_high",
    "origin",
    "step_value",
    "bifurcation_value",
    "bifurcation_error",
    "bracket_width",
    "xtol",
    "integrator_time",
    "wall_time",
    "setup_time",
    "reference_value",
)
_INTS = ("level", "n_probes", "periods", "nfev", "nsteps")
#: Folder of the rows and the names of the exports in an output directory.
ROWS_DIR = "bifurcation_targets"
EXPORT = "bifurcation_targets"


@dataclass(frozen=True)
class Location:
    """One row to compute: a target and an integrator configuration."""

    target: BifurcationTarget
    integrator: str
    options: dict[str, Any]
    level: int

    @property
    def row_id(self) -> str:
        from nsbench.bench.keys import stable_key

        target = {k: v for k, v in self.target.as_dict().items() if k != "exclude"}
        return stable_key(
            {"target": {**target, "ref_xtol": REFERENCE_XTOL}, "integrator": self.integrator, "options": self.options}
        )


def base_row(loc: Location, suite: str, ref: TargetReference | None) -> dict[str, Any]:
    from nsbench.bench.keys import jsonable
    from nsbench.integrators import get_integrator, integrator_class

    t = loc.target
    step_option = integrator_class(loc.integrator).capabilities.step_option
    try:
        config = get_integrator(loc.integrator, **loc.options).config()
    except Exception:  # noqa: BLE001 - validated when the suite was expanded
        config = {"name": loc.integrator, "options": dict(loc.options)}
    step = config["options"].get(step_option) if step_option else None
    row: dict[str, Any] = {c: None for c in COLUMN_NAMES}
    row.update(
        row_id=loc.row_id,
        suite=suite,
        target=t.name,
        problem=t.problem,
        case=str(t.case),
        problem_label=t.label(),
        param=t.param,
        bracket_low=t.low,
        bracket_high=t.high,
        origin=t.origin,
        integrator=loc.integrator,
        integrator_config=jsonable(config),
        options=jsonable(loc.options),
        level=loc.level,
        step_option=step_option or "",
        step_value=float(step) if isinstance(step, (int, float)) else math.nan,
        periods=t.periods,
        xtol=t.xtol,
        message="",
    )
    if ref is not None:
        row.update(
            reference_value=ref.value,
            reference_kind=ref.kind,
            reference_pattern=" ".join(ref.pattern),
            reference_status=ref.status,
        )
    return row


def finish(row: dict[str, Any]) -> dict[str, Any]:
    row["timestamp"] = _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds")
    return row


def compute_row(
    loc: Location,
    ref: TargetReference,
    suite: str = "suite",
    *,
    max_steps: int = 2_000_000,
    stage: Callable | None = None,
    time_limit: float | None = None,
    setup_limit: float | None = None,
) -> dict[str, Any]:
    """The row of ``loc``: :func:`locate_with` and the identity columns; never raises for the integrator."""
    row = base_row(loc, suite, ref)
    row.update(
        locate_with(
            loc.target,
            ref,
            loc.integrator,
            loc.options,
            max_steps=max_steps,
            stage=stage,
            time_limit=time_limit,
            setup_limit=setup_limit,
        )
    )
    return finish(row)


def location_job(
    loc: Location,
    ref: dict[str, Any],
    suite: str,
    max_steps: int,
    time_limit: float,
    setup_limit: float | None = None,
    *,
    stage: Callable = None,
    emit: Callable = None,
) -> dict[str, Any]:
    """A :mod:`nsbench.workers.jobs` job: the row of ``loc``, each probe a stage limited to ``time_limit`` seconds
    (the integrator's setup to ``setup_limit``)."""
    return compute_row(
        loc,
        TargetReference.from_dict(ref),
        suite,
        max_steps=max_steps,
        stage=stage,
        time_limit=time_limit,
        setup_limit=setup_limit,
    )


def to_frame(rows) -> pd.DataFrame:
    frame = pd.DataFrame(list(rows))
    for c in COLUMN_NAMES:
        if c not in frame:
            frame[c] = None
    frame = frame[list(COLUMN_NAMES)].copy()
    for c in _FLOATS:
        frame[c] = pd.to_numeric(frame[c], errors="coerce").astype("float64")
    for c in _INTS:
        frame[c] = pd.to_numeric(frame[c], errors="coerce").astype("Int64")
    for c in set(COLUMN_NAMES) - set(_FLOATS) - set(_INTS):
        frame[c] = frame[c].map(lambda v: "" if v is None or (isinstance(v, float) and v != v) else str(v))
    return frame


def row_path(out: str | Path, row_id: str) -> Path:
    from nsbench.bench.storage import file_name

    return Path(out) / ROWS_DIR / f"{file_name(row_id, 'row id')}.parquet"


def store_row(out: str | Path, row: dict[str, Any], provenance: dict[str, Any]) -> Path:
    """Store one finished row as ``OUT/bifurcation_targets/<row_id>.parquet`` (atomically)."""
    from nsbench.bench.storage import _table, _write_atomic

    path = row_path(out, row["row_id"])
    path.parent.mkdir(parents=True, exist_ok=True)
    _write_atomic(_table(to_frame([row]), provenance), path)
    return path


def done_rows(out: str | Path) -> set[str]:
    """Ids of the rows stored (readable) in ``out``; a damaged file is deleted (its row runs again)."""
    import sys

    from nsbench.bench.storage import read_table_checked

    d = Path(out) / ROWS_DIR
    done = set()
    for f in sorted(d.glob("*.parquet")) if d.is_dir() else []:
        try:
            frame = read_table_checked(f).to_pandas()  # its values checked against their checksum
            ok = len(frame) == 1 and str(frame["row_id"].iloc[0]) == f.name[: -len(".parquet")]
        except Exception:  # noqa: BLE001 - truncated, foreign, changed
            ok = False
        if ok:
            done.add(f.name[: -len(".parquet")])
        else:
            print(f"nsbench: warning: {f} is damaged; its row runs again", file=sys.stderr)
            f.unlink(missing_ok=True)
    return done


def clear_rows(out: str | Path) -> None:
    """Delete the stored rows and references (``--fresh``): only the files nsbench writes there."""
    for sub, ext in ((ROWS_DIR, ".parquet"), ("bifurcation_references", ".json")):
        d = Path(out) / sub
        if d.is_dir():
            for f in d.iterdir():
                if f.is_file() and (f.name.endswith(ext) or f.name.endswith(ext + ".tmp")):
                    f.unlink()


def load_rows(out: str | Path) -> pd.DataFrame:
    """Every bifurcation-target row of an output directory (rows or the export); empty if none."""
    o = Path(out)
    d = o / ROWS_DIR
    files = sorted(d.glob("*.parquet")) if d.is_dir() else []
    if files:
        frame = to_frame(r for f in files for r in pd.read_parquet(f).to_dict("records"))
    elif (o / f"{EXPORT}.parquet").exists():
        frame = to_frame(pd.read_parquet(o / f"{EXPORT}.parquet").to_dict("records"))
    else:
        return to_frame([])
    return frame.sort_values(["target", "integrator", "level"], kind="stable", ignore_index=True)


def export_rows(out: str | Path, provenance: dict[str, Any]) -> pd.DataFrame:
    """Write ``bifurcation_targets.parquet`` and ``.csv`` ('#' provenance lines first) from the stored rows."""
    from nsbench.bench.storage import _table, _write_atomic, write_csv

    o = Path(out)
    frame = load_rows(o)
    _write_atomic(_table(frame, provenance), o / f"{EXPORT}.parquet")
    write_csv(frame, o / f"{EXPORT}.csv", provenance)
    return frame


# ---------------------------------------------------------------------- the runner's phase
def locations(suite) -> list[Location]:
    """Every (target, configuration) of ``suite``: its integrators at their levels, reference-grade ones left out."""
    from nsbench.bench.summary import reference_grade

    plan = [(name, suite.option_sets(name)) for name in suite.integrator_names() if not reference_grade(name)]
    return [
        Location(t, name, options, level)
        for t in suite.target_list()
        for name, sets in plan
        if name not in t.exclude
        for level, options in sets
    ]


def run_targets(
    suite,
    out: str | Path,
    provenance: dict[str, Any],
    *,
    workers: int = 1,
    in_process: bool = False,
    components: dict[str, dict[str, Any]] | None = None,
    resume: bool = True,
    stream: TextIO | None = None,
    progress: bool = True,
) -> pd.DataFrame:
    """The runner's last phase: every missing bifurcation-target row of ``suite``, stored as it finishes.

    References first (cached per target in ``OUT/bifurcation_references``), then
    one job per row in supervised worker processes (:mod:`nsbench.workers.jobs`): each
    probe may take ``suite.time_limit`` seconds; a worker that crashes or is
    ended gives a ``crashed`` or ``time limit`` row. ``in_process`` runs
    everything here (components defined in ``__main__``). Returns every stored row.
    """
    import sys

    from nsbench.progress import Progress

    err = stream or sys.stderr
    o = Path(out)
    if not resume:
        clear_rows(o)
    locs = locations(suite)
    if not locs:
        return load_rows(o)
    done = done_rows(o)
    pending = [loc for loc in locs if loc.row_id not in done]
    refs: dict[str, TargetReference] = {}
    todo = {}
    for loc in pending:
        key = loc.target.key
        if key in refs or key in todo:
            continue
        cached = load_target_reference(o, key)
        if cached is not None:
            refs[key] = cached
        else:
            todo[key] = loc.target
    weight = _location_weights(pending)
    ref_weight = statistics.median(weight.values()) if weight else 1.0
    bar = Progress(
        len(todo) * ref_weight + sum(weight.values()),
        label="bifurcation targets",
        stream=err,
        enabled=progress and bool(pending),
        weighted=True,
    )
    suite_name = suite.name

    def got_reference(key: str, ref: TargetReference) -> None:
        refs[key] = ref
        if ref.ok:
            save_target_reference(o, ref)
        else:
            print(
                f"nsbench: warning: the reference of bifurcation target {todo[key].name!r} could not be "
                f"computed: {ref.status}",
                file=err,
            )
        bar.update(ref_weight, f"reference {todo[key].name}")

    def got_row(row: dict[str, Any]) -> None:
        store_row(o, row, provenance)
        bar.update(weight.get(row["row_id"], ref_weight), f"{row['target']} {row['integrator']}")

    try:
        if in_process:
            for key, target in todo.items():
                got_reference(key, compute_target_reference(target))
            for loc in pending:
                got_row(compute_row(loc, refs[loc.target.key], suite_name, max_steps=suite.max_steps))
        elif pending:
            _run_pooled(suite, o, provenance, workers, components or {}, todo, pending, refs, got_reference, got_row)
    finally:
        bar.close()
    return export_rows(o, provenance) if (o / ROWS_DIR).is_dir() else load_rows(o)


def _location_weights(pending: list[Location]) -> dict[str, float]:
    """Row id -> the expected seconds of its location (the packaged cost table; the median where it
    is unknown): the weights of the progress bar's steps."""
    from nsbench.bench.estimate import CostTable, location_label

    table = CostTable.packaged()
    known = table.target if table is not None else {}
    typical = statistics.median(known.values()) if known else 1.0
    return {
        loc.row_id: known.get(location_label(loc.target.name, loc.integrator, loc.options), typical) for loc in pending
    }


def _run_pooled(suite, out: Path, provenance, workers, components, todo, pending, refs, got_reference, got_row) -> None:
    from nsbench.workers import pool as wp
    from nsbench.workers.jobs import Job, JobPool

    hello = wp.hello(components, out, provenance)
    n = max(1, min(int(workers), max(len(todo), len(pending))))
    with JobPool(n, hello) as jobs:
        for key, target in todo.items():
            jobs.submit(Job(("ref", key), "nsbench.bench.targets:reference_job", (target.as_dict(),)))
        for o in jobs.outcomes():
            if not o.final:
                continue
            key = o.key[1]
            if o.kind is OutcomeKind.DONE:
                got_reference(key, TargetReference.from_dict(o.value))
            else:
                got_reference(key, TargetReference(key, ReferenceStatus.failed(f"{o.kind}: {o.reason}")))
        by_id = {loc.row_id: loc for loc in pending}
        for loc in pending:
            ref = refs[loc.target.key]
            jobs.submit(
                Job(
                    loc.row_id,
                    "nsbench.bench.targets:location_job",
                    (
                        loc,
                        ref.as_dict(),
                        suite.name,
                        suite.max_steps,
                        float(suite.time_limit),
                        float(suite.setup_limit),
                    ),
                )
            )
        for o in jobs.outcomes():
            if not o.final:
                continue
            if o.kind is OutcomeKind.DONE:
                got_row(o.value)
                continue
            loc = by_id[o.key]
            row = base_row(loc, suite.name, refs[loc.target.key])
            status = o.kind.status.value
            row.update(status=status, message=f"{o.reason} ({o.stage})" if o.stage else o.reason)
            got_row(finish(row))


# ---------------------------------------------------------------------- report
TABLE_CAPTION = (
    "Bifurcation-point error: each integrator configuration locates the target's bifurcation "
    "with its own flow (bisection on the event pattern of its own simulations, started on the "
    "periodic orbit; the two ends of the bracket probed first), against the value located on the "
    "reference flow by continuation (nsbench.periodic.locate_target). cost: the integrator's own "
    "time summed over the probes (setup apart); wall: the probes' whole runs. An error at the "
    "size of xtol (1e-10) is the bisection's resolution, not the integrator's."
)


def report_table(rows: pd.DataFrame) -> pd.DataFrame:
    """The report's table: target, integrator, options, status, value, error, probes, cost."""
    from nsbench.bench.labels import options_text

    if rows.empty:
        return pd.DataFrame()
    view = rows.assign(options=rows["options"].map(options_text))
    view = view[
        [
            "target",
            "integrator",
            "level",
            "options",
            "status",
            "bifurcation_value",
            "bifurcation_error",
            "n_probes",
            "integrator_time",
            "wall_time",
            "message",
        ]
    ]
    view = view.rename(columns={"integrator_time": "cost (s)", "wall_time": "wall (s)", "n_probes": "probes"})
    view["bifurcation_value"] = view["bifurcation_value"].map(lambda v: "" if v != v else f"{v:.12g}")
    return view.reset_index(drop=True)


def reference_table(rows: pd.DataFrame) -> pd.DataFrame:
    """One line per target: its problem, bracket and reference value, kind and near-side pattern."""
    if rows.empty:
        return pd.DataFrame()
    first = rows.groupby("target", sort=False).first().reset_index()
    out = first[
        [
            "target",
            "problem_label",
            "param",
            "bracket_low",
            "bracket_high",
            "origin",
            "reference_value",
            "reference_kind",
            "reference_pattern",
            "reference_status",
        ]
    ].copy()
    out["reference_value"] = out["reference_value"].map(lambda v: "" if v != v else f"{v:.12g}")
    return out


def report_figures(rows: pd.DataFrame, out: str | Path) -> list:
    """Per target: bifurcation-point error against cost (log-log), one marker per configuration."""
    from nsbench.bench.figures import ERROR_FLOOR, Figure, _legend_outside, _save, _styles, slug
    from nsbench.plotting import pyplot

    figures: list[Figure] = []
    if rows.empty:
        return figures
    plt = pyplot()
    styles = _styles(sorted(rows["integrator"].unique()))
    for target, group in rows.groupby("target", sort=True):
        fig, ax = plt.subplots(figsize=(6.4, 4.6))
        ok = group[group["bifurcation_error"].notna() & (group["integrator_time"] > 0)]
        for name, g in ok.groupby("integrator", sort=True):
            g = g.sort_values("level")
            x = g["integrator_time"].to_numpy(dtype=float)
            y = np.maximum(g["bifurcation_error"].to_numpy(dtype=float), ERROR_FLOOR)
            st = styles[name]
            ax.plot(x, y, "-", marker=st["marker"], color=st["color"], lw=1.0, ms=6, label=name)
        xtol = float(group["xtol"].dropna().iloc[0]) if group["xtol"].notna().any() else math.nan
        if math.isfinite(xtol):
            ax.axhline(xtol, color="0.5", lw=0.8, ls=":")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("integrator time summed over the probes (s)")
        ax.set_ylabel("|bifurcation value - reference|")
        ax.set_title(f"{target}: bifurcation-point error vs cost")
        ax.grid(True, which="major", alpha=0.3)
        _legend_outside(ax)
        dropped = len(group) - len(ok)
        caption = (
            f"Bifurcation target {target} ({group['param'].iloc[0]} in [{group['bracket_low'].iloc[0]:g}, "
            f"{group['bracket_high'].iloc[0]:g}]): the error of the bifurcation value each configuration "
            "locates with its own flow against the integrator's time summed over its probes, one marker "
            "per configuration, lines through an integrator's levels (loose to tight); colours by method "
            "family as in the other figures. The dotted line is the bisection tolerance."
        )
        if dropped:
            caption += f" {dropped} configuration(s) without a located value (see the table) are not drawn."
        figures.append(
            _save(fig, Path(out), f"bif_{slug(target)}", f"{target}: bifurcation-point error vs cost", caption)
        )
    return figures
