"""Metrics on constructed event logs, with expected values derived by hand."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from nsbench.bench.metrics import align, case_metrics, reaches, state_errors, switching_errors
from nsbench.bench.storage import to_frame
from nsbench.bench.tables import fixed_target, ranking

KINDS = [("stick", 1), ("slip", 1), ("stick", 2), ("slip", 2), ("stick", 1)]
T_REF = [1.0, 2.0, 3.0, 4.0, 5.0]


def log(times, kinds):
    return pd.DataFrame({"t": times, "kind": [k for k, _ in kinds], "block": [b for _, b in kinds]})


REF = log(T_REF, KINDS)


def test_known_shift():
    shift = np.array([1e-6, -2e-6, 3e-6, 0.0, 1e-6])
    run = log(np.array(T_REF) + shift, KINDS)
    al = align(REF, run)
    assert (al.n_prefix, al.n_matched, al.n_missed, al.n_extra) == (5, 5, 0, 0)
    assert al.sequence_ok and al.first_divergence_index == -1 and math.isnan(al.first_divergence_time)
    sw, t_ref, dt = switching_errors(REF, run, al.n_prefix)
    assert sw.err_max == pytest.approx(3e-6, rel=1e-9)
    assert sw.err_rms == pytest.approx(math.sqrt(15 / 5) * 1e-6, rel=1e-9)  # (1+4+9+0+1)/5
    assert sw.err_median == pytest.approx(1e-6, rel=1e-9)
    # relative errors 1e-6, 1e-6, 1e-6, 0, 2e-7: the worst time has 6 correct digits
    assert sw.digits == pytest.approx(6.0, abs=1e-6)
    assert np.allclose(dt, shift, atol=1e-15) and list(t_ref) == T_REF


def test_missing_event_limits_errors_to_the_matched_prefix():
    kinds = KINDS[:2] + KINDS[3:]  # stick@2 at t = 3 is missed
    times = [1.0 + 1e-9, 2.0 - 2e-9, 4.5, 5.5]  # later events would look 1.5 off if compared
    run = log(times, kinds)
    al = align(REF, run)
    assert (al.n_prefix, al.n_matched, al.n_missed, al.n_extra) == (2, 4, 1, 0)
    assert al.first_divergence_index == 2 and al.first_divergence_time == 3.0
    assert not al.sequence_ok
    sw, _, _ = switching_errors(REF, run, al.n_prefix)
    assert sw.err_max == pytest.approx(2e-9, rel=1e-6)
    assert not reaches(1e-6, status="success", sequence_ok=al.sequence_ok, err_max=sw.err_max)


def test_extra_event():
    kinds = KINDS[:2] + [("reverse", 1)] + KINDS[2:]
    run = log([1.0, 2.0, 2.5, 3.0, 4.0, 5.0], kinds)
    al = align(REF, run)
    assert (al.n_prefix, al.n_matched, al.n_missed, al.n_extra) == (2, 5, 0, 1)
    # the divergence is the extra reverse, at its own time (the run's: the reference has no event there)
    assert al.first_divergence_index == 2 and al.first_divergence_time == 2.5
    assert al.first_divergence == "extra"


def test_extra_event_after_the_reference_ends():
    run = log(T_REF + [6.0], KINDS + [("slip", 1)])
    al = align(REF, run)
    assert (al.n_prefix, al.n_missed, al.n_extra, al.first_divergence_index) == (5, 0, 1, 5)
    assert al.first_divergence_time == 6.0  # the run's time: the reference has none there


def test_empty_run_and_digits_cap():
    al = align(REF, log([], []))
    assert (al.n_prefix, al.n_matched, al.n_missed) == (0, 0, 5)
    assert math.isnan(switching_errors(REF, log([], []), 0)[0].err_max)
    exact = switching_errors(REF, REF, 5)[0]
    assert exact.err_max == 0.0 and exact.digits == pytest.approx(-math.log10(2.0**-53))


# A stick-slip cycle of block 2 every 3.58 time units, with block 1 slipping once: the run misses
# block 2's first stick (and so the slip that ends it). Aligned by label only, the run's stick at
# 8.16 pairs with the reference's at 1.0 (an "error" of 7.16) and the divergence shows up a cycle
# late; aligned by label and time, the first stick is missed and every pair is within 1e-9.
CYCLE = [("slip", 1), ("stick", 2), ("slip", 2), ("stick", 2), ("slip", 2), ("stick", 2), ("slip", 2)]
T_CYCLE = [0.5, 1.0, 4.58, 8.16, 11.74, 15.32, 18.9]


def test_a_missed_stick_is_missed_where_it_happened():
    ref = log(T_CYCLE, CYCLE)
    keep = [0, 3, 4, 5, 6]  # stick@2 at 1.0 and slip@2 at 4.58 missed
    run = log([T_CYCLE[i] + 1e-9 for i in keep], [CYCLE[i] for i in keep])
    al = align(ref, run)
    assert (al.n_prefix, al.n_matched, al.n_missed, al.n_extra) == (1, 5, 2, 0)
    assert al.first_divergence_index == 1 and al.first_divergence_time == 1.0 and al.first_divergence == "missed"
    row = case_metrics(ref, run, None, None, None, None)
    assert not row["sequence_ok"] and row["n_prefix"] == 1
    assert row["switch_err_max"] == pytest.approx(1e-9, rel=1e-6)  # the slip of block 1 only: never 7.16


def test_the_nearer_event_in_time_is_paired_when_labels_allow_both():
    """A run whose one stick@2 sits at the reference's second: paired with that one, the first missed."""
    ref = log([1.0, 2.0, 5.0, 6.0], [("stick", 2), ("slip", 2), ("stick", 2), ("slip", 2)])
    run = log([5.0 + 2e-9, 6.0 - 1e-9], [("stick", 2), ("slip", 2)])
    al = align(ref, run)
    assert (al.n_prefix, al.n_matched, al.n_missed, al.n_extra) == (0, 2, 2, 0)
    assert al.first_divergence_time == 1.0
    # and the other way round: a run that stops after the first cycle misses the second one
    early = log([1.0 + 1e-9, 2.0], [("stick", 2), ("slip", 2)])
    al = align(ref, early)
    assert (al.n_prefix, al.n_missed, al.first_divergence_index, al.first_divergence_time) == (2, 2, 2, 5.0)


