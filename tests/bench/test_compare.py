"""compare: a planted slowdown is flagged; noise, a busier machine and too few samples are not.

Every verdict here is computed on planted samples (no clock): the statistics are
the subject, not this machine's speed.
"""

from __future__ import annotations

import numpy as np
import pytest

from nsbench.bench import Suite, run_suite
from nsbench.bench.compare import compare, compare_frames, error_verdict, read_results, time_verdict, work_verdict
from nsbench.bench.stats import slower_p
from nsbench.bench.storage import to_frame

SUITE = {
    "name": "cmp",
    "t_span": [0.0, 25.0],
    "repeats": 5,
    "max_repeats": 5,
    "problems": [{"name": "one-dof", "case": 1}],
    "integrators": {"only": ["scipy-rk45"]},
}

A = [0.100, 0.104, 0.098, 0.110, 0.101]  # five warm samples (seconds per run)


def test_a_planted_slowdown_beyond_the_factor_is_slower():
    v = time_verdict(A, [2.0 * t for t in A], 1.5)
    # every sample of B above every sample of A: the smallest one-sided p with 5 a side, 1/252
    assert v.verdict == "slower" and v.ratio == pytest.approx(2.0) and v.p == pytest.approx(1 / 252)
    assert v.low < 2.0 < v.high and v.low > 1.5
    assert time_verdict(A, [0.5 * t for t in A], 1.5).verdict == "faster"
    assert time_verdict(A, [1.3 * t for t in A], 1.5).verdict == "same"  # within the factor


def test_the_p_value_is_given_within_the_factor_too_in_the_ratios_direction():
    # `compare --all` printed an empty time_p column: the p-value was kept only beyond the factor
    within = time_verdict(A, [1.3 * t for t in A], 1.5)
    assert within.verdict == "same" and within.p == pytest.approx(1 / 252)  # every B above every A
    quicker = time_verdict(A, [0.8 * t for t in A], 1.5)
    assert quicker.verdict == "same" and quicker.ratio < 1 and quicker.p == pytest.approx(1 / 252)
    # A against itself: half the pairs are ties, no evidence either way
    assert time_verdict(A, A, 1.5).p >= 0.5
    few = time_verdict([0.1, 0.11, 0.12], [0.3, 0.31, 0.32], 1.5)
    assert few.verdict == "unverified" and few.p == pytest.approx(1 / 20)  # the smallest p with 3 a side


def test_a_ratio_beyond_the_factor_that_the_test_does_not_support_is_noise():
    # ratio about 1.6, but one sample of B (0.103) falls below two of A's: U = 2, p = 4/252 = 0.016 > 0.01
    b = [0.103, 0.16, 0.17, 0.18, 0.19]
    assert slower_p(A, b) == pytest.approx(4 / 252)
    v = time_verdict(A, b, 1.5)
    assert v.verdict == "noise" and v.ratio > 1.5 and not v.low > 1.5
    assert time_verdict(A, b, 1.5, confidence=0.95).verdict == "slower"  # a looser confidence flags it


def test_too_few_samples_cannot_be_significant():
    # 3 a side: the smallest one-sided p is 1/20 = 0.05, above 1 - 0.99
    v = time_verdict([0.1, 0.11, 0.12], [0.3, 0.31, 0.32], 1.5)
    assert v.verdict == "unverified" and v.ratio == pytest.approx(0.31 / 0.11)
    assert time_verdict([0.1], [0.3], 1.5).verdict == "unverified"
    assert time_verdict([], [0.3], 1.5).verdict == "n/a"
    # results from before timing isolation listed the cold run first: it is left out
    legacy = time_verdict([0.5] + A, [0.5] + [2 * t for t in A], 1.5, cold_first=(True, True))
    assert legacy.verdict == "slower" and legacy.ratio == pytest.approx(2.0)


def test_a_busier_machine_shows_on_the_wall_clock_only_and_is_not_flagged():
    cpu = [0.095, 0.099, 0.094, 0.104, 0.096]
    # B's wall clock doubled (other programs held the core), its CPU clock did not: the machine
    v = time_verdict(A, [2.0 * t for t in A], 1.5, a_cpu=cpu, b_cpu=[1.02 * t for t in cpu])
    assert v.verdict == "load" and v.ratio == pytest.approx(2.0) and v.cpu_ratio == pytest.approx(1.02)
    # more work doubles the CPU clock: flagged, even where the wall clock's noise hides it
    work = time_verdict(A, [2.0 * t for t in A], 1.5, a_cpu=cpu, b_cpu=[2.0 * t for t in cpu])
    assert work.verdict == "slower" and work.cpu_ratio == pytest.approx(2.0)
    hidden = time_verdict(A, [0.1, 0.3, 0.09, 0.25, 0.2], 1.5, a_cpu=cpu, b_cpu=[2.0 * t for t in cpu])
    assert hidden.verdict == "slower" and hidden.p > 0.01


def test_twenty_noisy_comparisons_of_identical_work_flag_nothing_and_a_planted_2x_always():
    # Planted noise, no clock: 80 runs of 5 samples each. A sample's CPU time is the work times a
    # lognormal (10 % relative spread); its wall time that times a per-run machine factor in
    # [0.7, 1.6] and a per-sample one in [1, 3] (other programs holding the core), seeded.
    # Twenty pairs of identical work are compared, then twenty pairs whose B does twice the work.
    rng = np.random.default_rng(2026)

    def run(work: float):
        cpu = work * 0.01 * rng.lognormal(0.0, 0.10, 5)
        return list(cpu * rng.uniform(0.7, 1.6) * rng.uniform(1.0, 3.0, 5)), list(cpu)

    verdicts = []
    for _ in range(20):
        (wa, ca), (wb, cb) = run(1.0), run(1.0)
        verdicts.append(time_verdict(wa, wb, 1.5, a_cpu=ca, b_cpu=cb).verdict)
    assert "slower" not in verdicts and "faster" not in verdicts
    flagged = 0
    for _ in range(20):
        (wa, ca), (wb, cb) = run(1.0), run(2.0)
        flagged += time_verdict(wa, wb, 1.5, a_cpu=ca, b_cpu=cb).verdict == "slower"
    # with 10 % spread on the CPU clock a factor 2 is 7 standard deviations of a log ratio: the
    # samples separate (on the wall clock, a factor 3 of noise would hide it)
    assert flagged == 20


