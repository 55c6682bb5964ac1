"""Candidate bifurcation points across the pure-sliding threshold of case 1, checked independently."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

import nsbench
from nsbench.bifurcation import detect
from nsbench.bifurcation.parallel import run_sweep
from nsbench.bifurcation.sweep import SweepSpec


def _sticks_after(v0: float, transient: float = 1000.0, span: float = 300.0) -> bool:
    """Independent check with the Python ``exact`` engine: any stick event in the window?"""
    p = nsbench.get_problem("two-dof", case=1, v0=v0)
    ev = nsbench.simulate(p, "exact", transient + span).events
    return bool(((ev["t"] >= transient) & (ev["kind"] == "stick")).any())


def test_pure_sliding_threshold_is_found_and_refined(tmp_path):
    spec = SweepSpec(problem="two-dof", case=1, name="v0", start=0.17, stop=0.21, count=9, transient=1000.0, record=30)
    frame = run_sweep(spec, tmp_path / "s", workers=1, progress=False)
    feats = detect.classify(frame)
    assert feats["pure_sliding"].iloc[0] == False and feats["pure_sliding"].iloc[-1] == True  # noqa: E712
    cands = detect.candidates(feats)
    onset = cands[cands["description"] == "pure sliding begins"]
    assert len(onset) == 1
    left, right = float(onset["left"].iloc[0]), float(onset["right"].iloc[0])
    assert _sticks_after(left) and not _sticks_after(right)
    refined = detect.refine(spec, left, right, "sliding", xtol=1e-4)
    assert refined.right - refined.left <= 1e-4 and left <= refined.left < refined.right <= right
    assert _sticks_after(refined.left) and not _sticks_after(refined.right)


def test_period_detection():
    x = np.array([1.0, 2.0, 3.0] * 10)[:, None]
    assert detect.period_of(x, 1e-9) == 3
    assert detect.distinct_count(x, 1e-9) == 3
    assert detect.period_of(np.arange(20.0)[:, None], 1e-9) == 0


def _by_value(frame, tol=1e-6):
    """The classification's definition, one value at a time (period_of and distinct_count per value)."""
    rows = []
    for index, pts in frame.groupby("index", sort=True):
        first = pts.iloc[0]
        ok = first["status"] in ("success", "rest")
        feats = detect._features(pts, first["section"]) if ok else np.empty((0, 1))
        scale = max(1.0, float(np.nanmax(np.abs(feats)))) if feats.size else 1.0
        period = (1 if len(feats) == 1 else detect.period_of(feats, tol * scale)) if ok else -1
        rows.append((int(index), period, detect.distinct_count(feats, tol * scale) if ok else -1))
    return rows


def test_classify_of_all_values_at_once_is_the_value_by_value_one():
    """Periods and distinct counts of many values in one array computation agree with the loop over values:
    orbits of period 1 to 7 with rounding noise below the tolerance, aperiodic ones, a state NaN in one
    column of one value (that column left out) and in some points only, values of other lengths, a
    failed value, and the event sections (whose block number is a feature)."""
    import pandas as pd

    rng = np.random.default_rng(3)
    frames = []
    for index in range(60):
        section = ("peaks", "strobe", "mapping")[index % 3]
        n = (40, 40, 41, 7, 1)[index % 5]
        period = 1 + index % 7
        base = rng.normal(size=(period, 4))
        pts = base[np.arange(n) % period] + rng.normal(scale=1e-9, size=(n, 4))
        if index % 11 == 0:
            pts = rng.normal(size=(n, 4))  # no period
        if index % 13 == 0:
            pts[:, 1] = np.nan  # v1 missing throughout: left out
        if index % 17 == 0 and n > 2:
            pts[n // 2, 0] = np.nan  # x1 missing at one point: nothing repeats it
        status = "error" if index == 29 else ("rest" if n == 1 else "success")
        frames.append(
            pd.DataFrame(
                {
                    "param": "v0",
                    "value": 0.1 + index,
                    "index": index,
                    "section": section,
                    "k": np.arange(n),
                    "t": np.arange(n, dtype=float),
                    "x1": pts[:, 0],
                    "v1": pts[:, 1],
                    "x2": pts[:, 2],
                    "v2": pts[:, 3],
                    "event_block": 1 + (np.arange(n) % period) % 2,
                    "status": status,
                    "message": "",
                    "n_points": n,
                    "sticks1": index % 4,
                    "sticks2": index % 3,
                }
            )
        )
    frame = pd.concat(frames[::-1], ignore_index=True)  # not in index order
    got = detect.classify(frame)
    want = _by_value(frame)
    assert list(zip(got["index"], got["period"], got["n_distinct"])) == want
    assert len({p for _, p, _ in want}) >= 6  # the cases differ: the comparison can fail
    cycles = got["n_points"] / got["period"]
    expect = np.where(got["period"] > 0, np.round(got["sticks1"] / cycles), np.nan)
    np.testing.assert_array_equal(got["sticks1_per_cycle"].to_numpy(), expect)
    assert (got["pure_sliding"] == ((got["sticks1"] == 0) & (got["sticks2"] == 0))).all()


@pytest.mark.parametrize(
    "problem, words",
    [
        ("one-dof", ["block 1 starts sticking", "pure sliding ends", "sticking phases per cycle (0) -> (1)"]),
        (
            "impact-oscillator",
            ["the motion starts sticking", "motion without sticking ends", "sticking phases per cycle (0) -> (1)"],
        ),
    ],
)
def test_candidates_speak_of_the_problems_own_motion(problem, words):
    # The wording follows the swept problem's declared traits, not a label passed by hand.
    from nsbench.problems import get_problem
    from nsbench.problems.base import problem_traits

    blocks = problem_traits(get_problem(problem)).belt_blocks
    feats = pd.DataFrame(
        {
            "index": [0, 1],
            "value": [0.1, 0.2],
            "status": ["success", "success"],
            "n_points": [20, 20],
            "period": [1, 1],
            "n_distinct": [1, 1],
            "sticks1": [0, 5],
            "sticks1_per_cycle": [0.0, 1.0],
            "block1_sticks": [False, True],
            "pure_sliding": [True, False],
        }
    )
    cands = detect.candidates(feats, blocks)
    assert list(cands["description"]) == words
    assert list(cands["kind"]) == ["sliding", "sliding", "event-pattern"]
