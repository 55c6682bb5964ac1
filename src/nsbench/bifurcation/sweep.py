"""One bifurcation sweep: its specification and the computation of one parameter value.

Each point integrates from rest (the standard initial condition) through the
transient, then records ``record`` section points: ``peaks`` (local maxima of
``x1``), ``strobe`` (states at ``t = 2 pi k / Omega``), ``stick`` (stick events)
or ``mapping`` (slip events: where the locus of sticking phase leaves a
sliding region). Compiled integrators (``exact-jit``, ``henon-rk4-jit``) run the
whole hybrid loop compiled; any other registered integrator runs through the
ordinary engine, window by window.
"""

from __future__ import annotations

import math
import time
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np
import pandas as pd

from nsbench.errors import ConfigError, NsbenchError

SECTIONS = ("peaks", "strobe", "stick", "mapping")
#: statuses of a value whose points are usable: ``rest`` is a motion that came to rest
#: (pure sliding damped out) before ``record`` points: its final state is its one point
OK_STATUSES = ("success", "rest")
REST_SPEED = 1e-9
STATE_COLUMNS = ("x1", "v1", "x2", "v2")
COUNTER_COLUMNS = ("n_events", "sticks1", "sticks2", "slips1", "slips2", "reverses1", "reverses2",
                   "nfev", "nsteps")
COLUMNS = ("param", "value", "index", "section", "k", "t", *STATE_COLUMNS, "event_block", "status",
           "message", "n_points", *COUNTER_COLUMNS, "wall_time")


def parse_sweep(text: str) -> tuple[str, float, float, int]:
    """``NAME=START:STOP:COUNT`` as ``(name, start, stop, count)``."""
    name, sep, rng = text.partition("=")
    parts = rng.split(":")
    if not sep or not name.strip() or len(parts) != 3:
        raise ConfigError(f"--sweep expects NAME=START:STOP:COUNT, got {text!r}")
    try:
        start, stop = float(parts[0]), float(parts[1])
        count = float(parts[2])
    except ValueError:
        raise ConfigError(f"--sweep {text!r}: START, STOP must be numbers and COUNT an integer") from None
    if not (math.isfinite(start) and math.isfinite(stop)):
        raise ConfigError(f"--sweep {text!r}: START and STOP must be finite")
    if count != int(count) or count < 1:
        raise ConfigError(f"--sweep {text!r}: COUNT = {parts[2]} must be a positive integer")
    return name.strip(), start, stop, int(count)


@dataclass(frozen=True)
class SweepSpec:
    """Everything that defines a sweep (and its stored results).

    Attributes
    ----------
    problem, case, params
        Registered problem, preset and fixed parameter overrides (dimensionless).
    name, start, stop, count
        The swept parameter and its grid ``linspace(start, stop, count)``.
    integrator, options
        Registered integrator and its options.
    section
        ``peaks``, ``strobe``, ``stick`` or ``mapping``.
    transient, record
        Time integrated before recording, and section points recorded per value.
    window
        Longest time after the transient spent collecting the points.
    """

    problem: str
    case: int
    name: str
    start: float
    stop: float
    count: int
    integrator: str = "exact-jit"
    options: dict[str, Any] = field(default_factory=dict)
    section: str = "peaks"
    transient: float = 1500.0
    record: int = 100
    window: float | None = None
    params: dict[str, float] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.section not in SECTIONS:
            raise ConfigError(f"section {self.section!r} is not allowed; choose one of {', '.join(SECTIONS)}")
        if not (math.isfinite(self.transient) and self.transient >= 0):
            raise ConfigError(f"transient = {self.transient!r} must be a finite number >= 0")
        if int(self.record) != self.record or self.record < 1:
            raise ConfigError(f"record = {self.record!r} must be a positive integer")
        if self.window is not None and not (math.isfinite(self.window) and self.window > 0):
            raise ConfigError(f"window = {self.window!r} must be a finite number > 0")
        if self.name in self.params:
            raise ConfigError(f"parameter {self.name} is both swept and fixed")

    @property
    def values(self) -> np.ndarray:
        return np.linspace(self.start, self.stop, self.count)

    @property
    def record_window(self) -> float:
        return self.window if self.window is not None else 40.0 * self.record + 400.0

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> "SweepSpec":
        return cls(**d)

    def problem_at(self, value: float):
        """The problem at one parameter value (raises ``ConfigError`` on a bad value)."""
        from nsbench.problems import get_problem

        return get_problem(self.problem, case=self.case, **{**self.params, self.name: float(value)})

    def check(self) -> None:
        """Fail early: build the problem at both ends and the integrator, check the section."""
        from nsbench.integrators import get_integrator

        ends = [self.problem_at(v) for v in (self.start, self.stop)]
        if self.section == "strobe":
            # the forcing period must exist everywhere; F may be 0 at one end of an F sweep
            for v, problem in zip((self.start, self.stop), ends):
                if problem.coefficients.w <= 0:
                    raise ConfigError(f"section strobe needs Omega > 0; at {self.name} = {v:g} "
                                      f"Omega = {problem.coefficients.w:g}")
            if not any(p.is_forced for p in ends):
                raise ConfigError("section strobe needs a harmonic force (F > 0) in the sweep; "
                                  "use peaks, stick or mapping")
        problem = ends[0]
        # an integrator that refuses the problem (exact on cubic springs) fails here, not per point
        get_integrator(self.integrator, **self.options).setup(problem)


