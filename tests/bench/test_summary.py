"""The answer first: cheapest method per target, cost ratios, reasons, wrong sequences, references apart."""

from __future__ import annotations

from html.parser import HTMLParser

import pytest

from nsbench.bench.storage import to_frame
from nsbench.bench.summary import findings, problem_summary, reference_costs, wrong_sequences
from nsbench.bench.tables import fixed_target, ranking


#: Planted relative spread of every row's five timed samples (+-3 %).
SPREAD = (0.97, 0.99, 1.0, 1.01, 1.03)


def _row(integrator, wall, err, *, ok=True, status="success", level=0, missed=0, extra=0, spread=SPREAD):
    return {
        "case_id": f"p-{integrator}-{level}",
        "problem_label": "two-dof/1",
        "integrator": integrator,
        "options": '{"rtol": 1.0000000000000001e-11}',
        "level": level,
        "status": status,
        "reference": "exact",
        "reference_status": "ok",
        "sequence_ok": ok,
        "switch_err_max": err,
        "wall_time": wall,
        "wall_spread": 0.06,
        "wall_times": [wall * f for f in spread],
        "n_missed": missed,
        "n_extra": extra,
        "n_ref": 120,
        "nfev": 1000,
    }


@pytest.fixture
def frame():
    # timings are given, not measured: the summary is arithmetic on the stored rows
    return to_frame(
        [
            _row("exact", 0.001, 0.0),  # the reference itself: never ranked
            _row("fast-wrong", 0.01, 1e-12, ok=False, missed=3, extra=1),  # cheapest, but a wrong sequence
            _row("a", 0.1, 1e-10),
            _row("a", 0.2, 1e-13, level=1),
            _row("b", 0.3, 1e-10),
            _row("c", 0.05, 1e-7),  # never reaches 1e-9
            _row("d", float("nan"), float("nan"), status="time limit"),
        ]
    )


def test_cheapest_and_cost_ratios_per_target(frame):
    s = problem_summary(frame, (1e-6, 1e-9, 1e-12)).set_index("target")
    assert s.loc["1e-06", "cheapest"] == "c"  # c reaches the loose target and is cheapest there
    assert s.loc["1e-09", "cheapest"] == "a" and s.loc["1e-09", "others"].startswith("b x3 [")
    assert "tied" not in s.loc["1e-09", "others"] and s.loc["1e-09", "tied"] == ""
    # the 95 % interval of b's cost ratio: the 3rd smallest to the 3rd largest of the 25 pairwise ratios
    pairs = sorted(0.3 * fb / (0.1 * fa) for fa in SPREAD for fb in SPREAD)
    assert s.loc["1e-09", "ratio_low"] == pytest.approx(pairs[2]) and s.loc["1e-09", "ratio_high"] == pytest.approx(
        pairs[-3]
    )
    assert s.loc["1e-09", "time"] == "0.1 s [0.097-0.103]"  # 5 samples: the median's interval is their range
    assert s.loc["1e-12", "cheapest"] == "a" and s.loc["1e-12", "ratio"] != s.loc["1e-12", "ratio"]  # alone
    why = s.loc["1e-09", "not_reached"]
    assert "c (best error 1.0e-07)" in why and "d (1 time limit)" in why
    assert "fast-wrong (wrong event sequence in 1 of 1 configurations)" in why
    assert "exact" not in " ".join(s["cheapest"]) + " ".join(s["others"]) + " ".join(s["not_reached"])


