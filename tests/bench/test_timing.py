"""How a case is timed (loops per sample) and the statistics of its samples, on constructed samples."""

from __future__ import annotations

import math

import pandas as pd
import pytest

from nsbench.bench.execute import merge_runs
from nsbench.bench.storage import to_frame
from nsbench.bench.timing import (
    MAX_LOOPS,
    WIDE_SPREAD,
    loops_for,
    loops_within,
    needs_more,
    noise_line,
    setup_table,
    spread_label,
    summarize,
    wide_spread,
)


def test_summarize_gives_median_range_and_relative_spread():
    out = summarize([0.12, 0.10, 0.11], [0.09, 0.08, 0.085])
    assert out["wall_time"] == 0.11 and out["wall_time_min"] == 0.10 and out["wall_time_max"] == 0.12
    assert out["wall_spread"] == pytest.approx(0.02 / 0.11)
    assert out["integrator_time"] == 0.085


def test_summarize_edge_cases():
    one = summarize([0.5])
    assert one["wall_time"] == one["wall_time_min"] == one["wall_time_max"] == 0.5
    assert math.isnan(one["wall_spread"]) and math.isnan(one["integrator_time"])  # nothing to spread
    none = summarize([])
    assert all(math.isnan(v) for v in none.values())
    # an engine without integrator_time gives NaN per run: the median of nothing is NaN
    assert math.isnan(summarize([1.0, 1.0, 1.0], [math.nan] * 3)["integrator_time"])


@pytest.mark.parametrize("spread, label", [(0.16, "±8%"), (0.005, "±<1%"), (math.nan, ""), (pd.NA, "")])
def test_spread_label_is_half_the_range(spread, label):
    assert spread_label(spread) == label


def test_wide_spread_lists_successes_beyond_the_threshold_widest_first():
    rows = [
        {"case_id": str(i), "status": status, "wall_spread": spread}
        for i, (status, spread) in enumerate(
            [("success", 0.1), ("success", 0.6), ("success", 0.3), ("integrator failure", 0.9), ("success", math.nan)]
        )
    ]
    wide = wide_spread(to_frame(rows))
    assert WIDE_SPREAD == 0.25 and wide["case_id"].tolist() == ["1", "2"]


def test_merge_runs_joins_rounds_and_keeps_a_lost_round_as_a_note():
    first = {
        "status": "success",
        "message": "",
        "wall_times": [0.30],
        "integrator_times": [0.25],
        "n_repeats": 1,
        "setup_time_timed": 0.01,
        "switch_err_max": 1e-9,
        **summarize([0.30], [0.25]),
    }
    two = merge_runs(
        first,
        {
            "status": "success",
            "message": "",
            "wall_times": [0.50],
            "integrator_times": [0.45],
            "setup_time_timed": 0.02,
        },
    )
    three = merge_runs(
        two,
        {"status": "success", "message": "", "wall_times": [0.32], "integrator_times": [0.27], "setup_time_timed": 0.0},
    )
    assert three["wall_times"] == [0.30, 0.50, 0.32] and three["n_repeats"] == 3
    assert three["wall_time"] == 0.32 and three["wall_time_min"] == 0.30 and three["wall_time_max"] == 0.50
    assert three["wall_spread"] == pytest.approx(0.2 / 0.32) and three["integrator_time"] == 0.27
    assert three["setup_time_timed"] == 0.02 and three["switch_err_max"] == 1e-9  # metrics of round 1 kept
    assert first["n_repeats"] == 1  # inputs untouched
    lost = merge_runs(two, {"status": "time limit", "message": "wall-clock limit of 5 s per run reached"})
    assert lost["status"] == "success" and lost["wall_times"] == [0.30, 0.50]
    assert "a later timed sample ended with time limit: wall-clock limit" in lost["message"]


def test_merge_runs_joins_cpu_times_and_reads_rows_without_them():
    first = {
        "status": "success",
        "message": "",
        "wall_times": [0.30],
        "integrator_times": [0.25],
        "cpu_times": [0.28],
        "setup_time_timed": 0.0,
        **summarize([0.30], [0.25], [0.28]),
    }
    two = merge_runs(
        first,
        {
            "status": "success",
            "wall_times": [0.40],
            "integrator_times": [0.35],
            "cpu_times": [0.29],
            "setup_time_timed": 0.0,
        },
    )
    assert two["cpu_times"] == [0.28, 0.29] and two["cpu_time"] == pytest.approx(0.285)
    legacy = {k: v for k, v in first.items() if k != "cpu_times"}  # a row written before cpu_times
    assert merge_runs(
        legacy, {"status": "success", "wall_times": [0.4], "integrator_times": [0.3], "setup_time_timed": 0.0}
    )["wall_times"] == [0.30, 0.4]


