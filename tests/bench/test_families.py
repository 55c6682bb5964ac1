"""The answer per family (nsbench.bench.families): on constructed rows, and end to end on a small suite."""

from __future__ import annotations

import json
import math

import pandas as pd
import pytest

from nsbench.bench.families import families_answer, families_table, has_whole_system


def _row(integrator, family, options, err, l2, creep, seq=True, wall=1.0, step_option="h", arc=math.nan):
    return {
        "problem_label": "one-dof/1",
        "integrator": integrator,
        "family": family,
        "options": json.dumps(options),
        "step_option": step_option,
        "status": "success",
        "sequence_ok": seq,
        "switch_err_max": err,
        "state_err_l2": l2,
        "stick_creep": creep,
        "wall_time": wall,
        "reference": "exact",
        "arc_err": arc,
    }


def test_a_smoothing_method_without_eps_is_fitted_along_its_own_tolerance():
    # lugre (family smoothing) varies rtol, not eps: a tolerance tightens as it shrinks, so an arc error
    # ~ rtol is order +1 along it (fitted against 1/rtol, as for eps, it came out -1)
    rows = [
        _row("lugre", "smoothing", {"rtol": r}, 2.0 * r, 3.0 * r, 1e-6, step_option="rtol", arc=5.0 * r)
        for r in (1e-6, 1e-7, 1e-8)
    ]
    row = families_table(pd.DataFrame(rows), (1e-3,)).set_index("integrator").loc["lugre"]
    assert row["order (switches)"] == pytest.approx(1.0) and row["order (smooth arcs)"] == pytest.approx(1.0)
    assert row["ladder"] == "rtol 1e-06 .. 1e-08"


def test_the_table_reads_each_ladder_cost_order_and_creep():
    rows = [
        _row("moreau-jean", "time-stepping", {"h": h}, 0.5 * h, 2.0 * h, 0.0, wall=1e-3 / h, arc=3.0 * h * h)
        for h in (1e-2, 5e-3, 2.5e-3)
    ]
    # smoothing: error ~ 1/eps**2 against 1/eps (order 2), creep ~ 1/eps
    rows += [
        _row("smoothing", "smoothing", {"eps": e, "rtol": 1e-8}, 10.0 / e**2, 1.0 / e, 3.0 / e, step_option="rtol")
        for e in (1e2, 1e3)
    ]
    rows.append(
        _row("smoothing", "smoothing", {"eps": 10.0, "rtol": 1e-8}, 1.0, 1.0, 0.3, seq=False, step_option="rtol")
    )
    frame = pd.DataFrame(rows)
    assert has_whole_system(frame)
    table = families_table(frame, (1e-3, 1e-6)).set_index("integrator")
    mj, sm = table.loc["moreau-jean"], table.loc["smoothing"]
    assert mj["order (switches)"] == pytest.approx(1.0) and mj["order (states)"] == pytest.approx(1.0)
    assert mj["order (smooth arcs)"] == pytest.approx(2.0) and math.isnan(table.loc["smoothing"]["order (smooth arcs)"])
    # the cheapest configuration with error 0.5 h <= 1e-3 is h = 2e-3 or less: h = 2.5e-3 fails, none reaches
    assert math.isnan(mj["reaches 0.001"])
    assert sm["order (switches)"] == pytest.approx(2.0)  # the eps = 10 row has the wrong sequence: left out
    assert sm["creep (loosest)"] == pytest.approx(0.3) and sm["creep (tightest)"] == pytest.approx(3e-3)
    assert sm["reaches 0.001"] == pytest.approx(1.0) and sm["sequence ok"] == "2 of 3"
    assert sm["ladder"] == "eps 1000 .. 10"
    lines = families_answer(families_table(frame, (1e-3, 1e-6)), (1e-3, 1e-6))
    assert any(line.startswith("one-dof/1, smoothing (smoothing): reaches 0.001 in 1 s") for line in lines)
    assert any("moreau-jean" in line and "order 2.00 on a smooth arc" in line for line in lines)


