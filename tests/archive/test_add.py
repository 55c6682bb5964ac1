"""``archive add``: every row re-graded from its own event log against the archive's reference;
a hand-edited error is refused with its rows named; unknown problems and plug-ins kept, marked."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from nsbench.archive import add_run, layout, load
from nsbench.bench import storage
from nsbench.errors import ConfigError
from tests.archive.conftest import copy, edited_run


def test_the_archive_holds_both_runs_re_graded_to_the_very_errors_they_submitted(archive, runs):
    tables = load(archive)
    assert len(tables.runs) == 2 and set(tables.runs["n_rows"]) == {4, 7}
    assert tables.rows["graded"].all() and (tables.rows["mark"] == "").all()
    for name in ("a", "b"):
        sent = storage.load_results(runs[name]).set_index("case_id")
        kept = tables.rows[tables.rows["case_id"].isin(sent.index)].set_index("case_id").loc[sent.index]
        # one machine, one log, one reference computation: the re-grading gives the same floats bit for bit
        assert kept["switch_err_max"].tolist() == sent["switch_err_max"].tolist()
        assert kept["event_err"].map(list).tolist() == sent["event_err"].map(list).tolist()
        assert kept["n_prefix"].tolist() == sent["n_prefix"].tolist()


def test_the_event_table_holds_every_graded_event_of_the_matched_prefix(archive):
    tables = load(archive)
    assert list(tables.events.columns) == list(layout.EVENT_COLUMNS)
    for (rid, case), group in tables.events.groupby(["run_id", "case_id"]):
        row = tables.rows[(tables.rows["run_id"] == rid) & (tables.rows["case_id"] == case)].iloc[0]
        assert len(group) == row["n_prefix"] and group["event"].tolist() == list(range(len(group)))
        assert np.array_equal(group["abs_dt"].to_numpy(), np.abs(np.asarray(row["event_err"])))
        assert np.array_equal(group["t_ref"].to_numpy(), np.asarray(row["event_t"]))
        # |dt| is |t - t_ref| as measured (the run's own event time, not the reference's)
        assert np.allclose(np.abs(group["t"] - group["t_ref"]), group["abs_dt"], rtol=0, atol=1e-15)
    assert len(tables.events) == int(tables.rows["n_prefix"].sum())


def test_the_archive_computed_its_own_certified_reference(archive):
    metas = list((archive / layout.REFERENCES).glob("*.json"))
    assert len(metas) == 1  # one problem, one span, one reference integrator
    meta = json.loads(metas[0].read_text())
    assert meta["name"] == "exact" and meta["status"] == "ok"


def test_the_same_run_added_twice_is_kept_once(archive, runs, tmp_path):
    path = copy(archive, tmp_path / "arch")
    outcome = add_run(runs["a"], path)
    assert outcome.already and outcome.run is not None
    assert len(layout.runs(path)) == 2 and len(list((path / layout.RUNS).iterdir())) == 2


def _bump_error(frame: pd.DataFrame) -> None:
    # a submitter "improving" two rows of ofapi by hand
    rows = frame.index[frame["integrator"] == "ofapi"][:2]
    frame.loc[rows, "switch_err_max"] = frame.loc[rows, "switch_err_max"] / 10


def test_a_hand_edited_switching_time_error_is_refused_naming_the_rows(archive, runs, tmp_path):
    path = copy(archive, tmp_path / "arch")
    forged = edited_run(runs["b"], tmp_path / "forged", _bump_error)
    edited = pd.read_parquet(forged / "results.parquet")
    named = edited.loc[edited["integrator"] == "ofapi", "case_id"].tolist()[:2]
    outcome = add_run(forged, path)
    assert outcome.run is None and len(outcome.refused) == 2
    for case_id, line in zip(named, outcome.refused):
        assert line.startswith(case_id) and "ofapi level" in line and "switch_err_max" in line
        assert "submitted" in line and "re-graded" in line
    assert len(layout.runs(path)) == 2  # nothing added


def test_a_run_re_written_with_a_fresh_checksum_is_refused_all_the_same(archive, runs, tmp_path):
    # the checksum proves a file unchanged since it was written, not that its errors are right
    frame = storage.load_results(runs["b"])
    _bump_error(frame)
    (tmp_path / "forged").mkdir()
    storage.write_results(frame, tmp_path / "forged" / "results.parquet", storage.read_provenance(runs["b"]))
    outcome = add_run(tmp_path / "forged", copy(archive, tmp_path / "arch"))
    assert outcome.run is None and len(outcome.refused) == 2


def test_an_edited_event_error_is_refused_too(runs, tmp_path):
    def edit(frame: pd.DataFrame) -> None:
        i = frame.index[frame["integrator"] == "henon-rk4"][0]
        errs = list(frame.at[i, "event_err"])
        errs[1] = errs[1] / 2
        frame.at[i, "event_err"] = errs

    outcome = add_run(edited_run(runs["b"], tmp_path / "forged", edit), tmp_path / "arch")
    assert outcome.run is None and len(outcome.refused) == 1 and "event_err[1]" in outcome.refused[0]


def test_a_plug_in_not_installed_here_is_graded_and_marked_an_unknown_problem_kept_ungraded(runs, tmp_path):
    def edit(frame: pd.DataFrame) -> None:
        frame.loc[frame["integrator"] == "ofapi", "integrator"] = "someone-elses-plugin"
        frame.loc[frame["integrator"] == "henon-rk4", "problem"] = "no-such-problem"

    outcome = add_run(edited_run(runs["b"], tmp_path / "other", edit), tmp_path / "arch")
    assert outcome.run is not None and not outcome.refused
    rows = load(tmp_path / "arch").rows
    plugin = rows[rows["integrator"] == "someone-elses-plugin"]
    assert plugin["graded"].all() and plugin["mark"].str.contains("unknown integrator someone-elses-plugin").all()
    unknown = rows[rows["integrator"] == "henon-rk4"]
    assert not unknown["graded"].any()
    assert unknown["mark"].str.contains("not re-graded: unknown problem no-such-problem").all()
    assert outcome.run.n_graded == len(plugin) and outcome.run.n_rows == len(rows)
    assert any("unknown problem" in m for m in outcome.run.marks)


def test_a_folder_without_event_logs_cannot_be_re_graded(runs, tmp_path):
    def edit(frame: pd.DataFrame) -> None:
        frame["event_log"] = ""

    with pytest.raises(ConfigError, match="keeps no event log for case .* run its suite again"):
        add_run(edited_run(runs["a"], tmp_path / "old", edit), tmp_path / "arch")
    assert not (tmp_path / "arch").exists()


def test_a_plug_in_of_another_version_is_graded_and_marked(runs, tmp_path):
    import shutil

    folder = tmp_path / "other"
    shutil.copytree(runs["b"], folder)
    prov = json.loads((folder / "provenance.json").read_text())
    prov["plugins"] = [{"kind": "integrator", "name": "ofapi", "distribution": "ofapi-fast", "version": "9.9"}]
    (folder / "provenance.json").write_text(json.dumps(prov))
    outcome = add_run(folder, tmp_path / "arch")
    assert outcome.run is not None and outcome.run.marks == ["plug-in ofapi 9.9 in the run, not a plug-in here"]
    rows = load(tmp_path / "arch").rows
    assert rows["graded"].all()
    assert set(rows.loc[rows["integrator"] == "ofapi", "mark"]) == {outcome.run.marks[0]}
    assert set(rows.loc[rows["integrator"] != "ofapi", "mark"]) == {""}