def default_section(*problems) -> str:
    """``strobe`` if any of ``problems`` (e.g. both ends of a sweep) is forced, ``peaks`` otherwise."""
    forced = any(p.is_forced for p in problems)
    return "strobe" if forced and all(p.coefficients.w > 0 for p in problems) else "peaks"


def strobe_times(problem, transient: float, record: int) -> np.ndarray:
    """The first ``record`` stroboscopic times ``2 pi k / Omega >= transient``."""
    period = 2.0 * math.pi / problem.coefficients.w
    k0 = math.ceil(transient / period - 1e-12)
    return period * np.arange(k0, k0 + record)


def _rows(spec: SweepSpec, index: int, value: float, t, y, blocks, status: str, message: str,
          counters: dict[str, int], wall: float) -> pd.DataFrame:
    n = len(t)
    states = np.full((max(n, 1), 4), np.nan)
    if n:
        states[:n, : y.shape[1]] = y
    frame = pd.DataFrame({
        "param": spec.name, "value": float(value), "index": int(index), "section": spec.section,
        "k": np.arange(n) if n else np.array([-1]), "t": np.asarray(t, dtype=float) if n else np.array([np.nan]),
    })
    for j, col in enumerate(STATE_COLUMNS):
        frame[col] = states[:, j]
    frame["event_block"] = np.asarray(blocks, dtype=np.int64) if n else np.array([0])
    frame["status"] = status
    frame["message"] = message
    frame["n_points"] = n
    for col in COUNTER_COLUMNS:
        frame[col] = int(counters.get(col, 0))
    frame["wall_time"] = wall
    return frame


def compute_point(spec: SweepSpec, index: int, integrator=None) -> pd.DataFrame:
    """Rows of one parameter value. Failures become a row with their status and reason."""
    from nsbench.integrators import get_integrator

    value = float(spec.values[index])
    tic = time.perf_counter()
    try:
        problem = spec.problem_at(value)
        integ = integrator if integrator is not None else get_integrator(spec.integrator, **spec.options)
        if hasattr(integ, "run"):
            t, y, blocks, status, message, counters = _fast_point(spec, problem, integ)
        else:
            t, y, blocks, status, message, counters = _engine_point(spec, problem, integ)
    except (NsbenchError, ArithmeticError, ValueError, RuntimeError) as exc:
        return _rows(spec, index, value, [], None, [], "failure", f"{type(exc).__name__}: {exc}", {},
                     time.perf_counter() - tic)
    return _rows(spec, index, value, t, y, blocks, status, message, counters, time.perf_counter() - tic)


def _at_rest(y_final, counters) -> bool:
    """No event in the recording window and every velocity ~0: a sliding equilibrium."""
    moved = sum(int(counters.get(k, 0)) for k in ("sticks1", "sticks2", "slips1", "slips2",
                                                   "reverses1", "reverses2"))
    return moved == 0 and float(np.max(np.abs(np.asarray(y_final)[1::2]))) <= REST_SPEED