def test_many_event_driven_methods_make_one_sentence_naming_the_cheapest_per_target():
    """In a suite with several event-driven methods (the default) they are ranked in the tables; the answer
    per family gives them one sentence, the cheapest to each target, and each other family its own."""
    rows = [
        _row("exact", "event-driven", {}, 1e-14, 1e-14, 0.0, wall=2e-3, step_option="rtol"),
        _row("heyoka", "event-driven", {"rtol": 1e-6}, 1e-7, 1e-7, 0.0, wall=5e-4, step_option="rtol"),
        _row("heyoka", "event-driven", {"rtol": 1e-12}, 1e-13, 1e-13, 0.0, wall=1e-3, step_option="rtol"),
    ]
    rows += [_row("moreau-jean", "time-stepping", {"h": h}, 0.5 * h, 2.0 * h, 0.0, wall=1e-3 / h) for h in (1e-2, 1e-3)]
    for r in rows:  # exact under test, as in the default suite's cases graded against `reference`
        r["reference"] = "reference"
    lines = families_answer(families_table(pd.DataFrame(rows), (1e-6, 1e-12, 1e-15)), (1e-6, 1e-12, 1e-15))
    driven = [line for line in lines if "event-driven" in line]
    assert driven == [
        "one-dof/1, event-driven (2 methods, ranked with their ties in the answer above): the lowest median time "
        "to 1e-06 by heyoka in 0.0005 s, 1e-12 by heyoka in 0.001 s, 1e-15 by none."
    ]
    assert any(line.startswith("one-dof/1, time-stepping (moreau-jean)") for line in lines) and len(lines) == 2
    # one event-driven method (the families suite) keeps its own sentence with its order
    one = families_answer(families_table(pd.DataFrame(rows[1:]), (1e-6,)), (1e-6,))
    assert any(line.startswith("one-dof/1, event-driven (heyoka): reaches 1e-06 in 0.0005 s") for line in one)
    # and the report opens with the answer per family only then (the families suite)
    from nsbench.bench.report import answer_leads

    assert answer_leads(families_table(pd.DataFrame(rows), (1e-6,)))
    assert not answer_leads(families_table(pd.DataFrame(rows[1:]), (1e-6,)))


def test_table_tex_holds_the_per_family_table():
    from nsbench.bench.report import _latex

    rows = [_row("moreau-jean", "time-stepping", {"h": h}, 0.5 * h, 2.0 * h, 1e-3, wall=1e-3 / h) for h in (1e-2, 5e-3)]
    rows.append(_row("moreau-jean", "time-stepping", {"h": 2e-2}, 1.0, 1.0, 1e-2, seq=False))
    table = families_table(pd.DataFrame(rows), (1e-2, 1e-3))
    tex = _latex({}, pd.DataFrame(columns=["target"]), pd.DataFrame(), pd.DataFrame(), pd.DataFrame(), table)
    assert tex.count("\\label{tab:nsbench-families}") == 1
    part = tex.split("\\label{tab:nsbench-families}")[1].split("\\end{table}")[0]
    # the columns a time-stepping paper pastes: observed orders, creep, the sequence right in k of n
    for column in ("order (switches)", "order (states)", "creep (loosest)", "creep (tightest)", "sequence ok"):
        assert column in part
    assert "2 of 3" in part and "h 0.02 .. 0.005" in part and "`" not in part
    # without a whole-system method there is no such table
    assert "nsbench-families" not in _latex({}, pd.DataFrame(columns=["target"]), *[pd.DataFrame()] * 3)


@pytest.fixture(scope="module")
def one_dof_reference():
    import numpy as np

    from nsbench import simulate
    from nsbench.problems import get_problem

    problem = get_problem("one-dof")
    grid = np.linspace(0.0, 40.0, 401)
    ref = simulate(problem, "exact", 40.0, t_eval=grid)
    return problem, grid, ref.events, ref.trajectory[list(problem.state_names)].to_numpy().T