def test_work_and_error_verdicts():
    assert error_verdict(1e-9, 5e-9, 1.5)[1] == "worse"
    assert error_verdict(1e-17, 5e-16, 1.5)[1] == "same"  # both below the round-off floor
    assert work_verdict(1000, 2000, 1.5) == (2.0, "more") and work_verdict(1000, 1100, 1.5)[1] == "same"
    assert work_verdict(None, 10, 1.5)[1] == "n/a"


def test_noise_is_not_flagged_but_a_lost_success_is():
    base = {
        "case_id": "x",
        "problem_label": "p",
        "integrator": "i",
        "options": "{}",
        "status": "success",
        "sequence_ok": True,
        "switch_err_max": 1e-9,
        "nfev": 1000,
    }
    a = to_frame([{**base, "wall_times": [0.10, 0.30, 0.12], "wall_time": 0.12, "wall_time_min": 0.10}])
    b = to_frame([{**base, "wall_times": [0.11, 0.31, 0.29], "wall_time": 0.29, "wall_time_min": 0.11}])
    row = compare_frames(a, b, 1.5).iloc[0]
    # the medians of three differ 2.4-fold, decided by one sample each; the ratios of every pair of
    # samples have a median of 1.1: within the factor
    assert row["time_verdict"] == "same" and row["time_ratio"] == pytest.approx(1.1) and not row["flagged"]
    c = to_frame([{**base, "wall_times": [0.10, 0.30, 0.12], "status": "integrator failure"}])
    assert compare_frames(a, c, 1.5).iloc[0]["flags"] == "status"
    d = to_frame([{**base, "wall_times": [0.10, 0.30, 0.12], "sequence_ok": False, "switch_err_max": 1e-10}])
    assert compare_frames(a, d, 1.5).iloc[0]["flags"] == "event sequence"
    e = to_frame([{**base, "wall_times": [0.10, 0.30, 0.12], "nfev": 2500}])
    assert compare_frames(a, e, 1.5).iloc[0]["flags"] == "more work"


def test_planted_slowdown_is_flagged_and_identical_results_are_not(tmp_path):
    # The timing path runs for real once; the test asserts only what cannot depend on the
    # machine's speed. The slowdown is planted in the data compared (every sample 4x on both
    # clocks, over samples without spread), so the verdicts do not depend on how busy the machine is.
    run_suite(Suite.from_dict(SUITE), tmp_path / "a", workers=1, progress=False)
    a = read_results(tmp_path / "a")
    assert len(a) == 3 and (a["status"] == "success").all()
    assert all(len(w) == 5 and min(w) > 0 for w in a["wall_times"])  # repeats = 5, all warm, all timed
    assert all(len(w) == 5 and min(w) > 0 for w in a["cpu_times"])
    table, counts = compare(tmp_path / "a", tmp_path / "a", factor=2.0)  # a run against itself
    assert counts == {"common": 3, "only_a": 0, "only_b": 0, "flagged": 0}
    assert (table["time_verdict"] == "same").all() and np.allclose(table["time_ratio"], 1.0)
    # The planted pair: every case's samples set to their own median (a spread of 0, so the rank test
    # sees two separated groups however busy the machine was: a load spike can make one real sample
    # 4x another, and 5 against 5 samples then overlap), and the same times 4x.
    base = a.copy()
    for column in ("wall_times", "cpu_times"):
        base[column] = [[float(np.median(w))] * len(w) for w in a[column]]
    base["wall_time"] = base["wall_time_min"] = base["wall_time_max"] = [w[0] for w in base["wall_times"]]
    base_path = tmp_path / "base.parquet"
    base.to_parquet(base_path)
    slow = base.copy()
    for column in ("wall_times", "cpu_times"):
        slow[column] = [[4.0 * t for t in w] for w in base[column]]
    for column in ("wall_time", "wall_time_min", "wall_time_max"):
        slow[column] = 4.0 * base[column]
    b = tmp_path / "b.parquet"
    slow.to_parquet(b)
    table, counts = compare(base_path, b, factor=2.0)
    assert counts["flagged"] == 3, table.to_string()
    assert (table["time_verdict"] == "slower").all() and np.allclose(table["time_ratio"], 4.0, rtol=1e-12)
    assert (table["err_verdict"] == "same").all() and (table["err_ratio"] == 1.0).all()  # same computation
    assert (table["nfev_verdict"] == "same").all()
    # a slowdown smaller than the factor is not flagged, whatever the spread
    for column in ("wall_times", "cpu_times"):
        slow[column] = [[1.5 * t for t in w] for w in base[column]]
    slow.to_parquet(b)
    assert compare(base_path, b, factor=2.0)[1]["flagged"] == 0


def test_foreign_files_and_bad_settings_are_refused(tmp_path):
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
    for bad in (1.0, 0.3, float("nan")):
        with pytest.raises(ConfigError, match=r"confidence = .* must be a number in \[0.5, 1\)"):
            compare_frames(row, row, 1.5, bad)
