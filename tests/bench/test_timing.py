"""Statistics of the timed repeats, on constructed samples."""

from __future__ import annotations

import math

import pandas as pd
import pytest

from nsbench.bench.execute import merge_runs
from nsbench.bench.storage import to_frame
from nsbench.bench.timing import WIDE_SPREAD, spread_label, summarize, wide_spread


def test_summarize_gives_median_range_and_relative_spread():
    out = summarize([0.12, 0.10, 0.11], [0.09, 0.08, 0.085])
    assert out["wall_time"] == 0.11 and out["wall_time_min"] == 0.10 and out["wall_time_max"] == 0.12
    assert out["wall_spread"] == pytest.approx(0.02 / 0.11)
    assert out["integrator_time"] == 0.085


def test_summarize_edge_cases():
    one = summarize([0.5])
    assert one["wall_time"] == one["wall_time_min"] == one["wall_time_max"] == 0.5
    assert math.isnan(one["wall_spread"]) and math.isnan(one["integrator_time"])   # nothing to spread
    none = summarize([])
    assert all(math.isnan(v) for v in none.values())
    # an engine without integrator_time gives NaN per run: the median of nothing is NaN
    assert math.isnan(summarize([1.0, 1.0, 1.0], [math.nan] * 3)["integrator_time"])


@pytest.mark.parametrize("spread, label", [(0.16, "±8%"), (0.005, "±<1%"), (math.nan, ""), (pd.NA, "")])
def test_spread_label_is_half_the_range(spread, label):
    assert spread_label(spread) == label


def test_wide_spread_lists_successes_beyond_the_threshold_widest_first():
    rows = [{"case_id": str(i), "status": status, "wall_spread": spread}
            for i, (status, spread) in enumerate([("success", 0.1), ("success", 0.6), ("success", 0.3),
                                                  ("integrator failure", 0.9), ("success", math.nan)])]
    wide = wide_spread(to_frame(rows))
    assert WIDE_SPREAD == 0.25 and wide["case_id"].tolist() == ["1", "2"]


def test_merge_runs_joins_rounds_and_keeps_a_lost_round_as_a_note():
    first = {"status": "success", "message": "", "wall_times": [0.30], "integrator_times": [0.25],
             "n_repeats": 1, "setup_time_timed": 0.01, "switch_err_max": 1e-9, **summarize([0.30], [0.25])}
    two = merge_runs(first, {"status": "success", "message": "", "wall_times": [0.50],
                             "integrator_times": [0.45], "setup_time_timed": 0.02})
    three = merge_runs(two, {"status": "success", "message": "", "wall_times": [0.32],
                             "integrator_times": [0.27], "setup_time_timed": 0.0})
    assert three["wall_times"] == [0.30, 0.50, 0.32] and three["n_repeats"] == 3
    assert three["wall_time"] == 0.32 and three["wall_time_min"] == 0.30 and three["wall_time_max"] == 0.50
    assert three["wall_spread"] == pytest.approx(0.2 / 0.32) and three["integrator_time"] == 0.27
    assert three["setup_time_timed"] == 0.02 and three["switch_err_max"] == 1e-9   # metrics of round 1 kept
    assert first["n_repeats"] == 1                                                # inputs untouched
    lost = merge_runs(two, {"status": "time limit", "message": "wall-clock limit of 5 s per run reached"})
    assert lost["status"] == "success" and lost["wall_times"] == [0.30, 0.50]
    assert "a later timed run ended with time limit: wall-clock limit" in lost["message"]