def test_methods_whose_intervals_overlap_are_tied_and_both_named(frame):
    # e is 5 % slower than a by the median, but their samples (+-3 %, +-10 %) overlap: not distinguishable
    tied = to_frame([*frame.to_dict("records"), _row("e", 0.105, 1e-10, spread=(0.9, 0.95, 1.0, 1.05, 1.1))])
    s = problem_summary(tied, (1e-9,)).iloc[0]
    assert s["cheapest"] == "tied: a, e" and s["tied"] == "a, e"
    assert s["others"].startswith("e x1.0") and "e x1" in s["others"] and " tied" in s["others"]
    assert "b x3" in s["others"] and "b x3 [" in s["others"].split("tied")[-1]  # b still distinguishable
    words = " ".join(findings(problem_summary(tied, (1e-9,)), wrong_sequences(tied)))
    assert "no method is distinguishably the cheapest on any problem" in words
    assert "they are tied: a and e on two-dof/1" in words and "a is the cheapest" not in words
    # rows without their samples (one median each) cannot be told apart either
    bare = frame.assign(wall_times=[[] for _ in range(len(frame))])
    assert problem_summary(bare, (1e-9,)).iloc[0]["cheapest"] == "tied: a, b"


def test_wrong_sequences_and_references_are_apart(frame):
    wrong = wrong_sequences(frame)
    assert wrong["integrator"].tolist() == ["fast-wrong"]
    assert wrong["events missed / extra"].tolist() == ["3 / 1"]
    refs = reference_costs(frame)
    assert refs[["integrator", "role"]].values.tolist() == [["exact", "the reference"]]
    words = " ".join(findings(problem_summary(frame, (1e-9,)), wrong))
    assert (
        "a is the cheapest method on 1 of 1 problems; the next method costs 3 times as much (the 95 % "
        "intervals of these ratios start at 2.9 or above)" in words
    )
    assert "1 run(s) end with a wrong event sequence" in words and "fast-wrong" in words


def test_the_ranking_leaves_out_reference_grade_integrators(frame):
    from nsbench.bench.summary import reference_grade

    long = fixed_target(frame, (1e-9,))
    rank = ranking(long[~long["integrator"].map(reference_grade).astype(bool)])
    assert "exact" not in set(rank["integrator"]) and rank["integrator"].iloc[0] == "a"


def test_the_ranking_shares_a_rank_between_methods_whose_timings_overlap(frame):
    # e is 5 % slower than a by the median, their samples overlap; b is three times slower than both
    rows = [*frame.to_dict("records"), _row("e", 0.105, 1e-10, spread=(0.9, 0.95, 1.0, 1.05, 1.1))]
    tied = to_frame(rows)
    long = fixed_target(tied, (1e-9,))
    long = long[long["integrator"] != "exact"]
    samples = {r["case_id"]: r["wall_times"] for r in rows}
    rank = ranking(long, samples).set_index("integrator")
    assert rank.loc["a", "mean_rank"] == rank.loc["e", "mean_rank"] == 1  # neither is singled out
    assert rank.loc["a", "rank"] == rank.loc["e", "rank"] == 1
    assert rank.loc["b", "mean_rank"] == 3 and rank.loc["b", "rank"] == 3  # both are distinguishably faster
    # by medians alone (no samples given) the 5 % decides, as before
    plain = ranking(long).set_index("integrator")
    assert (plain.loc["a", "mean_rank"], plain.loc["e", "mean_rank"]) == (1, 2)
    # a case without samples cannot be told apart from anything
    bare = ranking(long, {}).set_index("integrator")
    assert bare.loc[["a", "b", "e"], "mean_rank"].tolist() == [1, 1, 1]


class _Text(HTMLParser):
    """The visible text of a page, without <pre> and <code> (where markdown-like text is legitimate)."""

    def __init__(self):
        super().__init__()
        self.skip, self.text, self.headings, self._h = 0, [], [], False

    def handle_starttag(self, tag, attrs):
        self.skip += tag in ("pre", "code", "style")
        self._h = tag == "h2"

    def handle_endtag(self, tag):
        self.skip -= tag in ("pre", "code", "style")
        self._h = False

    def handle_data(self, data):
        if self._h:
            self.headings.append(data)
        if not self.skip:
            self.text.append(data)


def test_the_report_opens_with_the_answer_and_shows_no_raw_markdown(frame, tmp_path):
    from nsbench.bench.report import write_report

    rep = write_report(tmp_path, frame)
    page = _Text()
    page.feed(rep.html.read_text())
    text = " ".join(page.text)
    assert page.headings[0] == "The answer"
    for raw in ("`", "**", "|---", "](figures/"):
        assert raw not in text, raw
    assert "1.0000000000000001e-11" not in text and "rtol=1e-11" in text
    md = rep.markdown.read_text()
    assert md.index("## The answer") < md.index("## Fixed-target table")