def test_the_smooth_arc_is_the_middle_of_the_longest_slipping_arc(one_dof_reference):
    """On the 1-DOF scenario the stick arcs (the block moving with the belt) are longer than the slip arcs;
    the window is the middle half of the longest arc on which the block slips, between two exact events."""
    import numpy as np

    from nsbench.bench.families import smooth_arc_window

    problem, grid, events, dense = one_dof_reference
    a, b = smooth_arc_window(events["t"].to_numpy(), grid, dense, problem.v0)
    t = np.sort(events["t"].to_numpy())
    k = np.searchsorted(t, grid[a])
    start, end = t[k - 1], t[k]
    assert events.set_index("t").loc[start, "kind"] == "slip"  # a slip arc, from a break-away to a stick
    assert start + 0.25 * (end - start) <= grid[a] < grid[b] <= end - 0.25 * (end - start)
    assert np.all(np.abs(dense[1, a : b + 1] - problem.v0) > 1e-3)
    assert smooth_arc_window(np.empty(0), grid[:1], dense[:, :1], problem.v0) is None


@pytest.mark.parametrize("theta, order", [(0.5, 2.0), (1.0, 1.0)])
def test_smooth_arc_error_shows_the_order_on_a_smooth_arc(one_dof_reference, theta, order):
    """moreau-jean is first order across switches but, on an arc without a switch, the trapezoidal rule at
    theta = 1/2 (order 2) and the implicit Euler at theta = 1 (order 1): arc_err separates them (measured
    slopes 2.00 and 1.00 over three halvings; the bound 0.15 leaves room for the error's higher terms)."""
    from nsbench.bench.families import smooth_arc_error
    from nsbench.bench.metrics import observed_order
    from nsbench.integrators import get_integrator

    problem, grid, events, dense = one_dof_reference
    hs = (0.01, 0.005, 0.0025, 0.00125)
    errs = [
        smooth_arc_error(problem, get_integrator("moreau-jean", h=h, theta=theta), events, grid, dense, problem.v0)
        for h in hs
    ]
    assert observed_order(hs, errs) == pytest.approx(order, abs=0.15), errs


def test_event_driven_results_have_no_family_answer():
    frame = pd.DataFrame([_row("henon-rk4", "event-driven", {"h": 0.01}, 1e-8, 1e-8, 0.0)])
    assert not has_whole_system(frame)


@pytest.mark.slow
def test_a_small_families_suite_reports_per_family(tmp_path):
    from nsbench.bench.report import write_report
    from nsbench.bench.runner import run_suite

    suite = {
        "name": "families-small",
        "t_span": [0.0, 20.0],
        "repeats": 3,
        "dense_points": 200,
        "targets": [1e-2, 1e-3],
        "reference": ["exact"],
        "problems": [{"name": "one-dof", "case": 1}],
        "integrators": {
            "only": ["moreau-jean", "smoothing"],
            "grids": {
                "moreau-jean": {"grid": {"h": [0.01, 0.005, 0.0025]}},
                "smoothing": {"grid": {"eps": [1e2, 1e3]}, "fixed": {"rtol": 1e-8}},
            },
        },
    }
    run_suite(suite, tmp_path, workers=1, progress=False)
    report = write_report(tmp_path)
    text = report.markdown.read_text() if hasattr(report, "markdown") else (tmp_path / "report.md").read_text()
    assert "The answer per family of methods" in text
    assert text.index("The answer per family") < text.index("Fixed-target table")
    assert "one-dof/1, time-stepping (moreau-jean)" in text and "one-dof/1, smoothing (smoothing)" in text
    assert "\\label{tab:nsbench-families}" in (tmp_path / "table.tex").read_text()


def test_a_whole_system_case_runs_in_process():
    """The runner's in-process fallback wraps integrators to check a time limit between arcs; a whole-system
    method has no arcs and runs unwrapped."""
    from nsbench.bench import execute
    from nsbench.bench.suite import Suite

    suite = Suite.from_dict(
        {
            "name": "t",
            "t_span": [0.0, 5.0],
            "repeats": 3,
            "dense_points": 50,
            "reference": ["exact"],
            "problems": [{"name": "one-dof", "case": 1}],
            "integrators": {"only": ["moreau-jean"]},
        }
    )
    warm = execute.warm_up(suite.cases()[0], in_process=True)
    assert warm.row is None and warm.warmup_time >= 0.0
