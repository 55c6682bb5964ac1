"""The coverage matrix says, of each pair, what ``simulate`` does with it: runs it, or refuses it
with the same reason; and the docs' page is the matrix the code writes.

``simulate`` is the judge: a pair the matrix marks ``yes`` must integrate a short span without a
refusal, and a pair marked ``-`` must be refused by ``simulate`` with the cell's own message. The
default tests take one pair of each kind of refusal and a few that run; every pair is behind the
``slow`` marker (each integrator compiles its kernels on each problem's law).
"""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

from nsbench import coverage, registry
from nsbench.engine import simulate
from nsbench.errors import NsbenchError
from nsbench.problems import get_problem
from nsbench.status import Status

ROOT = Path(__file__).resolve().parents[1]
PAGE = ROOT / "docs" / "reference" / "coverage.md"

#: A few pairs for the default run: runs (a closed form, an adaptive library, a fixed step on the
#: smooth case), and each kind of refusal (a quadratic guard, a formulation of the belt family only,
#: events nsbench cannot infer for a whole-system method, an impact law a library does not take).
PAIRS = [
    ("exact", "one-dof", coverage.RUNS),
    ("scipy-rk45", "bouncing-ball", coverage.RUNS),
    ("henon-rk4", "henon-heiles", coverage.RUNS),
    ("moreau-jean", "bouncing-ball", coverage.RUNS),
    ("exact", "circle-oscillator", coverage.REFUSED),
    ("cvode-bdf", "relay-feedback", coverage.REFUSED),
    ("smoothing", "impact-oscillator", coverage.REFUSED),
    ("moreau-jean", "woodpecker", coverage.REFUSED),
    ("siconos-moreau-jean", "one-dof", coverage.REFUSED),
]


def _installed(name: str) -> bool:
    return registry.unavailable_reason("integrators", name) is None


def _judge(cell: coverage.Cell) -> None:
    """``simulate`` over a short span does what ``cell`` says."""
    problem = get_problem(cell.problem)
    t_end = 0.05 * problem.time_scale  # a few steps: the set-up and its refusals are what is judged
    if cell.status == coverage.REFUSED:
        with pytest.raises(NsbenchError) as caught:
            simulate(problem, cell.integrator, t_end)
        assert str(caught.value) == cell.why
        return
    assert cell.status == coverage.RUNS, cell
    result = simulate(problem, cell.integrator, t_end)
    assert result.status in (Status.SUCCESS, Status.REST), (cell, result.status)


@pytest.mark.parametrize("integrator, problem, status", PAIRS)
def test_the_matrix_says_what_simulate_does(integrator, problem, status):
    if not _installed(integrator):
        pytest.skip(f"{integrator} is not installed")
    (cell,) = coverage.coverage_matrix([integrator], [problem])
    assert cell.status == status, cell.why
    _judge(cell)


@pytest.mark.slow
def test_every_pair_says_what_simulate_does():
    names = [n for n in coverage.builtin_integrators() if _installed(n)]
    cells = coverage.coverage_matrix(names, coverage.builtin_problems())
    for cell in cells:
        _judge(cell)


def test_an_integrator_not_installed_fills_its_row_with_the_install_command(monkeypatch):
    # the row of an engine without its extra, whatever is installed here: its reason is the registry's
    monkeypatch.setattr(
        registry, "unavailable_reason", lambda kind, name: "X not installed; install with pip install x"
    )
    cells = coverage.coverage_matrix(["cvode-bdf"], ["one-dof", "bouncing-ball"])
    assert [c.status for c in cells] == [coverage.UNAVAILABLE] * 2
    assert "unavailable:\n  cvode-bdf: X not installed; install with pip install x" in coverage.text(cells)


def test_a_problem_not_built_costs_its_own_column():
    cells = coverage.coverage_matrix(["exact"], ["one-dof", "broken"], unbuilt={"broken": "its factory raised E"})
    assert [(c.problem, c.status) for c in cells] == [("one-dof", coverage.RUNS), ("broken", coverage.NOT_BUILT)]
    assert "not built:\n  broken: its factory raised E" in coverage.text(cells)


def _page_rows() -> dict[str, list[str]]:
    lines = PAGE.read_text(encoding="utf-8").splitlines()
    lines = lines[: lines.index("## What each side declares")]  # the matrix only
    header = next(ln for ln in lines if ln.startswith("| integrator |"))
    problems = [p.strip() for p in header.strip("|").split("|")[1:]]
    rows = {}
    for ln in lines:
        m = re.match(r"^\| `([^`]+)` \|(.*)\|$", ln)
        if m:
            rows[m.group(1)] = dict(zip(problems, (c.strip() for c in m.group(2).split("|"))))
    return rows


def test_the_docs_page_is_the_matrix_the_code_writes():
    """Each row of ``docs/reference/coverage.md`` for an integrator installed here, and each reason given."""
    rows = _page_rows()
    problems = coverage.builtin_problems()
    names = [n for n in coverage.builtin_integrators() if _installed(n)]
    assert set(names) <= set(rows), "rewrite the page: python -m nsbench.coverage docs/reference/coverage.md"
    cells = coverage.coverage_matrix(names, problems)
    page = PAGE.read_text(encoding="utf-8")
    for cell in cells:
        assert rows[cell.integrator][cell.problem] == coverage._MARK[cell.status], cell
        if cell.status == coverage.REFUSED:
            assert f"- `{cell.integrator}` on `{cell.problem}`: {cell.why.replace('|', '/')}" in page
    for line in coverage._declarations(names, problems):  # the traits and what each integrator accepts
        assert line in page.splitlines(), line


def test_nsbench_list_coverage_prints_the_matrix_and_every_refusal():
    done = subprocess.run(
        [sys.executable, "-m", "nsbench", "list", "coverage"], capture_output=True, text=True, timeout=600
    )
    assert done.returncode == 0, done.stderr
    out = done.stdout
    assert out.startswith("coverage (yes: runs;")
    cell = coverage.coverage_matrix(["exact"], ["circle-oscillator"])[0]
    assert f"  exact on circle-oscillator: {cell.why}" in out
    for name in coverage.builtin_integrators():
        assert re.search(rf"^  {re.escape(name)} +(yes|-|n/a)", out, re.M), name