def test_fewest_unmatched_events_come_before_time():
    """Time only chooses among alignments with the fewest unmatched events: a late but complete
    sequence is matched in full (a large error, not a wrong sequence)."""
    ref = log([1.0, 2.0, 3.0], [("stick", 1), ("slip", 1), ("stick", 1)])
    late = log([1.7, 2.7, 3.7], [("stick", 1), ("slip", 1), ("stick", 1)])
    al = align(ref, late)
    assert al.sequence_ok and al.n_prefix == 3
    assert switching_errors(ref, late, 3)[0].err_max == pytest.approx(0.7)
    swapped = log([1.0, 2.0, 3.0, 4.0], [("stick", 1), ("stick", 2), ("slip", 1), ("stick", 1)])
    al = align(ref, swapped)
    assert (al.n_matched, al.n_missed, al.n_extra, al.first_divergence) == (3, 0, 1, "extra")
    assert al.first_divergence_time == 2.0


def test_long_logs_align_in_full():
    """Two 3000-event logs that differ by one missed event deep inside: found at its place."""
    rng = np.random.default_rng(7)
    n = 3000
    t = np.cumsum(rng.uniform(0.05, 0.2, n))
    kinds = [("stick", 1 + i % 3) if i % 2 == 0 else ("slip", 1 + i % 3) for i in range(n)]
    ref = log(t, kinds)
    run = ref.drop(index=2001).reset_index(drop=True)
    al = align(ref, run)
    assert (al.n_prefix, al.n_matched, al.n_missed, al.n_extra) == (2001, n - 1, 1, 0)
    assert al.first_divergence_time == t[2001]


def test_state_errors_by_hand():
    ref = np.zeros((2, 4))
    run = np.array([[3.0, 0.0, 0.0, 0.0], [4.0, 0.0, 0.0, 1.0]])  # norms 5, 0, 0, 1
    final, l2 = state_errors(ref, run, np.zeros(2), np.array([0.5, -2.0]))
    assert final == 2.0
    assert l2 == pytest.approx(math.sqrt((25 + 1) / 4))
    assert all(math.isnan(v) for v in state_errors(ref, run[:, :3], np.zeros(2), np.zeros(2)))


def test_case_metrics_has_every_metric_column():
    m = case_metrics(REF, REF, None, None, None, None)
    assert m["n_prefix"] == 5 and m["switch_err_max"] == 0.0 and math.isnan(m["state_err_l2"])


def _row(integrator, options, err, time, ok=True, status="success", label="p/1"):
    return {
        "case_id": f"{integrator}{options}",
        "problem_label": label,
        "integrator": integrator,
        "options": options,
        "status": status,
        "sequence_ok": ok,
        "switch_err_max": err,
        "wall_time": time,
        "nfev": int(time * 1000),
        "reference_status": "ok",
        "level": 0,
    }


