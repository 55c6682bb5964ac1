"""Incremental, resumable storage of a sweep: a folder of atomically written chunk files.

``meta.json`` holds the sweep specification and the provenance of the first
run; ``points/`` holds one CSV per finished chunk of parameter values, written
to a temporary name and renamed, so a killed run leaves only whole chunks.
Rerunning with the same specification computes only the missing values; a
different specification in the same folder is refused.
"""

from __future__ import annotations

import json
import os
import uuid
from pathlib import Path

import pandas as pd

from nsbench.bifurcation.sweep import SweepSpec, counter_columns
from nsbench.errors import ConfigError


class SweepStore:
    """The results folder of one sweep.

    Parameters
    ----------
    directory
        Folder (created if needed).
    spec
        The sweep; if the folder already holds another sweep, ``ConfigError``.
        ``None`` opens an existing folder read-only (its spec from ``meta.json``).
    """

    def __init__(self, directory: str | os.PathLike, spec: SweepSpec | None = None) -> None:
        self.directory = Path(directory)
        self.points_dir = self.directory / "points"
        meta_path = self.directory / "meta.json"
        if meta_path.exists():
            meta = json.loads(meta_path.read_text())
            stored = SweepSpec.from_dict(meta["spec"])
            self._columns: tuple[str, ...] | None = tuple(meta.get("columns", ())) or None
            if spec is not None and _canonical(stored) != _canonical(spec):
                raise ConfigError(
                    f"{self.directory} holds a different sweep ({_describe(stored)}); "
                    f"use another --out for {_describe(spec)}")
            self.spec = stored
            self.meta = meta
        else:
            if spec is None:
                raise ConfigError(f"{self.directory} holds no sweep (no meta.json)")
            from nsbench.provenance import provenance

            self.spec = spec
            self._columns = spec.columns
            self.meta = {"spec": spec.to_dict(), "columns": list(self._columns), "provenance": provenance()}
            self.points_dir.mkdir(parents=True, exist_ok=True)
            _atomic_write(meta_path, json.dumps(self.meta, indent=2, default=str))
        self.points_dir.mkdir(parents=True, exist_ok=True)

    @property
    def columns(self) -> tuple[str, ...]:
        """The tidy columns of this sweep (the problem's state names and per-block counters)."""
        if self._columns is None:  # a store written before the columns were kept in meta.json
            self._columns = self.spec.columns
        return self._columns

    @property
    def state_names(self) -> tuple[str, ...]:
        """``x1, v1, ..., xn, vn`` of the swept problem."""
        cols = self.columns
        return tuple(cols[cols.index("t") + 1: cols.index("event_block")])

    def write(self, frame: pd.DataFrame) -> Path:
        """Store the rows of some finished parameter values (one chunk file)."""
        first = int(frame["index"].min())
        path = self.points_dir / f"chunk-{first:06d}-{uuid.uuid4().hex[:8]}.csv"
        tmp = path.with_suffix(".tmp")
        frame.loc[:, list(self.columns)].to_csv(tmp, index=False, float_format="%.17g")
        os.replace(tmp, path)
        return path

    def load(self) -> pd.DataFrame:
        """All stored rows, sorted by parameter index and point index (one row per value kept once)."""
        files = sorted(self.points_dir.glob("chunk-*.csv"))
        if not files:
            return pd.DataFrame(columns=list(self.columns))
        text = {c: str for c in ("param", "section", "status", "message")}
        frame = pd.concat([pd.read_csv(f, dtype=text, keep_default_na=False, na_values={"t": [""]})
                           for f in files], ignore_index=True)
        for col in ("t", *self.state_names):
            frame[col] = pd.to_numeric(frame[col], errors="coerce")
        # a value computed twice (two runs racing on one folder) keeps its first copy
        frame = frame.drop_duplicates(subset=["index", "k"], keep="first")
        return frame.sort_values(["index", "k"], kind="stable").reset_index(drop=True)

    def done(self) -> set[int]:
        """Indices of the parameter values already stored."""
        files = sorted(self.points_dir.glob("chunk-*.csv"))
        out: set[int] = set()
        for f in files:
            out.update(pd.read_csv(f, usecols=["index"])["index"].astype(int).tolist())
        return out

    def missing(self) -> list[int]:
        done = self.done()
        return [i for i in range(self.spec.count) if i not in done]


def points_summary(frame: pd.DataFrame) -> pd.DataFrame:
    """One row per parameter value: status, message, points and counters (of every block)."""
    cols = ["index", "value", "status", "message", "n_points", *counter_columns(n_blocks_of(frame)), "wall_time"]
    return frame.groupby("index", sort=True).first().reset_index()[cols]


def n_blocks_of(frame: pd.DataFrame) -> int:
    """Number of blocks of a sweep table (its ``x1, x2, ...`` columns)."""
    n = 0
    while f"x{n + 1}" in frame.columns:
        n += 1
    return n


def _canonical(spec: SweepSpec) -> str:
    from nsbench.integrators import canonical_name

    # an alias (exact-jit) names the same integrator: a store that recorded it resumes
    return json.dumps({**spec.to_dict(), "integrator": canonical_name(spec.integrator)}, sort_keys=True,
                      default=str)


def _describe(spec: SweepSpec) -> str:
    return (f"{spec.problem} case {spec.case}, {spec.name} = {spec.start:g}:{spec.stop:g}:{spec.count}, "
            f"{spec.integrator}, {spec.section}")


def _atomic_write(path: Path, text: str) -> None:
    tmp = path.with_suffix(path.suffix + ".tmp")
    tmp.write_text(text)
    os.replace(tmp, path)


