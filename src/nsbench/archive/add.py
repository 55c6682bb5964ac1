"""``nsbench archive add RUN --to ARCHIVE``: a results folder added after re-grading it.

Every row's switching-time errors are graded again (:mod:`nsbench.archive.regrade`), and its state
errors from the dense states the run keeps (a run made before nsbench kept them: its state errors
kept as submitted, ``states_graded`` false and the row marked); if any row's submitted errors
disagree with the re-grading, nothing is added and the outcome names every such row. Rows that cannot be graded here (a problem or reference integrator this nsbench does not
know, a case that did not run) are kept and marked, and so are rows of an integrator plug-in not
installed here (graded all the same: the grading needs only the reference and the log).

The run's bifurcation-target rows (``bifurcation_targets.parquet``, :mod:`nsbench.bench.targets`),
if it has any, are kept as submitted, NOT re-graded: locating a bifurcation again takes the
integrator's own probes (seconds to minutes per row), which the archive does not run.
"""

from __future__ import annotations

import datetime as _dt
import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pandas as pd

from nsbench.archive import layout
from nsbench.archive.regrade import (
    REGRADED,
    STATE_REGRADED,
    Graded,
    dense_points_of,
    disagreement,
    grade_row,
    no_events,
)
from nsbench.bench import storage
from nsbench.bench.history import environment_of
from nsbench.errors import ConfigError
from nsbench.files import refuse_links
from nsbench.status import ReferenceStatus, Status


@dataclass(frozen=True)
class AddOutcome:
    """What ``archive add`` did: the run added (or found already there), or the rows refused."""

    run: layout.Run | None
    refused: list[str] = field(default_factory=list)
    already: bool = False


def machine_of(provenance: dict[str, Any]) -> str:
    """A run's machine when none is named: its CPU and core count, as a folder-safe name."""
    text = f"{provenance.get('cpu') or 'unknown-cpu'}-{provenance.get('cpu_count') or 0}cores"
    cleaned = "".join(c if c.isalnum() or c in "._+-" else "-" for c in text).strip("-.")
    return cleaned[:100] or "unknown"


def _check_kept_logs(frame: pd.DataFrame, run: Path) -> None:
    """``ConfigError`` if a case that ran has no event log: the folder predates nsbench keeping them."""
    ran = frame["status"].astype(str) == Status.SUCCESS.value
    missing = frame[ran & (frame["event_log"].fillna("").astype(str) == "")]
    if len(missing):
        raise ConfigError(
            f"{str(run)!r} keeps no event log for case {missing['case_id'].iloc[0]} (and {len(missing) - 1} more): "
            "it was made by an nsbench that did not keep them, so it cannot be re-graded; run its suite again"
        )


def _row_label(row: pd.Series) -> str:
    return f"{row['case_id']} ({row['integrator']} level {row['level']} on {row['problem_label']})"


def _grade_all(frame: pd.DataFrame, references: Path, dense_points: int) -> tuple[list[Graded], list[str]]:
    graded, refused = [], []
    for _, row in frame.iterrows():
        g = grade_row(row, references, dense_points)
        graded.append(g)
        if g.graded:
            why = disagreement(row, g.values, g.allowed if g.states else None)
            if why:
                refused.append(f"{_row_label(row)}: {why}")
    return graded, refused


def plugin_versions(provenance: dict[str, Any]) -> dict[str, str]:
    """``{component name: note}`` for each plug-in of the run's provenance whose version here is
    another (or that is nsbench's own here): its rows are kept and marked with the note."""
    from nsbench.provenance import plugins

    here = {(p["kind"], p["name"]): p.get("version") for p in plugins()}
    notes = {}
    for entry in provenance.get("plugins") or []:
        if not isinstance(entry, dict) or "name" not in entry:
            continue
        key, version = (str(entry.get("kind")), str(entry["name"])), entry.get("version")
        if key not in here:
            notes[key[1]] = f"plug-in {key[1]} {version} in the run, not a plug-in here"
        elif here[key] != version:
            notes[key[1]] = f"plug-in {key[1]} {version} in the run, {here[key]} here"
    return notes


def _mark(row: pd.Series, g: Graded, versions: dict[str, str]) -> str:
    if not g.graded:
        return g.mark
    own = ReferenceStatus.of(str(row["reference_status"])) is ReferenceStatus.OK
    notes = [n for n in (g.note, g.states_note) if n]
    notes += [versions[name] for name in (str(row["integrator"]), str(row["problem"])) if name in versions]
    if not own:
        notes.append("graded by the archive only (the run had no reference)")
    return "; ".join(notes)


