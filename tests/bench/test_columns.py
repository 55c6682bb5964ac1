"""The column declarations: every stored column is declared, with the dtype it is stored as; the docs'
column reference and the report's tables come from them; the efficiency column is 1 / (error x time)."""

from __future__ import annotations

import math
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from nsbench.bench import Suite, columns, load_results, run_suite, storage
from nsbench.bench.columns import DECLARED, NAMES

DOCS = Path(__file__).resolve().parents[2] / "docs" / "bench.md"

#: Whether an Arrow type is the one a stored file holds each kind of column in (written independently
#: of storage's map; pandas' string dtype is written as Arrow's large string).
ARROW = {
    "int": lambda t: t == pa.int64(),
    "float": lambda t: t == pa.float64(),
    "bool": lambda t: t == pa.bool_(),
    "text": lambda t: pa.types.is_string(t) or pa.types.is_large_string(t),
    "json": lambda t: pa.types.is_string(t) or pa.types.is_large_string(t),
    "list": lambda t: pa.types.is_list(t) and t.value_type == pa.float64(),
}
#: The pandas dtype a loaded frame holds each kind of column in.
PANDAS = {"int": "Int64", "float": "float64", "bool": "boolean", "text": "string", "json": "string", "list": "object"}


def _suite() -> Suite:
    # a friction problem and an impact problem, so the impact-only columns are filled on some rows
    return Suite.from_dict(
        {
            "name": "cols",
            "t_span": [0.0, 10.0],
            "repeats": 3,
            "max_repeats": 3,
            "min_sample_time": 0.0,  # one run per sample: the columns, not timing, are tested
            "reference": ["exact"],
            "problems": [{"name": "one-dof", "case": 1}, {"name": "bouncing-ball", "case": 1}],
            "integrators": {"only": ["exact", "scipy-dop853"]},
        }
    )


@pytest.fixture(scope="module")
def bench(tmp_path_factory):
    out = tmp_path_factory.mktemp("cols")
    return out, run_suite(_suite(), out, workers=1, progress=False).results


def test_every_stored_column_is_declared_and_every_declaration_stored(bench):
    out, _ = bench
    files = sorted((out / "cases").glob("*.parquet"))
    assert len(files) == 2 * (1 + 3)
    for f in files + [out / "results.parquet"]:
        stored = pq.read_schema(f).names
        undeclared = [c for c in stored if c not in NAMES]
        assert not undeclared, f"{f.name}: stored columns without a declaration: {undeclared}"
        assert stored == list(NAMES)


def test_the_row_a_case_computes_holds_only_declared_columns():
    # storage drops a key it has no declaration for: a metric computed but not declared would be lost
    # silently, so the row of a real case, before storage, is checked too
    from nsbench.bench.execute import run_case
    from nsbench.bench.reference import candidates, compute_reference

    case = next(c for c in _suite().cases() if c.integrator == "scipy-dop853")
    ref = compute_reference(case.problem, candidates(["exact"]), case.t0, case.t_end, case.dense_points)
    row = run_case(case, ref, "cols")
    assert row["status"] == "success"
    undeclared = sorted(set(row) - set(NAMES))
    assert not undeclared, f"the row holds columns without a declaration: {undeclared}"
    # what the row lacks is exactly what storage derives from it
    assert set(NAMES) - set(row) <= {c.name for c in columns.derived()}


def test_each_declared_dtype_is_the_stored_and_loaded_one(bench):
    out, results = bench
    schema = pq.read_schema(next((out / "cases").glob("*.parquet")))
    for column in DECLARED:
        assert ARROW[column.dtype](schema.field(column.name).type), column.name
    for frame in (results, load_results(out), load_results(out / "results.csv")):
        for column in DECLARED:
            assert str(frame[column.name].dtype) == PANDAS[column.dtype], column.name


def test_the_docs_column_reference_is_the_declarations():
    page = DOCS.read_text()
    assert page == columns.with_reference(page), (
        "docs/bench.md's column reference differs from nsbench.bench.columns: rewrite it with "
        "`python -m nsbench.bench.columns docs/bench.md`"
    )
    for column in DECLARED:
        assert f"| `{column.name}` | {column.dtype} |" in page