def test_figures_leave_out_references_and_unsuccessful_runs(frame, tmp_path):
    from nsbench.bench.figures import _styles, family, work_precision

    styles = _styles(sorted(frame["integrator"].unique()) + ["scipy-rk45", "scipy-dop853"])
    assert family("scipy-rk45") == family("scipy-dop853") == "dense output" and family("exact") == "reference"
    assert styles["scipy-rk45"]["marker"] != styles["scipy-dop853"]["marker"]
    fig = work_precision(frame, "two-dof/1", "wall_time", styles, tmp_path)
    assert "1 run(s) that did not succeed (time limit, failure) are not drawn" in fig.caption
    assert "References not drawn: exact." in fig.caption and fig.png.exists()


def test_an_ill_conditioned_problem_is_stated(frame):
    from nsbench.bench.summary import conditioning_table

    # the conditioning itself is measured and checked in tests/bench/test_reference.py
    frame["ref_conditioning"] = 1.61e6
    cond = conditioning_table(frame)
    assert cond[["problem", "conditioning", "double floor"]].values.tolist() == [["two-dof/1", "1.61e+06", "3.6e-10"]]
    words = findings(problem_summary(frame, (1e-9,)), wrong_sequences(frame), cond)
    assert words[0].startswith("two-dof/1 amplifies a change of its start 1.61e+06-fold")
    assert "uncertain by about 4e-10" in words[0]
    frame["ref_conditioning"] = 12.0
    assert findings(problem_summary(frame, (1e-9,)), wrong_sequences(frame), conditioning_table(frame))[0].startswith(
        "At a switching-time error of 1e-09"
    )


def test_targets_below_the_references_certainty_are_not_graded(frame):
    from nsbench.bench.summary import conditioning_table
    from nsbench.bench.tables import grading_floor

    frame["ref_certainty"] = 3e-11
    assert grading_floor(frame) == (3e-11, "the reference is certified to 3.0e-11 only")
    summary = problem_summary(frame, (1e-9, 1e-12))
    at9, at12 = summary.iloc[0], summary.iloc[1]
    assert at9["cheapest"] == "a" and at9["reached"] == "2 of 5"  # graded as before
    assert at12["cheapest"] == "" and at12["reached"] == "not graded"  # 'a' at 1e-13 does not count
    assert "not graded at this target: the reference is certified to 3.0e-11 only" in at12["not_reached"]
    long = fixed_target(frame, (1e-9, 1e-12))
    at = long[long["target"] == 1e-12].set_index("integrator")["outcome"]
    assert at["exact"] == "reference" and (at.drop("exact") == "not graded").all()
    assert set(ranking(long)["attempted"]) == {1}  # only 1e-9 is ranked
    words = findings(summary, wrong_sequences(frame), conditioning_table(frame))
    assert "No problem can be graded at a switching-time error of 1e-12" in " ".join(words)
    # a reference the check does not certify to the end: nothing is graded, and it is said
    frame["ref_certainty"] = float("inf")
    cond = conditioning_table(frame)
    assert cond["certified"].tolist() == ["not over the span"] and not cond["gradable"].any()
    words = findings(problem_summary(frame, (1e-9,)), wrong_sequences(frame), cond)
    assert words[0].startswith("two-dof/1 is not graded below that: its reference is not certified")
    assert problem_summary(frame, (1e-6,))["reached"].tolist() == ["not graded"]


def test_the_double_floor_also_limits_grading(frame):
    from nsbench.bench.tables import grading_floor

    frame["ref_certainty"] = 1e-14
    frame["ref_double_floor"] = 3.6e-10
    limit, why = grading_floor(frame)
    assert limit == 3.6e-10 and "rounding alone" in why
    assert problem_summary(frame, (1e-9, 1e-10))["reached"].tolist() == ["2 of 5", "not graded"]


