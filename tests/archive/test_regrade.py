"""Re-grading: the stored event log reads back bit for bit, and the bench's own grading of it is
what the archive keeps; the tolerance stays far below the finest leaderboard target."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

import nsbench
from nsbench.archive import regrade
from nsbench.bench import metrics, storage


def test_an_event_log_reads_back_bit_for_bit():
    events = nsbench.simulate(nsbench.get_problem("one-dof", case=1), "henon-rk4", 20.0).events
    back = metrics.event_log_frame(metrics.event_log_text(events))
    for name in back.columns:
        assert back[name].tolist() == events[name].tolist(), name
    assert set(back.columns) == {c for c in metrics.GRADED_LOG_COLUMNS if c in events}


@pytest.mark.parametrize("text", ["not json", "[1, 2]", '{"t": [1.0]}', '{"t": [1.0], "kind": [], "block": []}'])
def test_a_damaged_event_log_is_refused(text):
    with pytest.raises(ValueError):
        metrics.event_log_frame(text)


def test_every_stored_row_re_grades_from_its_own_log_to_its_own_errors(runs, tmp_path):
    frame = storage.load_results(runs["b"])
    for _, row in frame.iterrows():
        graded = regrade.grade_row(row, tmp_path / "references", 100)
        assert graded.graded and regrade.disagreement(row, graded.values) == ""
        assert graded.values["switch_err_max"] == row["switch_err_max"]


def test_a_changed_count_or_error_is_a_disagreement(runs, tmp_path):
    row = storage.load_results(runs["b"]).iloc[0]
    values = regrade.grade_row(row, tmp_path / "references", 100).values
    changed = row.copy()
    changed["n_prefix"] = int(row["n_prefix"]) - 1
    assert regrade.disagreement(changed, values).startswith(f"n_prefix {int(row['n_prefix']) - 1} submitted")
    tol = regrade.tolerance(row)
    nudged = row.copy()
    nudged["switch_err_max"] = row["switch_err_max"] + tol / 2  # within the rounding a machine may differ by
    assert regrade.disagreement(nudged, values) == ""
    nudged["switch_err_max"] = row["switch_err_max"] + 2 * tol
    assert regrade.disagreement(nudged, values).startswith("switch_err_max")


def test_a_submission_within_the_tolerance_is_added_with_the_re_graded_errors_not_its_own(runs, tmp_path):
    from nsbench.archive import add_run, load
    from tests.archive.conftest import edited_run

    def nudge(frame: pd.DataFrame) -> None:
        frame["switch_err_max"] = frame["switch_err_max"] + regrade.tolerance(frame.iloc[0]) / 2

    outcome = add_run(edited_run(runs["b"], tmp_path / "nudged", nudge), tmp_path / "arch")
    assert outcome.run is not None and not outcome.refused
    kept = load(tmp_path / "arch").rows.set_index("case_id")["switch_err_max"]
    sent = storage.load_results(runs["b"]).set_index("case_id")["switch_err_max"]
    assert kept.loc[sent.index].tolist() == sent.tolist()  # the archive's own grading, bit for bit
    row = pd.Series({"t0": 0.0, "t_end": 20.0})
    assert regrade.tolerance(row) == regrade.ULPS * np.finfo(float).eps * 20.0 and math.isfinite(regrade.tolerance(row))


@pytest.mark.parametrize(
    "provenance, expected",
    [({"suite": {"dense_points": 100}}, 100), ({}, regrade.DENSE_POINTS), ({"suite": {"dense_points": "many"}}, 2)],
)
def test_the_archive_reference_uses_the_runs_own_grid(provenance, expected):
    assert regrade.dense_points_of(provenance) == expected