def _finish(spec, n_found, status, t_last, rest=False) -> tuple[str, str]:
    if status != "success":
        return status, f"stopped at t = {t_last:.6g}"
    if n_found < spec.record and rest:
        return "rest", (f"at rest (sliding equilibrium) by t = {t_last:.6g} after {n_found} "
                        f"{spec.section} points; the final state is recorded")
    if n_found < spec.record:
        return "incomplete", (f"{n_found} of {spec.record} {spec.section} points by t = {t_last:.6g} "
                              f"(window {spec.record_window:g} after the transient)")
    return "success", ""


def _fast_point(spec, problem, integ):
    times = None
    t_end = spec.transient + spec.record_window
    if spec.section == "strobe":
        times = strobe_times(problem, spec.transient, spec.record)
        t_end = float(times[-1])
    run = integ.run(problem, t_end=t_end, section=spec.section, t_rec=spec.transient,
                    n_rec=spec.record, times=times)
    rest = run.n < spec.record and _at_rest(run.y, run.counters)
    status, message = _finish(spec, run.n, run.status, run.t, rest)
    if status == "rest":
        return (np.array([run.t]), run.y[None, :], np.zeros(1, np.int64), status, message, run.counters)
    return run.rec_t, run.rec_y, run.rec_block, status, message, run.counters


def _engine_point(spec, problem, integ):
    """The same point through :func:`nsbench.engine.simulate`, continued window by window."""
    from nsbench.engine import simulate
    from nsbench.sections import peaks, stroboscopic

    sections = []
    if spec.section == "peaks":
        sections = [peaks(problem)]
    elif spec.section == "strobe":
        sections = [stroboscopic(problem)]
    t_stop_all = spec.transient + spec.record_window
    if spec.section == "strobe":
        t_stop_all = float(strobe_times(problem, spec.transient, spec.record)[-1]) + 1e-9
    t0, y0 = 0.0, None
    step = min(spec.record_window, 12.0 * spec.record + 50.0)
    t1 = min(spec.transient + step, t_stop_all)
    found_t, found_y, found_b = [], [], []
    events = []
    counters = {"nfev": 0, "nsteps": 0, "n_events": 0}
    status, t_last = "success", 0.0
    while True:
        res = simulate(problem, integ, t1, t0=t0, y0=y0, sections=sections)
        counters["nfev"] += res.counters.nfev
        counters["nsteps"] += res.counters.nsteps
        counters["n_events"] += res.counters.n_events
        ev = res.events[res.events["t"] >= spec.transient]
        events.append(ev)
        if spec.section in ("stick", "mapping"):
            kind = "stick" if spec.section == "stick" else "slip"
            pts = ev[ev["kind"] == kind]
            found_b.extend(pts["block"].tolist())
        else:
            pts = res.sections[res.sections["t"] >= spec.transient - 1e-9]
            if t0 > 0.0:  # a continued window: its start was the previous window's end
                pts = pts[pts["t"] > t0]
            found_b.extend([1 if spec.section == "peaks" else 0] * len(pts))
        found_t.extend(pts["t"].tolist())
        found_y.extend(pts[list(problem.state_names)].to_numpy().tolist())
        t_last = res.t_final
        if not res.ok:
            status = res.status.value
            break
        if len(found_t) >= spec.record or t1 >= t_stop_all:
            break
        t0, y0 = res.t_final, res.y_final
        step *= 2.0
        t1 = min(t1 + step, t_stop_all)
    n = min(len(found_t), spec.record)
    t = np.array(found_t[:n])
    y = np.array(found_y[:n]).reshape(n, problem.n_states)
    t_cut = t[-1] if n == spec.record else np.inf
    ev = pd.concat(events) if events else pd.DataFrame(columns=["t", "kind", "block"])
    ev = ev[ev["t"] <= t_cut]
    for kind, key in (("stick", "sticks"), ("slip", "slips"), ("reverse", "reverses")):
        for b in (1, 2):
            counters[f"{key}{b}"] = int(((ev["kind"] == kind) & (ev["block"] == b)).sum())
    rest = n < spec.record and status == "success" and _at_rest(res.y_final, counters)
    status, message = _finish(spec, n, status, t_last, rest)
    if status == "rest":
        return np.array([t_last]), np.array(res.y_final)[None, :], np.zeros(1, np.int64), status, message, counters
    return t, y, np.array(found_b[:n]), status, message, counters
