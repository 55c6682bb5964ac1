"""Statistics of the timed repeats, on constructed samples."""

from __future__ import annotations

import math

import pandas as pd
import pytest

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