@pytest.mark.parametrize(
    "run, minimum, loops",
    [
        (0.3, 0.02, 1),  # a run longer than the minimum is a sample on its own
        (0.02, 0.02, 1),
        (0.019, 0.02, 2),  # the sequence of timeit's autorange: 1, 2, 5, 10, 20, 50, ...
        (0.005, 0.02, 5),
        (0.0039, 0.02, 10),
        (0.0005, 0.02, 50),
        (0.00099, 0.05, 100),
        (1e-9, 0.02, MAX_LOOPS),  # bounded
        (math.nan, 0.02, 1),
        (0.0, 0.02, 1),
        (0.001, 0.0, 1),  # unmeasured run, or no minimum
    ],
)
def test_loops_for_makes_a_sample_last_the_minimum(run, minimum, loops):
    assert loops_for(run, minimum) == loops
    if 1 < loops < MAX_LOOPS:
        assert loops * run >= minimum  # long enough ...
        assert loops_for(run, minimum) * run < 2.5 * minimum  # ... and never more than a step of 2.5 over


def test_noise_line_states_the_load_and_the_median_spread():
    rows = [
        {"case_id": str(i), "status": "success", "wall_spread": s} for i, s in enumerate([0.02, 0.04, 0.06, 0.5])
    ] + [{"case_id": "f", "status": "error"}]
    prov = {"timing": {"workers": 2, "cores": 2, "load": {"min": 1.9, "median": 2.4, "max": 3.1, "n": 10}}}
    line = noise_line(to_frame(rows), prov)
    assert line.startswith(
        "How noisy the machine was: load average 2.4 (1.9-3.1) while timing, on 2 cores "
        "with 2 worker(s) (about 0.4 from other programs)"
    )
    assert "spread by 5 % (median over 4 cases of (max - min) / median; 1 spread by more than 25%)" in line
    assert noise_line(to_frame(rows)).startswith("How noisy the machine was: a case's timed samples spread")
    assert noise_line(to_frame([{"case_id": "f", "status": "error"}])) == ""


def test_setup_is_charged_to_the_integrator_not_to_the_level_that_ran_first():
    # as measured on main at aca9a23: cvode-adams 16.3 s for the level whose warm-up compiled, 0.0007 s next
    rows = [
        {
            "case_id": f"{n}{lv}",
            "integrator": n,
            "problem_label": "two-dof/1",
            "level": lv,
            "options": options,
            "setup_time": t,
        }
        for n, lv, options, t in [
            ("cvode-adams", 0, '{"rtol": 1e-06}', 0.0007),
            ("cvode-adams", 1, '{"rtol": 1e-09}', 16.3),
            ("cvode-adams", 2, '{"rtol": 1e-12}', 0.0009),
            ("exact", 0, "{}", 0.002),
        ]
    ]
    table = setup_table(to_frame(rows)).set_index("integrator")
    # the configuration named by its options, not by the index of its level
    assert table.loc["cvode-adams", "first_use"] == 16.3 and table.loc["cvode-adams", "on"] == "two-dof/1 at rtol=1e-09"
    assert table.loc["exact", "on"] == "two-dof/1 at defaults"
    assert table.loc["cvode-adams", "later"] == pytest.approx(0.0008) and table.loc["cvode-adams", "cases"] == 3
    assert math.isnan(table.loc["exact", "later"]) and list(table.index) == ["cvode-adams", "exact"]


def test_a_case_gets_more_samples_while_its_cpu_clock_spreads_widely():
    tight = {
        "status": "success",
        "wall_times": [0.1, 0.3, 0.1, 0.2, 0.1],  # the wall clock is noisy
        "cpu_times": [0.090, 0.092, 0.091, 0.093, 0.090],
    }
    assert not needs_more(tight, 10)  # ... the CPU clock is not
    wide = {**tight, "cpu_times": [0.09, 0.13, 0.09, 0.10, 0.09]}  # 44 % on the CPU clock
    assert needs_more(wide, 10) and not needs_more(wide, 5)  # until max_repeats
    # rows without cpu times: the wall clock decides; a failure never gets more
    assert needs_more({"status": "success", "wall_times": [0.1, 0.2, 0.1]}, 6)
    assert not needs_more({**wide, "status": "time limit"}, 10)


def test_a_looped_sample_is_kept_within_a_quarter_of_the_time_limit():
    # a 0.1 ms run in a 2 ms call: 500 loops by the engine's clock, a 1 s sample; a 1 s limit allows 0.25 s of
    # calls, 125, rounded down to the autorange ladder: 100
    assert loops_for(1e-4, 0.05) == 500 and loops_within(500, 2e-3, 0.25) == 100
    assert loops_within(500, 2e-3, 30.0 / 4) == 500  # the default 30 s limit: untouched
    assert loops_within(5, 1.0, 0.25) == 1  # never below one run
    assert loops_within(20, math.nan, 0.25) == 20  # an unmeasured call changes nothing