def _tables(
    frame: pd.DataFrame, graded: list[Graded], rid: str, versions: dict[str, str]
) -> tuple[pd.DataFrame, pd.DataFrame]:
    """The archive's rows (the re-graded columns in place of the submitted ones) and event table."""
    records, events = [], []
    for (_, row), g in zip(frame.iterrows(), graded):
        record = row.to_dict()
        record.update({k: v for k, v in g.values.items() if k in REGRADED or (g.states and k in STATE_REGRADED)})
        records.append(record)
        if len(g.events):
            events.append(g.events.assign(run_id=rid, case_id=str(row["case_id"])))
    rows = storage.to_frame(records)
    rows["run_id"] = pd.array([rid] * len(rows), dtype="string")
    rows["graded"] = pd.array([g.graded for g in graded], dtype="boolean")
    rows["states_graded"] = pd.array([g.graded and g.states for g in graded], dtype="boolean")
    rows["mark"] = pd.array([_mark(r, g, versions) for (_, r), g in zip(frame.iterrows(), graded)], dtype="string")
    table = pd.concat(events, ignore_index=True) if events else no_events().assign(run_id="", case_id="")
    table = table[list(layout.EVENT_COLUMNS)].astype({"run_id": "string", "case_id": "string", "kind": "string"})
    return rows, table


def bifurcation_rows(run: Path, rid: str) -> pd.DataFrame | None:
    """The run's bifurcation-target rows as submitted (the bench's columns, then ``run_id``), ``None``
    if it has none."""
    from nsbench.bench import targets

    frame = targets.load_rows(run if run.is_dir() else run.parent)
    if frame.empty:
        return None
    frame["run_id"] = pd.array([rid] * len(frame), dtype="string")
    return frame


def add_run(run: str | Path, archive: str | Path, machine: str | None = None) -> AddOutcome:
    """Re-grade the results folder ``run`` and add it to ``archive`` (created if absent).

    Raises ``ConfigError`` for a folder that cannot be read or re-graded (damaged, no event logs)
    and for an archive of another schema.
    """
    run, archive = Path(run), Path(archive)
    frame = storage.load_results(run)
    prov = storage.read_provenance(run)
    _check_kept_logs(frame, run)
    rid = layout.run_id(frame)
    layout.create(archive)
    refuse_links(archive, (layout.RUNS, layout.REFERENCES), (layout.RUNS, layout.REFERENCES))
    present = {r.run_id: r for r in layout.runs(archive)}
    if rid in present:
        return AddOutcome(present[rid], already=True)
    graded, refused = _grade_all(frame, archive / layout.REFERENCES, dense_points_of(prov))
    if refused:
        return AddOutcome(None, refused=refused)
    rows, events = _tables(frame, graded, rid, plugin_versions(prov))
    environment, versions = environment_of(prov)
    marks = sorted({m for m in rows["mark"].astype(str) if m})
    entry = layout.Run(
        run_id=rid,
        machine=machine or machine_of(prov),
        environment=environment,
        commit=str(prov.get("git_commit") or "unknown"),
        suite=",".join(sorted(set(frame["suite"].astype(str)))),
        added=_dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
        source=str(run.resolve()),
        n_rows=len(rows),
        n_graded=int(rows["graded"].sum()),
        marks=marks,
        versions=json.loads(json.dumps(versions, default=str)),
    )
    return AddOutcome(layout.write_run(archive, entry, rows, events, prov, bifurcation_rows(run, rid)))


@dataclass(frozen=True)
class ArchiveAddRequest:
    """What ``archive add`` asks for, checked at its construction (a :class:`~nsbench.errors.ConfigError`
    naming the value before anything is read or written).

    Attributes
    ----------
    run
        A results folder of ``nsbench bench`` or ``nsbench run`` (or its ``results.parquet``).
    to
        The archive: an archive folder, or a folder to make one (absent or empty).
    machine
        The machine's name in the archive (``None``: the run's CPU and core count).
    """

    run: str
    to: str
    machine: str | None = None

    def __post_init__(self) -> None:
        if not str(self.run).strip() or not Path(self.run).exists():
            raise ConfigError(f"RUN {str(self.run)!r} does not exist: give the results folder of nsbench bench")
        layout.check_target(Path(self.to), "--to")
        if self.machine is not None and (not self.machine.strip() or not self.machine.isprintable()):
            raise ConfigError(f"--machine {self.machine!r}: give a non-empty name of printable characters")


@dataclass(frozen=True)
class ArchiveAddResult:
    """The outcome of ``archive add``: exit status 1 when the run was refused."""

    outcome: AddOutcome

    @property
    def exit_code(self) -> int:
        return 1 if self.outcome.refused else 0


def add_to_archive(request: ArchiveAddRequest) -> ArchiveAddResult:
    """Re-grade and add the request's run (:func:`add_run`); print what was done, or every refused row."""
    import sys

    outcome = add_run(request.run, request.to, machine=request.machine)
    if outcome.refused:
        print(
            f"nsbench: archive add: {request.run} refused: {len(outcome.refused)} row(s) disagree with the "
            "archive's re-grading from their event logs (nothing was added):",
            file=sys.stderr,
        )
        for line in outcome.refused:
            print(f"  {line}", file=sys.stderr)
    elif outcome.run is not None:
        run = outcome.run
        head = "already in" if outcome.already else "added to"
        print(
            f"{request.run} {head} {request.to} as run {run.run_id} (machine {run.machine}, environment "
            f"{run.environment}, commit {run.commit[:10]}): {run.n_graded} of {run.n_rows} rows re-graded"
        )
        for mark in run.marks:
            print(f"  marked: {mark}")
    return ArchiveAddResult(outcome)
