"""compare: a planted slowdown is flagged; noise (overlapping repeats) is not."""

from __future__ import annotations

import numpy as np
import pytest

from nsbench.bench import Suite, run_suite
from nsbench.bench.compare import compare, compare_frames, error_verdict, read_results, time_verdict
from nsbench.bench.storage import to_frame

SUITE = {"name": "cmp", "t_span": [0.0, 25.0], "repeats": 5,
         "problems": [{"name": "one-dof", "case": 1}], "integrators": {"only": ["scipy-rk45"]}}


def test_time_verdicts_on_constructed_repeats():
    a = [0.10, 0.12, 0.11, 0.13]                           # warm timed runs
    assert time_verdict(a, [0.30, 0.33, 0.31, 0.32], 1.5) == (pytest.approx(0.315 / 0.115), "slower")
    assert time_verdict(a, [0.05, 0.06, 0.05, 0.06], 1.5)[1] == "faster"
    # medians 0.115 -> 0.20 (ratio 1.7) but the repeats overlap: noise
    assert time_verdict(a, [0.11, 0.20, 0.25, 0.20], 1.5)[1] == "noise"
    assert time_verdict(a, [0.12], 1.5)[1] == "same"
    # results from before timing isolation listed the cold run first: it is left out
    legacy = [0.50] + a
    assert time_verdict(legacy, [0.5, 0.30, 0.33, 0.31, 0.32], 1.5, cold_first=(True, True)) == \
        (pytest.approx(0.315 / 0.115), "slower")
    assert time_verdict([0.1], [0.3], 1.5)[1] == "unverified"
    assert error_verdict(1e-9, 5e-9, 1.5)[1] == "worse"
    assert error_verdict(1e-17, 5e-16, 1.5)[1] == "same"          # both below the round-off floor


def test_noise_is_not_flagged_but_a_lost_success_is():
    base = {"case_id": "x", "problem_label": "p", "integrator": "i", "options": "{}", "status": "success",
            "sequence_ok": True, "switch_err_max": 1e-9}
    a = to_frame([{**base, "wall_times": [0.10, 0.30, 0.12], "wall_time": 0.12, "wall_time_min": 0.10}])
    b = to_frame([{**base, "wall_times": [0.11, 0.31, 0.29], "wall_time": 0.29, "wall_time_min": 0.11}])
    row = compare_frames(a, b, 1.5).iloc[0]
    assert row["time_verdict"] == "noise" and not row["flagged"]
    c = to_frame([{**base, "wall_times": [0.10, 0.30, 0.12], "status": "integrator failure"}])
    assert compare_frames(a, c, 1.5).iloc[0]["flags"] == "status"
    d = to_frame([{**base, "wall_times": [0.10, 0.30, 0.12], "sequence_ok": False, "switch_err_max": 1e-10}])
    assert compare_frames(a, d, 1.5).iloc[0]["flags"] == "event sequence"


def test_planted_slowdown_is_flagged_and_identical_results_are_not(tmp_path):
    # The timing path runs for real once; the test asserts only what cannot depend on the
    # machine's speed. The slowdown is planted in the data compared (every timed run 4x),
    # so the verdicts do not depend on how busy the machine is.
    run_suite(Suite.from_dict(SUITE), tmp_path / "a", workers=1, progress=False)
    a = read_results(tmp_path / "a")
    assert len(a) == 3 and (a["status"] == "success").all()
    assert all(len(w) == 5 and min(w) > 0 for w in a["wall_times"])     # repeats = 5, all warm, all timed
    table, counts = compare(tmp_path / "a", tmp_path / "a", factor=2.0)   # a run against itself
    assert counts == {"common": 3, "only_a": 0, "only_b": 0, "flagged": 0}
    assert (table["time_verdict"] == "same").all() and (table["time_ratio"] == 1.0).all()
    slow = a.copy()
    slow["wall_times"] = [[4.0 * t for t in w] for w in a["wall_times"]]
    slow["wall_time"] = 4.0 * a["wall_time"]
    slow["wall_time_min"], slow["wall_time_max"] = 4.0 * a["wall_time_min"], 4.0 * a["wall_time_max"]
    b = tmp_path / "b.parquet"
    slow.to_parquet(b)
    table, counts = compare(tmp_path / "a", b, factor=2.0)
    assert counts["flagged"] == 3
    assert (table["time_verdict"] == "slower").all() and np.allclose(table["time_ratio"], 4.0, rtol=1e-12)
    assert (table["err_verdict"] == "same").all() and (table["err_ratio"] == 1.0).all()  # same computation
    # a slowdown smaller than the factor is not flagged, whatever the spread
    slow["wall_times"] = [[1.5 * t for t in w] for w in a["wall_times"]]
    slow["wall_time"] = 1.5 * a["wall_time"]
    slow.to_parquet(b)
    assert compare(tmp_path / "a", b, factor=2.0)[1]["flagged"] == 0


def test_foreign_files_and_an_infinite_factor_are_refused(tmp_path):
    from nsbench.bench.compare import read_results
    from nsbench.errors import ConfigError

    (tmp_path / "other.csv").write_text("a,b\n1,2\n")
    with pytest.raises(ConfigError, match="holds no nsbench results"):
        read_results(tmp_path / "other.csv")
    (tmp_path / "bin.csv").write_bytes(bytes(range(256)) * 4)
    with pytest.raises(ConfigError, match="cannot read results|holds no nsbench results"):
        read_results(tmp_path / "bin.csv")
    (tmp_path / "empty").mkdir()
    with pytest.raises(ConfigError, match="holds no results"):
        read_results(tmp_path / "empty")
    row = to_frame([{"case_id": "x", "status": "success", "wall_times": [0.1, 0.1, 0.1]}])
    with pytest.raises(ConfigError, match="finite number > 1"):
        compare_frames(row, row, float("inf"))