def test_fixed_target_picks_the_cheapest_reaching_config_and_ignores_wrong_sequences():
    frame = to_frame(
        [
            _row("a", "loose", 1e-7, 0.1),
            _row("a", "tight", 1e-10, 0.5),
            _row("b", "wrong-seq", 1e-13, 0.01, ok=False),  # never counts
            _row("b", "failed", 1e-13, 0.02, status="integrator failure"),
            _row("b", "ok", 1e-7, 0.3),
        ]
    )
    long = fixed_target(frame, (1e-6, 1e-9, 1e-12))
    got = {(r.integrator, r.target): (r.outcome, r.wall_time) for r in long.itertuples()}
    assert got[("a", 1e-6)] == ("reached", 0.1)
    assert got[("a", 1e-9)] == ("reached", 0.5)
    assert got[("a", 1e-12)][0] == "not reached"
    assert got[("b", 1e-6)] == ("reached", 0.3)
    assert got[("b", 1e-9)][0] == "not reached" and got[("b", 1e-12)][0] == "not reached"
    rank = ranking(long)
    # a: ranks 1, 1, 2 (nobody reaches 1e-12: both last = 2); b: 2, 2, 2
    assert list(rank["integrator"]) == ["a", "b"]
    assert rank["mean_rank"].tolist() == pytest.approx([4 / 3, 2.0])


def test_tie_groups_are_compared_in_the_reference_order():
    """Three blocks sticking within rounding of each other: any order inside the group matches."""
    from nsbench.bench.metrics import order_ties_as_reference, tie_groups

    t0 = 0.100251
    ref = log(
        [0.05, t0, t0 + 2e-16, t0 + 4e-16, 0.3], [("slip", 1), ("stick", 31), ("stick", 4), ("stick", 17), ("slip", 2)]
    )
    assert tie_groups(ref["t"]).tolist() == [0, 1, 1, 1, 2]
    run = log(
        [0.05 + 1e-9, t0 + 3e-9, t0 + 3e-9, t0 + 3e-9 + 1e-16, 0.3 - 2e-9],
        [("slip", 1), ("stick", 4), ("stick", 17), ("stick", 31), ("slip", 2)],
    )
    row = case_metrics(ref, run, None, None, None, None)
    assert row["sequence_ok"] and row["n_prefix"] == 5
    assert row["switch_err_max"] == pytest.approx(3e-9, rel=1e-6)
    same = order_ties_as_reference(ref, ref)
    assert same is ref  # nothing to reorder: the frame itself


def test_a_wrong_member_of_a_tie_group_is_a_divergence():
    ref = log([1.0, 2.0, 2.0, 3.0], [("slip", 1), ("stick", 2), ("stick", 3), ("slip", 1)])
    run = log([1.0, 2.0, 2.0, 3.0], [("slip", 1), ("stick", 3), ("reverse", 2), ("slip", 1)])
    row = case_metrics(ref, run, None, None, None, None)
    assert not row["sequence_ok"] and row["first_divergence_index"] == 1


def test_events_a_microsecond_apart_are_not_a_tie():
    """Distinct events keep their order: a swap of events 1e-6 apart is a wrong sequence."""
    ref = log([1.0, 1.0 + 1e-6], [("stick", 1), ("stick", 2)])
    run = log([1.0, 1.0 + 1e-6], [("stick", 2), ("stick", 1)])
    assert not case_metrics(ref, run, None, None, None, None)["sequence_ok"]


def test_no_error_is_reported_below_the_references_certified_error():
    # each event's error is max(|dt|, certified error of the reference there); NaN: not certified, no floor
    ref = REF.assign(certified_error=[1e-9, 1e-9, 1e-9, 5e-8, float("nan")])
    shift = np.array([5e-10, -2e-9, 0.0, 1e-8, 3e-9])
    run = log(np.array(T_REF) + shift, KINDS)
    sw, _, dt = switching_errors(ref, run, 5)
    assert np.allclose(dt, shift, rtol=0, atol=1e-15)  # the signed errors are as measured
    assert sw.err_max == pytest.approx(5e-8)  # floored: 1e-9, 2e-9, 1e-9, 5e-8, 3e-9
    assert sw.err_median == pytest.approx(2e-9, rel=1e-6)
    assert sw.err_rms == pytest.approx(math.sqrt((1 + 4 + 1 + 2500 + 9) / 5) * 1e-9, rel=1e-6)
    assert not sw.at_reference  # event 2 (2e-9) is outside 1e-9
    assert not reaches(1e-8, status="success", sequence_ok=True, err_max=sw.err_max)  # below the reference
    # without the column nothing is floored
    plain, _, _ = switching_errors(REF, run, 5)
    assert plain.err_max == pytest.approx(1e-8, rel=1e-6) and not plain.at_reference

    within = log(np.array(T_REF) + np.array([5e-10, 0.0, -9e-10, 4e-8, 0.0]), KINDS)
    row = case_metrics(ref, within, None, None, None, None)
    assert row["at_ref_accuracy"] and row["switch_err_max"] == pytest.approx(5e-8)
    assert row["event_cert"] == pytest.approx([1e-9, 1e-9, 1e-9, 5e-8, 0.0])
    assert row["switch_digits"] == pytest.approx(-math.log10(5e-8 / 4.0), abs=1e-9)
    assert case_metrics(REF, within, None, None, None, None)["event_cert"] == []
