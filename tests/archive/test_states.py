"""The state errors re-graded on arrival: the bench keeps each run's dense states (``dense_states``),
``archive add`` grades them again against its own reference with the bench's grading, refuses a
submission whose state errors disagree (naming the rows), and keeps a run made before the column
with its state errors as submitted, marked."""

from __future__ import annotations

import hashlib
import json
import math

import numpy as np
import pandas as pd
import pytest

from nsbench.archive import add_run, layout, load, regrade
from nsbench.bench import metrics, storage
from nsbench.cli import main
from tests.archive.conftest import copy, edited_run

STATES = regrade.STATE_REGRADED


def _row(frame: pd.DataFrame, integrator: str, level: int) -> pd.Series:
    return frame[(frame["integrator"] == integrator) & (frame["level"] == level)].iloc[0]


def test_the_bench_keeps_each_runs_own_dense_states_bit_for_bit(runs):
    from nsbench.engine import simulate
    from nsbench.integrators import integrator_from_config
    from nsbench.problems import problem_from_config

    frame = storage.load_results(runs["b"])
    assert (frame["dense_states"] != "").all()  # every case of the run succeeded
    row = _row(frame, "henon-rk4", 1)
    dense, final = metrics.dense_states_arrays(str(row["dense_states"]))
    problem = problem_from_config(json.loads(str(row["problem_config"])))
    t0, t_end = float(row["t0"]), float(row["t_end"])
    again = simulate(
        problem,
        integrator_from_config(json.loads(str(row["integrator_config"]))),
        t_end,
        t0=t0,
        t_eval=np.linspace(t0, t_end, dense.shape[1]),
    )
    # the run is deterministic: the same states, on the suite's grid (100 points, its default)
    assert dense.shape == (problem.n_states, 100)
    assert np.array_equal(again.trajectory[list(problem.state_names)].to_numpy().T, dense)
    assert np.array_equal(np.asarray(again.y_final, dtype=float), final)


def test_the_archive_grades_them_again_to_the_very_errors_the_run_submitted(archive, runs):
    rows = load(archive).rows
    assert rows["states_graded"].all() and (rows["mark"] == "").all()
    for name in ("a", "b"):
        sent = storage.load_results(runs[name]).set_index("case_id")
        kept = rows.set_index("case_id").loc[sent.index]
        for column in STATES:  # one machine, the same states and reference: the same floats bit for bit
            assert kept[column].tolist() == sent[column].tolist() or np.array_equal(
                kept[column].to_numpy(), sent[column].to_numpy(), equal_nan=True
            ), column


def test_the_kept_state_error_is_the_stored_states_against_the_archives_own_reference(archive):
    # computed here by the definition (docs/bench.md), not by the bench's function
    rows = load(archive).rows
    row = _row(rows, "henon-rk4", 0)
    ref = regrade.archive_reference(
        archive / layout.REFERENCES,
        json.loads(str(row["problem_config"])),
        json.loads(str(row["reference_config"])),
        float(row["t0"]),
        float(row["t_end"]),
        100,
    )
    dense, final = metrics.dense_states_arrays(str(row["dense_states"]))
    l2 = math.sqrt(np.mean(np.sum((dense - ref.y_dense) ** 2, axis=0)))
    # the same sums in another order at most: within 1e-12 relative (a few hundred terms, eps each)
    assert row["state_err_l2"] == pytest.approx(l2, rel=1e-12) and l2 > 1e-10
    assert row["final_state_err"] == float(np.max(np.abs(final - ref.y_final)))


@pytest.mark.parametrize("column", ["state_err_l2", "final_state_err", "stick_creep"])
def test_a_hand_edited_state_error_is_refused_naming_the_rows(archive, runs, tmp_path, column):
    def edit(frame: pd.DataFrame) -> None:
        # a submitter "improving" two rows of henon-rk4 by hand (each error well above the allowance)
        rows = frame.index[frame["integrator"] == "henon-rk4"][:2]
        frame.loc[rows, column] = frame.loc[rows, column] / 10

    forged = edited_run(runs["b"], tmp_path / "forged", edit)
    edited = pd.read_parquet(forged / "results.parquet")
    named = edited.loc[edited["integrator"] == "henon-rk4", "case_id"].tolist()[:2]
    path = copy(archive, tmp_path / "arch")
    outcome = add_run(forged, path)
    assert outcome.run is None and len(outcome.refused) == 2
    for case_id, line in zip(named, outcome.refused):
        assert line.startswith(case_id) and "henon-rk4 level" in line
        assert f": {column} " in line and "submitted" in line and "re-graded (allowed:" in line
    assert len(layout.runs(path)) == 2  # nothing added