def test_efficiency_is_one_over_error_times_wall_time_of_its_row(bench):
    _, frame = bench
    usable = (frame["status"] == "success") & frame["sequence_ok"].fillna(False)
    assert usable.sum() == 8
    expected = 1.0 / (frame["switch_err_max"] * frame["wall_time"])
    np.testing.assert_allclose(frame.loc[usable, "efficiency"], expected[usable], rtol=1e-15)
    assert (frame.loc[usable, "efficiency"] > 0).all()


def test_efficiency_is_nan_where_error_or_time_is_missing_or_zero():
    rows = [
        {"case_id": "a", "status": "success", "sequence_ok": True, "switch_err_max": 2e-6, "wall_time": 0.5},
        {"case_id": "b", "status": "success", "sequence_ok": True, "switch_err_max": 0.0, "wall_time": 0.5},
        {"case_id": "c", "status": "success", "sequence_ok": True, "switch_err_max": 2e-6, "wall_time": 0.0},
        {"case_id": "d", "status": "success", "sequence_ok": True, "switch_err_max": None, "wall_time": 0.5},
        {"case_id": "e", "status": "success", "sequence_ok": True, "switch_err_max": 2e-6},
        {"case_id": "f", "status": "time limit", "sequence_ok": True, "switch_err_max": 2e-6, "wall_time": 0.5},
        {"case_id": "g", "status": "success", "sequence_ok": False, "switch_err_max": 2e-6, "wall_time": 0.5},
        {"case_id": "h", "status": "success", "switch_err_max": 2e-6, "wall_time": 0.5},
        {"case_id": "i", "status": "success", "sequence_ok": True, "switch_err_max": math.inf, "wall_time": 0.5},
    ]
    eff = storage.to_frame(rows)["efficiency"].tolist()
    assert eff[0] == 1e6  # 1 / (2e-6 x 0.5), exact in binary to the last bit here
    assert all(math.isnan(e) for e in eff[1:])


def test_an_older_folder_without_the_newer_columns_loads_them_as_missing_or_computed(bench, tmp_path):
    out, results = bench
    old = tmp_path / "old"
    old.mkdir()
    newer = ["efficiency", "engine_share", "penetration", "energy_err", "breakaway_err_max", "event_cert"]
    table = pq.read_table(out / "results.parquet").drop_columns(newer)
    meta = dict(table.schema.metadata)
    meta[storage.CONTENT_KEY] = storage.content_digest(table).encode()  # as an older nsbench wrote it
    pq.write_table(table.replace_schema_metadata(meta), old / "results.parquet")
    frame = load_results(old / "results.parquet")
    assert list(frame.columns) == list(NAMES)
    assert frame["penetration"].isna().all() and frame["energy_err"].isna().all()
    assert frame["event_cert"].map(len).eq(0).all()
    # the derived ones are computed from the columns the old folder has
    pd.testing.assert_series_equal(frame["efficiency"], results["efficiency"])
    pd.testing.assert_series_equal(frame["engine_share"], results["engine_share"])


def test_the_report_shows_each_column_in_the_tables_its_declaration_names(bench, tmp_path):
    from nsbench.bench.report import write_report

    out = tmp_path / "rep"
    shutil.copytree(bench[0], out)
    md = write_report(out).markdown.read_text()
    cases = md[md.index("## All cases") :]
    header = cases.splitlines()[2]
    for name in columns.in_table(columns.CASES):
        assert f" {'problem' if name == 'problem_label' else name} " in header, name
    assert "efficiency" in header
    specific = md[md.index("## Problem-specific errors") :]
    header = specific.splitlines()[2]
    for name in ("penetration", "energy_err", "breakaway_err_max"):
        assert f" {name} " in header
    table = specific.split("\n\n")[1].splitlines()[2:]
    # only the impact problem defines penetration here: one row per case of it, none for one-dof
    assert len(table) == 4 and all("bouncing-ball" in line for line in table)


def test_a_declaration_with_an_unknown_dtype_or_table_is_refused():
    with pytest.raises(ValueError, match="dtype 'decimal' is not one of"):
        columns.Column("x", "decimal", "a column")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="table 'summary' is not one of"):
        columns.Column("x", "float", "a column", tables=("summary",))
