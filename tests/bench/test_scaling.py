"""The scaling study: families, the cheapest configuration per n, growth exponents, the report section."""

from __future__ import annotations

import json
import math

import numpy as np
import pandas as pd
import pytest

from nsbench.bench.scaling import growth_exponent, scaling_families, scaling_summary, scaling_table


def _row(n, integrator, level, wall, err, *, status="success", seq=True, nfev=100, setup=0.1, case=2):
    config = {"name": "chain", "case": case, "dimensional": False, "params": {"n": n}}
    return {
        "problem_config": json.dumps(config, sort_keys=True),
        "integrator": integrator,
        "level": level,
        "options": json.dumps({"level": level}),
        "status": status,
        "sequence_ok": seq,
        "switch_err_max": err,
        "wall_time": wall,
        "wall_spread": 0.05,
        "integrator_time": 0.9 * wall,
        "nfev": nfev,
        "setup_time": setup,
        "t0": 0.0,
        "t_end": 300.0,
        "n_ref": 3 * n,
        "reference": "exact",
    }


def _frame():
    rows = []
    for n in (2, 4, 8, 16):
        # "fast": cost ~ n^1 at its tight level, which reaches 1e-8 everywhere
        rows.append(_row(n, "fast", 0, 0.01 * n, 1e-5, nfev=10 * n, setup=0.5 * n**2))
        rows.append(_row(n, "fast", 1, 0.1 * n, 1e-9, nfev=100 * n, setup=0.5 * n**2))
        # "slow": cost ~ n^2, wrong sequence from n = 8 on, time limit at 16
        if n < 8:
            rows.append(_row(n, "slow", 0, 0.2 * n * n, 1e-10))
        elif n == 8:
            rows.append(_row(n, "slow", 0, 0.2 * n * n, 1e-10, seq=False))
        else:
            rows.append(_row(n, "slow", 0, math.nan, math.nan, status="time limit", seq=pd.NA))
        rows.append(_row(n, "exact", 0, 1e-3, 0.0))
    frame = pd.DataFrame(rows)
    frame["sequence_ok"] = frame["sequence_ok"].astype("boolean")
    return frame


def test_a_family_needs_two_sizes():
    frame = _frame()
    assert scaling_families(frame) == ["chain/2"]
    assert scaling_families(frame[frame["problem_config"].str.contains('"n": 2}')]) == []


def test_cheapest_reaching_configuration_per_n():
    table = scaling_table(_frame())
    fast = table[table["integrator"] == "fast"].set_index("n")
    assert fast["reached"].all()
    assert fast.loc[8, "wall_time"] == pytest.approx(0.8) and fast.loc[8, "nfev"] == 800
    assert fast.loc[4, "events_per_time"] == pytest.approx(12 / 300)
    slow = table[table["integrator"] == "slow"].set_index("n")
    assert slow.loc[4, "reached"] and not slow.loc[8, "reached"] and not slow.loc[16, "reached"]
    assert "wrong event sequence" in slow.loc[8, "why"] and "time limit" in slow.loc[16, "why"]
    assert table[table["integrator"] == "exact"]["why"].str.startswith("the reference").all()
    assert table[table["integrator"] == "exact"]["setup_time"].isna().all()  # compiled by the reference run


def test_exponents_and_where_an_integrator_stops():
    summary = scaling_summary(scaling_table(_frame())).set_index("integrator")
    assert summary.loc["fast", "exponent_wall_time"] == pytest.approx(1.0)
    assert summary.loc["fast", "exponent_nfev"] == pytest.approx(1.0)
    assert summary.loc["fast", "exponent_setup_time"] == pytest.approx(2.0)  # set-up ~ n^2 (compilation)
    assert summary.loc["fast", "largest_n_reached"] == 16 and pd.isna(summary.loc["fast", "first_n_not_reached"])
    # two sizes only: no exponent (a single ratio is not a trend)
    assert math.isnan(summary.loc["slow", "exponent_wall_time"])
    assert summary.loc["slow", "largest_n_reached"] == 4 and summary.loc["slow", "first_n_not_reached"] == 8
    assert "wrong event sequence" in summary.loc["slow", "why"]


def test_growth_exponent_recovers_a_power_law():
    n = np.array([2, 4, 8, 16, 32, 64])
    assert growth_exponent(n, 3e-4 * n**1.7) == pytest.approx(1.7)
    assert math.isnan(growth_exponent(n[:2], n[:2]))
    assert growth_exponent(n, np.where(n > 8, n**2.0, 0.0)) == pytest.approx(2.0)  # zeros are left out


def test_report_opens_with_the_scaling_section(tmp_path):
    from nsbench.bench.report import write_report
    from nsbench.bench.storage import to_frame

    rows = _frame().to_dict("records")
    for r in rows:
        r.update(
            problem="chain",
            case=2,
            problem_label=f"chain/2 n={json.loads(r['problem_config'])['params']['n']}",
            reference_status="ok",
            n_repeats=3,
            wall_time_min=r["wall_time"],
            wall_time_max=r["wall_time"],
            n_events=r["n_ref"],
            n_missed=0,
            n_extra=0,
            switch_digits=8.0,
            state_err_l2=1e-9,
            message="",
        )
    frame = to_frame(rows)
    rep = write_report(tmp_path, frame)
    md = rep.markdown.read_text()
    assert md.index("## Scaling with the number of blocks") < md.index("## Fixed-target table")
    # a scaling study opens with its scaling (docs/bench.md): the first section, before the answer
    assert md.index("## Scaling with the number of blocks") < md.index("## The answer")
    assert [line for line in md.splitlines() if line.startswith("## ")][0] == "## Scaling with the number of blocks"
    # the problem a scaling row is of is headed "problem": "family" is a family of methods in the report
    section = md.split("## Scaling with the number of blocks")[1].split("\n## ")[0]
    headers = [line for line in section.splitlines() if line.startswith("| ")]
    assert headers and headers[0].startswith("| problem ") and "| family" not in section
    assert "scaling_cost_chain_2.png" in md and (tmp_path / "figures" / "scaling_cost_chain_2.png").exists()
    assert (tmp_path / "scaling_summary.csv").exists()
    html = rep.html.read_text()
    assert html.index("Scaling with the number of blocks") < html.index("Fixed-target table")