def test_edited_dense_states_disagree_with_the_submitted_errors_and_are_refused(runs, tmp_path):
    # states nudged by 1e-6 at one inner point (not the last: the final state is its own value)
    def edit(frame: pd.DataFrame) -> None:
        i = frame.index[frame["integrator"] == "ofapi"][0]
        dense, final = metrics.dense_states_arrays(frame.at[i, "dense_states"])
        dense = dense.copy()
        dense[0, 50] += 1e-6
        frame.at[i, "dense_states"] = metrics.dense_states_text(dense, final)

    outcome = add_run(edited_run(runs["b"], tmp_path / "forged", edit), tmp_path / "arch")
    assert outcome.run is None and len(outcome.refused) == 1
    assert "ofapi level 0" in outcome.refused[0] and ": state_err_l2 " in outcome.refused[0]


def test_the_allowance_separates_another_machines_rounding_from_an_edit(runs, tmp_path):
    row = _row(storage.load_results(runs["b"]), "henon-rk4", 0)
    graded = regrade.grade_row(row, tmp_path / "references", 100)
    assert graded.states and set(graded.allowed) == set(STATES)
    for column in ("state_err_l2", "final_state_err"):
        allowed = graded.allowed[column]
        # far below the error itself (5.9e-9 and 1.9e-8 here): a few ulps of states of order 1
        assert 0 < allowed < 1e-13
        nudged = row.copy()
        nudged[column] = row[column] + allowed / 2
        assert regrade.disagreement(nudged, graded.values, graded.allowed) == ""
        nudged[column] = row[column] + 2 * allowed
        assert regrade.disagreement(nudged, graded.values, graded.allowed).startswith(f"{column} ")
        # without the allowances (states not re-graded), the state columns are not compared
        assert regrade.disagreement(nudged, graded.values) == ""


def _old(frame: pd.DataFrame) -> None:
    # a results folder of an nsbench before the column: its rows lack it (and an edited error is
    # then not caught: the state errors are kept as submitted, and marked so)
    del frame["dense_states"]
    frame.loc[frame["integrator"] == "henon-rk4", "state_err_l2"] = 1e-300


def test_a_run_made_before_the_column_is_kept_with_its_state_errors_as_submitted_and_marked(runs, tmp_path, capsys):
    old = edited_run(runs["b"], tmp_path / "old", _old)
    outcome = add_run(old, tmp_path / "arch")
    assert outcome.run is not None and not outcome.refused
    assert outcome.run.marks == [regrade.NO_STATES]
    rows = load(tmp_path / "arch").rows.set_index("case_id")
    sent = storage.load_results(old).set_index("case_id")
    rows = rows.loc[sent.index]
    assert rows["graded"].all() and not rows["states_graded"].any()  # switching times graded, states not
    assert (rows["mark"] == regrade.NO_STATES).all()
    for column in STATES:
        assert np.array_equal(rows[column].to_numpy(), sent[column].to_numpy(), equal_nan=True), column
    assert (rows.loc[rows["integrator"] == "henon-rk4", "state_err_l2"] == 1e-300).all()
    assert rows["switch_err_max"].tolist() == sent["switch_err_max"].tolist()
    # show says so
    assert main(["archive", "show", str(tmp_path / "arch")]) == 0
    assert f"marked: {regrade.NO_STATES}" in capsys.readouterr().out
    # hashed without the (empty) column, as an nsbench before it hashed the run: the same id
    import pyarrow as pa

    before = storage.to_frame(sent.reset_index().to_dict("records")).drop(columns="dense_states")
    assert outcome.run.run_id == storage.content_digest(pa.Table.from_pandas(before, preserve_index=False))[:16]


def test_an_archive_written_before_the_states_graded_column_reads_it_as_false(archive, tmp_path):
    path = copy(archive, tmp_path / "arch")
    folder = sorted((path / layout.RUNS).iterdir())[0]
    rows = layout.read_table(folder / layout.ROWS).drop(columns="states_graded")
    layout.write_table(rows, folder / layout.ROWS, json.loads((folder / layout.PROVENANCE).read_text()))
    manifest = json.loads((folder / layout.MANIFEST).read_text())
    manifest["sha256"][layout.ROWS] = hashlib.sha256((folder / layout.ROWS).read_bytes()).hexdigest()
    (folder / layout.MANIFEST).write_text(json.dumps(manifest))
    tables = load(path)
    old = tables.rows["run_id"] == folder.name
    assert old.any() and not tables.rows.loc[old, "states_graded"].any()
    assert tables.rows.loc[~old, "states_graded"].all()
    assert tables.rows["states_graded"].dtype == "boolean"
