"""The results store: a damaged, foreign or misnamed case file or cached reference is named,
refused by readers and computed again by a resumed run; no stale temporary files stay."""

from __future__ import annotations

import io
import os
import shutil
import time

import pytest

from nsbench.bench import Suite, load_results, run_suite
from nsbench.errors import ConfigError


def _suite():
    return Suite.from_dict(
        {
            "name": "store",
            "t_span": [0.0, 30.0],
            "repeats": 3,
            "reference": ["exact"],
            "min_sample_time": 0.0,  # one run per sample: storage, not timing, is tested here
            "problems": [{"name": "one-dof", "case": 1}],
            "integrators": {"only": ["exact", "henon-rk4"]},
        }
    )


@pytest.fixture(scope="module")
def stored(tmp_path_factory):
    out = tmp_path_factory.mktemp("store")
    summary = run_suite(_suite(), out, workers=1, progress=False)
    return out, summary.results


def _copy(stored, tmp_path):
    out = tmp_path / "copy"
    shutil.copytree(stored[0], out)
    return out


def _cols(frame):
    return frame.sort_values("case_id").reset_index(drop=True)[["case_id", "status", "n_events", "switch_err_max"]]


def test_a_truncated_case_file_is_refused_then_run_again(stored, tmp_path):
    out = _copy(stored, tmp_path)
    files = sorted((out / "cases").glob("*.parquet"))
    victim = files[len(files) // 2]
    data = victim.read_bytes()
    victim.write_bytes(data[: int(0.55 * len(data))])
    with pytest.raises(ConfigError, match=f"{victim.name} is damaged.*not a readable Parquet"):
        load_results(out)
    err = io.StringIO()
    again = run_suite(_suite(), out, workers=1, progress=False, stream=err)
    assert f"{victim.name} is damaged" in err.getvalue()
    assert again.n_computed == 1
    assert _cols(again.results).equals(_cols(stored[1]))


def test_a_case_file_under_another_case_name_is_refused(stored, tmp_path):
    out = _copy(stored, tmp_path)
    a, b = sorted((out / "cases").glob("*.parquet"))[:2]
    shutil.copy(a, b)  # duplicate id, missing case: never read silently
    with pytest.raises(ConfigError, match=f"{b.name} is damaged .*holds case '{a.stem}'"):
        load_results(out)
    again = run_suite(_suite(), out, workers=1, progress=False, stream=io.StringIO())
    assert again.n_computed == 1 and _cols(again.results).equals(_cols(stored[1]))


def test_a_foreign_parquet_file_is_refused(stored, tmp_path):
    import pandas as pd

    out = _copy(stored, tmp_path)
    foreign = sorted((out / "cases").glob("*.parquet"))[0]
    pd.DataFrame({"a": [1, 2]}).to_parquet(foreign)
    with pytest.raises(ConfigError, match="not an nsbench case file"):
        load_results(out)


def test_a_damaged_reference_cache_is_computed_again(stored, tmp_path, capsys):
    out = _copy(stored, tmp_path)
    meta = next((out / "references").glob("*.json"))
    events = meta.with_name(meta.name[: -len(".json")] + ".events.parquet")
    events.write_bytes(events.read_bytes()[:100])
    shutil.rmtree(out / "cases")  # every case runs again, against the recomputed reference
    again = run_suite(_suite(), out, workers=1, progress=False, stream=io.StringIO())
    assert "cached reference" in capsys.readouterr().err
    assert _cols(again.results).equals(_cols(stored[1]))


def test_stale_temporary_files_are_removed_on_resume(stored, tmp_path):
    out = _copy(stored, tmp_path)
    stale = [out / "cases" / "x.parquet.tmp", out / "references" / "y.json.tmp", out / "results.csv.tmp"]
    for f in stale:
        f.write_text("partial")
        os.utime(f, (time.time() - 3600, time.time() - 3600))
    young = out / "cases" / "z.parquet.tmp"
    young.write_text("being written by another run")
    run_suite(_suite(), out, workers=1, progress=False, stream=io.StringIO())
    assert not any(f.exists() for f in stale) and young.exists()


@pytest.mark.parametrize("name", ["../x", "/abs", "a/b", "..", ".hidden", ""])
def test_names_from_data_cannot_leave_the_folder(name):
    from nsbench.bench.storage import file_name

    with pytest.raises(ConfigError, match="cannot name a file"):
        file_name(name, "integrator name")
    assert file_name("heyoka-q", "integrator name") == "heyoka-q"


def test_a_truncated_or_edited_csv_export_is_refused(stored, tmp_path, capsys):
    from nsbench.bench.storage import read_provenance
    from nsbench.cli import main

    out = _copy(stored, tmp_path)
    csv = out / "results.csv"
    text = csv.read_text()
    assert _cols(load_results(csv)).equals(_cols(stored[1]))  # whole: read as written
    assert "nsbench_csv_sha256" not in read_provenance(csv) and read_provenance(csv) == read_provenance(out)
    cut = tmp_path / "cut.csv"
    cut.write_text(text[: int(0.8 * len(text))])  # a copy cut short, mid-row: pandas filled it with NaN
    with pytest.raises(ConfigError, match="cut.csv is damaged .*does not match the checksum"):
        load_results(cut)
    assert main(["compare", str(out), str(cut)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "cut.csv is damaged" in err
    edited = tmp_path / "edited.csv"
    edited.write_text(text.replace(",success,", ",integrator failure,", 1))
    with pytest.raises(ConfigError, match="edited.csv is damaged"):
        load_results(edited)
    # an export written before checksums: a row cut short is refused, a whole file read
    old = tmp_path / "old.csv"
    lines = [line for line in text.splitlines(keepends=True) if not line.startswith("# nsbench_csv")]
    old.write_text("".join(lines))
    assert len(load_results(old)) == len(stored[1])
    old.write_text("".join(lines)[:-40])
    with pytest.raises(ConfigError, match="a row does not have every column"):
        load_results(old)


def test_a_changed_value_in_a_case_file_is_refused_then_run_again(stored, tmp_path):
    import pyarrow as pa
    import pyarrow.parquet as pq

    out = _copy(stored, tmp_path)
    victim = sorted((out / "cases").glob("*.parquet"))[0]
    table = pq.read_table(victim)
    i = table.column_names.index("switch_err_max")
    damaged = table.set_column(i, "switch_err_max", pa.array([0.125]))  # what a flipped bit can do
    pq.write_table(damaged.replace_schema_metadata(table.schema.metadata), victim)  # its checksum kept
    with pytest.raises(ConfigError, match=f"{victim.name} is damaged .*do not match the checksum"):
        load_results(out)
    err = io.StringIO()
    again = run_suite(_suite(), out, workers=1, progress=False, stream=err)
    assert f"{victim.name} is damaged" in err.getvalue() and again.n_computed == 1
    assert _cols(again.results).equals(_cols(stored[1]))


def test_a_case_file_of_another_computation_under_its_id_is_run_again(stored, tmp_path):
    from nsbench.bench import storage

    out = _copy(stored, tmp_path)
    victim = sorted((out / "cases").glob("*.parquet"))[0]
    row = storage.read_case(victim).to_dict("records")[0]
    storage.append_row(out, {**row, "t_end": 25.0}, {})  # a sound file (checksum and all), other span
    err = io.StringIO()
    again = run_suite(_suite(), out, workers=1, progress=False, stream=err)
    assert "another computation than its case id says (t_end differs)" in err.getvalue()
    assert again.n_computed == 1 and _cols(again.results).equals(_cols(stored[1]))


def test_a_flipped_bit_in_a_cached_reference_is_seen_and_computed_again(stored, tmp_path, capsys):
    out = _copy(stored, tmp_path)
    dense = next((out / "references").glob("*.dense.npy"))
    data = bytearray(dense.read_bytes())
    data[len(data) // 2] ^= 0x10  # one bit of one stored state: the file still loads
    dense.write_bytes(bytes(data))
    shutil.rmtree(out / "cases")  # every case runs again: against the reference computed again
    again = run_suite(_suite(), out, workers=1, progress=False, stream=io.StringIO())
    assert "dense.npy does not match its checksum" in capsys.readouterr().err
    assert _cols(again.results).equals(_cols(stored[1]))
    state = again.results.sort_values("case_id")["state_err_l2"].tolist()
    assert state == stored[1].sort_values("case_id")["state_err_l2"].tolist()  # not the 0.125 of a bad state


def test_nothing_is_written_or_deleted_through_a_link_in_the_output_folder(stored, tmp_path, capsys):
    from nsbench.cli import main

    elsewhere = tmp_path / "elsewhere"
    shutil.copytree(stored[0] / "cases", elsewhere)  # someone's folder of Parquet files
    before = sorted(p.name for p in elsewhere.iterdir())
    out = _copy(stored, tmp_path)
    shutil.rmtree(out / "cases")
    (out / "cases").symlink_to(elsewhere)
    suite = tmp_path / "s.toml"
    suite.write_text(
        'name = "store"\nt_span = [0.0, 30.0]\nrepeats = 3\nmin_sample_time = 0\nreference = ["exact"]\n'
        'problems = [{name = "one-dof", case = 1}]\n[integrators]\nonly = ["exact", "henon-rk4"]\n'
    )
    for fresh in (["--fresh"], []):  # bench --fresh deleted every *.parquet of the linked folder
        assert main(["bench", str(suite), "--out", str(out), "--no-progress", *fresh]) == 2
        assert "cases is a symbolic link" in capsys.readouterr().err
    assert sorted(p.name for p in elsewhere.iterdir()) == before
    (out / "cases").unlink()
    shutil.copytree(stored[0] / "cases", out / "cases")
    for name in ("provenance.json", "timeline.csv", "results.csv.tmp"):  # were overwritten through the link
        target = tmp_path / f"mine-{name}"
        target.write_text("precious")
        (out / name).unlink(missing_ok=True)
        (out / name).symlink_to(target)
        with pytest.raises(ConfigError, match=f"{name} is a symbolic link"):
            run_suite(_suite(), out, workers=1, progress=False, stream=io.StringIO())
        assert target.read_text() == "precious"
        (out / name).unlink()


@pytest.mark.parametrize("how", ["fresh", "resume", "ingest"])
def test_a_foreign_parquet_file_in_cases_is_never_deleted(stored, tmp_path, how):
    import json

    import pandas as pd

    out = _copy(stored, tmp_path)
    foreign = out / "cases" / "my-data.parquet"
    pd.DataFrame({"a": [1, 2]}).to_parquet(foreign)
    data = foreign.read_bytes()
    with pytest.raises(ConfigError, match="my-data.parquet.*nsbench did not write"):
        if how == "ingest":
            src = tmp_path / "b.json"
            src.write_text(json.dumps({"benchmarks": [{"name": "b", "fullname": "b", "stats": {"median": 0.1}}]}))
            from nsbench.bench.ingest import ingest

            ingest(src, out)
        else:
            run_suite(_suite(), out, workers=1, progress=False, resume=how == "resume", stream=io.StringIO())
    assert foreign.read_bytes() == data


def test_a_stale_temporary_file_of_someone_else_is_left_alone(stored, tmp_path):
    out = _copy(stored, tmp_path)
    theirs = out / "notes.tmp"
    theirs.write_text("mine")
    os.utime(theirs, (time.time() - 3600, time.time() - 3600))
    run_suite(_suite(), out, workers=1, progress=False, stream=io.StringIO())
    assert theirs.read_text() == "mine"
