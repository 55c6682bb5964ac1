"""The README says what the code does: the facts it states that the code can check, checked."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from nsbench import registry
from nsbench.integrators import integrator_class
from nsbench.problems.modes import mode_name

README = (Path(__file__).resolve().parents[1] / "README.md").read_text()
BUILTINS = [e.name for e in registry.entries("integrators") if e.distribution == "nsbench"]


def _integrator_row(name: str) -> str:
    table = README[README.index("## Integrators") :]
    table = table[: table.index("\n\n", table.index("|---"))]
    rows = [line for line in table.splitlines() if line.startswith("| ")]
    (row,) = [r for r in rows if f"`{name}`" in r.split("|")[1]]
    return row


def _shown(value: float) -> str:
    return format(value, "g").replace("e-0", "e-")  # 1e-06 is written 1e-6


@pytest.mark.parametrize("name", BUILTINS)
def test_each_integrator_row_states_its_accuracy_levels(name):
    row = _integrator_row(name)
    cls = integrator_class(name)
    levels = cls.accuracy_levels
    if not levels:
        assert "none" in row.split("|")[-2], row
        return
    step = cls.capabilities.step_option
    values = ", ".join(_shown(level[step]) for level in levels)
    assert f"{values}" in row, (values, row)
    if len(levels) != 3:  # the usual number goes without saying; any other is stated
        words = {4: "four", 2: "two", 5: "five"}[len(levels)]
        assert row.split("|")[-2].strip().startswith(words), row


def test_the_mode_column_is_described_as_written():
    written = mode_name((-1, 0))
    assert written == "slip-|stick"
    assert f"`{written}`" in README and "one character per block" not in README
    assert all(f"`{p}`" in README for p in ("slip+", "stick", "slip-"))


def test_exact_locates_events_as_nsbench_list_says():
    first_line = integrator_class("exact").__doc__.strip().splitlines()[0]
    row = _integrator_row("exact")
    for words in ("curvature-bounded scan", "Newton", "double-double polish"):
        assert words in first_line and words in row, words
    assert "Brent roots" not in first_line


def test_the_layout_names_modules_that_exist():
    src = Path(__file__).resolve().parents[1] / "src" / "nsbench"
    layout = README[README.index("## Layout") :]
    for name in re.findall(r"\b(_?[a-z][a-z0-9_]*\.py)\b", layout):
        assert list(src.rglob(name)), name