def test_one_margin_is_said_once_not_as_a_range_from_itself(frame):
    # the same methods on two problems: the cheapest wins both by the same ratio, said once ("3 times",
    # not "3 to 3 times")
    other = frame.assign(problem_label="one-dof/1", case_id=[f"q{i}" for i in range(len(frame))])
    both = to_frame([*frame.to_dict("records"), *other.to_dict("records")])
    words = " ".join(findings(problem_summary(both, (1e-9,)), wrong_sequences(both)))
    assert "a is the cheapest method on 2 of 2 problems; the next method costs 3 times as much" in words
    assert "3 to 3" not in words


def _pair_frame(rows):
    return to_frame([_row("exact", 0.001, 0.0), *rows])


def test_a_ratio_to_the_fastest_is_never_below_1_even_for_a_tied_method():
    # a's median is the smallest (1.0), b's is 1.02; but 10 of b's 25 pairwise ratios to a are below 0.7
    # (a's two slow samples), so the median of the pairwise ratios (Hodges-Lehmann) is 0.95
    a = _row("a", 1.0, 1e-10, spread=(1.0, 1.0, 1.0, 1.5, 1.5))
    b = _row("b", 1.02, 1e-10, spread=(0.95 / 1.02, 0.95 / 1.02, 1.0, 1.0, 1.0))
    s = problem_summary(_pair_frame([a, b]), (1e-9,)).iloc[0]
    assert s["cheapest"] == "tied: a, b"  # a's samples span 1.0-1.5, b's 0.95-1.02: they overlap
    assert s["ratio"] == pytest.approx(1.02 / 1.0)  # the ratio of the medians the answer compares
    assert s["others"].startswith("b x1.02 [") and s["others"].endswith(" tied")
    assert s["ratio_low"] == pytest.approx(0.95 / 1.5) and s["ratio_high"] == pytest.approx(1.02)  # Moses, 3rd of 25


def test_every_method_the_answer_calls_tied_for_the_cheapest_is_ranked_first():
    # a is the fastest by the median but spread widely (1.0-1.4); b (1.25) and c (1.35) are tight:
    # each is tied with a, while c is distinguishably slower than b
    rows = [
        _row("a", 1.2, 1e-10, spread=(1.0 / 1.2, 1.1 / 1.2, 1.0, 1.3 / 1.2, 1.4 / 1.2)),
        _row("b", 1.25, 1e-10, spread=(0.99, 0.995, 1.0, 1.005, 1.01)),
        _row("c", 1.35, 1e-10, spread=(0.99, 0.995, 1.0, 1.005, 1.01)),
        _row("d", 3.0, 1e-10, spread=(0.99, 0.995, 1.0, 1.005, 1.01)),  # distinguishably slower than all
    ]
    frame = _pair_frame(rows)
    assert problem_summary(frame, (1e-9,)).iloc[0]["tied"] == "a, b, c"
    long = fixed_target(frame, (1e-9,))
    rank = ranking(long[long["integrator"] != "exact"], {r["case_id"]: r["wall_times"] for r in rows})
    rank = rank.set_index("integrator")
    assert rank.loc[["a", "b", "c"], "mean_rank"].tolist() == [1, 1, 1]
    assert rank.loc[["a", "b", "c"], "rank"].tolist() == [1, 1, 1]
    assert rank.loc["d", "mean_rank"] == 4 and rank.loc["d", "rank"] == 4  # behind the three of the first tier


def test_a_method_that_counts_no_evaluations_shows_n_a_not_0():
    from nsbench.bench.tables import fixed_target_wide

    counted = _row("a", 0.1, 1e-10)
    uncounted = {**_row("siconos-like", 0.2, 1e-10), "nfev": 0}  # a method that reports no count stores 0
    wide = fixed_target_wide(fixed_target(_pair_frame([counted, uncounted]), (1e-9,))).set_index("integrator")
    assert wide.loc["a", "1e-09"].endswith(" / 1000")
    assert wide.loc["siconos-like", "1e-09"].endswith(" / n/a")
