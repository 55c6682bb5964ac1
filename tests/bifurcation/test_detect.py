"""Candidate bifurcation points across the pure-sliding threshold of case 1, checked independently."""

from __future__ import annotations

import numpy as np

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
    spec = SweepSpec(problem="two-dof", case=1, name="v0", start=0.17, stop=0.21, count=9,
                     transient=1000.0, record=30)
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
