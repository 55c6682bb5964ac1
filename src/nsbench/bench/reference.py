"""References: the run every case of a problem is compared with, computed once and cached.

The reference of a problem is the first integrator of the suite's ``reference``
list that is registered and accepts the problem (``exact`` for linear problems,
the high-precision ``reference`` for cubic ones when it is registered). It is
cached on disk under ``OUT/references/``, keyed by the problem config, the
configs of the registered candidates, the span and the dense grid, so a resumed
run never recomputes it.

Every reference log is certified: an independent second run at higher precision
(:data:`nsbench.certify.CERTIFY_CHECKS`) bounds the error of each event time, stored as the log's
``certified_error`` column (:func:`nsbench.certify.certified_errors`; the certification lives
below the bench, so that ``nsbench simulate --integrator reference`` certifies without it). The metrics never report an
integrator's error below that bound (:mod:`nsbench.bench.metrics`), and the
reference also measures how strongly the case amplifies a change of its start
(:func:`conditioning`).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from nsbench.bench.keys import stable_key
from nsbench.certify import (  # noqa: F401 - certified_errors, certainty_of: the bench's names for them too
    CERTIFIED,
    CERTIFY_CHECKS,
    NOT_CERTIFIED_FROM,
    certainty_of,
    certified_errors,
    compare_logs,
)
from nsbench.errors import UnsupportedProblemError
from nsbench.files import write_atomic
from nsbench.status import ReferenceStatus


#: Size of the perturbation of the start positions that measures a case's conditioning.
PERTURBATION = 1e-9
#: Unit roundoff scale of a double-precision state of order one.
EPS = float(np.finfo(float).eps)
#: A case whose double-precision floor exceeds this cannot be graded in double over its span.
DOUBLE_GRADABLE = 1e-10


def failed_status(status: str) -> bool:
    """Whether a ``reference_status`` says the reference run failed (raised, failed, crashed)."""
    return ReferenceStatus.of(status) is ReferenceStatus.FAILED


@dataclass
class Reference:
    """A reference run (or why there is none): events, dense states and final state."""

    key: str
    name: str | None
    config: dict[str, Any] | None
    status: str  # "ok" or the reason there is no usable reference
    events: pd.DataFrame
    t_dense: np.ndarray
    y_dense: np.ndarray  # (n_states, k)
    y_final: np.ndarray
    wall_time: float = math.nan
    #: A candidate accepted the problem but its run raised, failed or crashed: a
    #: failure of the suite run (unlike "no candidate accepts the problem").
    failed: bool = False
    #: Max switching-time change per unit change of the start (see :func:`conditioning`).
    conditioning: float = math.nan
    #: Where a start perturbation of :data:`PERTURBATION` changed the event sequence ('' if nowhere).
    conditioning_note: str = ""
    #: What certified the event times (the check and where it stopped agreeing), see :func:`certified_errors`.
    certify_note: str = ""

    @property
    def double_floor(self) -> float:
        """Switching-time uncertainty of any double-precision solution from the rounding of its start."""
        return self.conditioning * EPS if math.isfinite(self.conditioning) else self.conditioning

    @property
    def certainty(self) -> float:
        """The largest certified error of the event times (``inf`` if some are not certified, NaN if none)."""
        return certainty_of(self.events)

    def columns(self) -> dict[str, Any]:
        """The reference columns of a benchmark row."""
        return {
            "reference": self.name or "",
            "reference_status": self.status,
            "ref_conditioning": self.conditioning,
            "ref_double_floor": self.double_floor,
            "ref_certainty": self.certainty,
        }

    @property
    def ok(self) -> bool:
        return self.status == ReferenceStatus.OK


def candidates(names: tuple[str, ...] | list[str]) -> list[dict[str, Any]]:
    """Default configs of the registered reference candidates, in order."""
    from nsbench.errors import PluginLoadError
    from nsbench.integrators import get_integrator, list_integrators

    registered = set(list_integrators())
    out = []
    for name in names:
        if name in registered:
            try:
                out.append(get_integrator(name).config())
            except PluginLoadError:  # an uninstallable plug-in is no reference, not a crash
                continue
    return out


def reference_key(
    problem: dict[str, Any], cands: list[dict[str, Any]], t0: float, t_end: float, dense_points: int
) -> str:
    from nsbench import __version__

    return stable_key(
        {
            "problem": problem,
            "candidates": cands,
            "t": [t0, t_end],
            "dense": dense_points,
            "nsbench": __version__,
            "certify": list(CERTIFY_CHECKS),
            # impact problems are certified by a whole hybrid run in mp (issue 48), not arc by arc
            "certify_mp": "whole hybrid run, digits 40 and 50",
        }
    )


def compute_reference(
    problem_config: dict[str, Any], cands: list[dict[str, Any]], t0: float, t_end: float, dense_points: int
) -> Reference:
    """Run the first candidate that accepts the problem (worker-side; no caching here)."""
    from nsbench.engine import simulate
    from nsbench.integrators import integrator_from_config
    from nsbench.problems import problem_from_config

    key = reference_key(problem_config, cands, t0, t_end, dense_points)
    problem = problem_from_config(problem_config)
    grid = np.linspace(t0, t_end, dense_points)
    empty = pd.DataFrame(columns=["t", "kind", "block"])
    refused = []
    for config in cands:
        try:
            res = simulate(problem, integrator_from_config(config), t_end, t0=t0, t_eval=grid, max_steps=10**9)
        except UnsupportedProblemError:
            refused.append(config["name"])
            continue
        except Exception as exc:  # a broken reference must not end the suite
            status = ReferenceStatus.failed(f"{config['name']} raised {type(exc).__name__}: {exc}")
            return Reference(
                key,
                config["name"],
                config,
                status,
                empty,
                grid,
                np.empty((problem.n_states, 0)),
                np.full(problem.n_states, np.nan),
                failed=True,
            )
        if not res.ok:
            status = ReferenceStatus.failed(f"{config['name']} ended with {res.status.value}: {res.message}")
            return Reference(
                key,
                config["name"],
                config,
                status,
                res.events,
                grid,
                np.empty((problem.n_states, 0)),
                res.y_final,
                res.wall_time,
                failed=True,
            )
        dense = res.trajectory[list(problem.state_names)].to_numpy().T
        cond, note = conditioning(problem, config, t0, t_end, res.events)
        events = res.events.copy()
        events[CERTIFIED], certify_note = certified_errors(problem, events, t0, t_end, reference=config["name"])
        status = ReferenceStatus.OK.value
        if NOT_CERTIFIED_FROM in certify_note:
            # its independent check logs other events: which one is right is not known here, so
            # grading against it could blame the integrators that agree with the check
            status = ReferenceStatus.failed(
                f"{config['name']} is not certified ({certify_note}); nothing is graded against it"
            )
        return Reference(
            key,
            config["name"],
            config,
            status,
            events,
            grid,
            dense,
            res.y_final,
            res.wall_time + res.setup_time,
            failed=status != ReferenceStatus.OK,
            conditioning=cond,
            conditioning_note=note,
            certify_note=certify_note,
        )
    if refused:
        reason = "no reference available: " + ", ".join(f"{n} refused the problem" for n in refused)
    else:
        reason = "no reference available: no candidate is registered"
    return Reference(
        key, None, None, reason, empty, grid, np.empty((problem.n_states, 0)), np.full(problem.n_states, np.nan)
    )


def conditioning(problem, config: dict[str, Any], t0: float, t_end: float, events: pd.DataFrame) -> tuple[float, str]:
    """How strongly the case amplifies a change of its start: ``(max |dt_k| / delta, note)``.

    The reference integrator runs again from the start with every position
    moved by ``delta = PERTURBATION`` (positions are free in every mode;
    velocities of stuck blocks are not; by ``-delta`` if ``+delta`` would put the
    start in another mode, as a start on a switching surface), and the switching times of the two
    runs are compared event by event over their common ``(kind, block)``
    prefix. Multiplied by the unit roundoff (:attr:`Reference.double_floor`) it
    is the switching-time uncertainty that the rounding of the start alone gives
    any double-precision solution. If the perturbed run's event sequence differs
    before the end, the amplification there is beyond ``1 / delta`` and the
    result is ``inf`` with the time of the first difference in the note.
    """
    from nsbench.engine import simulate
    from nsbench.integrators import integrator_from_config

    start = np.array(problem.initial_state(), dtype=float)
    y0 = start.copy()
    y0[0::2] += PERTURBATION
    if problem.initial_mode(t0, y0) != problem.initial_mode(t0, start):
        # a start on a switching surface (Henon-Heiles on its section plane): moved the other way, the
        # start keeps its mode, so the comparison measures the flow, not an extra event at t0
        y0 = start.copy()
        y0[0::2] -= PERTURBATION
    try:
        other = simulate(
            problem, integrator_from_config(config), t_end, t0=t0, y0=y0, max_steps=10**9, check_points=0
        ).events
    except Exception as exc:  # a conditioning that cannot be measured is no reason to lose the reference
        return math.nan, f"not measured: {type(exc).__name__}: {exc}"
    dt, at = compare_logs(events, other)
    if at is not None:
        return math.inf, (
            f"a start moved by {PERTURBATION:g} changes the event sequence at t = {at:.6g} "
            f"(event {dt.size + 1} of {len(events)})"
        )
    return (float(dt.max()) / PERTURBATION if dt.size else 0.0), ""


def _paths(directory: Path, key: str) -> tuple[Path, Path, Path]:
    return (directory / f"{key}.json", directory / f"{key}.events.parquet", directory / f"{key}.dense.npy")


def _digest(path: Path) -> str:
    import hashlib

    return hashlib.sha256(path.read_bytes()).hexdigest()


def save_reference(directory: str | Path, ref: Reference) -> None:
    """Write ``ref`` to the cache; the JSON file, with the checksums of the other two, is written last,
    so it marks completion."""
    d = Path(directory)
    d.mkdir(parents=True, exist_ok=True)
    meta, events, dense = _paths(d, ref.key)
    ref.events.to_parquet(events, index=False)
    with open(dense, "wb") as fh:
        np.save(fh, np.vstack([ref.t_dense[None, :], ref.y_dense]) if ref.y_dense.size else ref.t_dense[None, :])
    data = {
        "key": ref.key,
        "name": ref.name,
        "config": ref.config,
        "status": ref.status,
        "y_final": [float(v) for v in ref.y_final],
        "wall_time": ref.wall_time,
        "failed": ref.failed,
        "conditioning": repr(ref.conditioning),
        "conditioning_note": ref.conditioning_note,
        "certify_note": ref.certify_note,
        "sha256": {
            events.name.removeprefix(ref.key): _digest(events),
            dense.name.removeprefix(ref.key): _digest(dense),
        },
    }
    write_atomic(meta, json.dumps(data, indent=1))


def load_reference(directory: str | Path, key: str) -> Reference | None:
    """The cached reference ``key``, or ``None`` if it is not (completely and soundly) cached.

    A damaged cache entry (truncated, edited, a bit flipped, another key's) is
    deleted, with one warning line, so that the reference is computed again:
    the JSON file names its key and holds the SHA-256 of the event table and of
    the dense states (an entry written before checksums were kept passes the
    other checks).
    """
    import sys

    paths = _paths(Path(directory), key)
    meta, events, dense = paths
    if not meta.exists():
        return None
    try:
        data = json.loads(meta.read_text())
        if not isinstance(data, dict) or data.get("key") != key:
            raise ValueError(f"it holds reference {data.get('key') if isinstance(data, dict) else data!r}")
        for path, digest in (
            (events, (data.get("sha256") or {}).get(".events.parquet")),
            (dense, (data.get("sha256") or {}).get(".dense.npy")),
        ):
            if digest is not None and _digest(path) != digest:
                raise ValueError(f"{path.name} does not match its checksum")
        table = np.load(dense, allow_pickle=False)
        t_dense, y_dense = table[0], table[1:]
        ref = Reference(
            key,
            data["name"],
            data["config"],
            data["status"],
            pd.read_parquet(events),
            t_dense,
            y_dense,
            np.array(data["y_final"], dtype=float),
            float(data["wall_time"]),
            bool(data.get("failed", False)),
            float(data.get("conditioning", "nan")),
            str(data.get("conditioning_note", "")),
            str(data.get("certify_note", "")),
        )
        if len(ref.events) and not {"t", "kind", "block"} <= set(ref.events.columns):
            raise ValueError("its event table lacks t, kind or block")
    except (OSError, ValueError, KeyError, TypeError, IndexError, EOFError, AttributeError) as exc:
        print(
            f"nsbench: warning: cached reference {meta} is damaged ({type(exc).__name__}: {exc}); computing it again",
            file=sys.stderr,
        )
        for p in paths:
            p.unlink(missing_ok=True)
        return None
    return ref
