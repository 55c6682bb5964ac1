"""One status vocabulary: what became of a supervised job is an :class:`OutcomeKind`, compared as a member."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

import nsbench
from nsbench.status import OutcomeKind, ReferenceStatus, Status, TargetOutcome

SRC = Path(nsbench.__file__).parent


def test_each_ending_of_a_job_gives_its_case_status():
    assert OutcomeKind.DONE.status is Status.SUCCESS
    assert OutcomeKind.FAILED.status is Status.ERROR  # the job raised: the case is an error
    assert OutcomeKind.TIME_LIMIT.status is Status.TIME_LIMIT
    assert OutcomeKind.CRASHED.status is Status.CRASHED
    with pytest.raises(ValueError, match="partial"):
        OutcomeKind.PARTIAL.status
    # the text written in logs and failure lines is the value
    assert f"{OutcomeKind.TIME_LIMIT}: ran past" == "time limit: ran past"


def _offending(walk) -> dict[str, list[int]]:
    """``{module: lines}`` of every module of ``src/nsbench`` where ``walk`` finds a literal comparison."""
    return {
        str(path.relative_to(SRC)): lines
        for path in sorted(SRC.rglob("*.py"))
        if (lines := walk(ast.parse(path.read_text())))
    }


def _literal_comparisons(tree: ast.AST, side, values: set[str]) -> list[int]:
    """Lines of the comparisons in ``tree`` between an expression ``side`` accepts and a string of ``values``."""
    lines = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Compare):
            sides = [node.left, *node.comparators]
            if any(side(s) for s in sides) and any(isinstance(s, ast.Constant) and s.value in values for s in sides):
                lines.append(node.lineno)
    return lines


def _column(name: str):
    """Accepts ``<frame or row>["name"]``."""
    return lambda s: isinstance(s, ast.Subscript) and isinstance(s.slice, ast.Constant) and s.slice.value == name


def _kind_compared_with_literal(tree: ast.AST) -> list[int]:
    """Lines where ``<x>.kind`` is compared with a string that is an outcome kind's value."""
    return _literal_comparisons(
        tree, lambda s: isinstance(s, ast.Attribute) and s.attr == "kind", {k.value for k in OutcomeKind}
    )


def test_no_module_compares_a_job_outcome_with_a_literal_string():
    found = _offending(_kind_compared_with_literal)
    assert not found, f"compare Outcome.kind with OutcomeKind members: {found}"


def test_the_walk_sees_a_literal_comparison():
    # the check above can fail: a comparison written the old way is found
    assert _kind_compared_with_literal(ast.parse('if o.kind == "done":\n    pass\n')) == [1]


def test_a_stored_reference_status_reads_as_its_kind():
    assert ReferenceStatus.of("ok") is ReferenceStatus.OK
    text = ReferenceStatus.failed("exact raised ValueError: no")
    assert text == "reference failed: exact raised ValueError: no"
    assert ReferenceStatus.of(text) is ReferenceStatus.FAILED
    # no candidate accepts the problem: not a failure of the run, and nothing to grade against
    assert ReferenceStatus.of("no reference available: exact refused the problem") is ReferenceStatus.UNAVAILABLE
    # a frame's text column compares with the member
    import pandas as pd

    assert (pd.Series(["ok", text]) == ReferenceStatus.OK).tolist() == [True, False]


def _status_compared_with_ok(tree: ast.AST) -> list[int]:
    """Lines where a ``status`` (attribute, or a frame's ``reference_status`` column) is compared with ``"ok"``."""

    def status(s: ast.AST) -> bool:
        return (
            (isinstance(s, ast.Attribute) and s.attr == "status")
            or (isinstance(s, ast.Name) and s.id == "status")
            or _column("reference_status")(s)
        )

    return _literal_comparisons(tree, status, {"ok"})


def test_no_module_compares_a_reference_status_with_a_literal_string():
    found = _offending(_status_compared_with_ok)
    assert not found, f"compare reference statuses with ReferenceStatus members: {found}"
    assert _status_compared_with_ok(ast.parse('x = frame["reference_status"] == "ok"\n')) == [1]


def test_a_target_outcome_says_whether_its_pair_is_graded():
    graded = {o for o in TargetOutcome if o.graded}
    # a refusal is graded: the method does not solve the pair (the ECDF counts it as unsolved)
    assert graded == {TargetOutcome.REACHED, TargetOutcome.NOT_REACHED, TargetOutcome.UNSUPPORTED}
    assert TargetOutcome("not graded") is TargetOutcome.NOT_GRADED


def _outcome_compared_with_literal(tree: ast.AST) -> list[int]:
    """Lines where a frame's ``outcome`` column (or a row's) is compared with, or matched against, a literal."""
    values = {o.value for o in TargetOutcome}
    lines = _literal_comparisons(tree, _column("outcome"), values)
    for node in ast.walk(tree):
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and node.func.attr == "isin":
            listed = [a for a in node.args if isinstance(a, (ast.List, ast.Tuple, ast.Set))]
            if any(isinstance(e, ast.Constant) and e.value in values for a in listed for e in a.elts):
                lines.append(node.lineno)
    return sorted(lines)


def test_no_module_compares_a_target_outcome_with_a_literal_string():
    found = _offending(_outcome_compared_with_literal)
    assert not found, f"compare fixed-target outcomes with TargetOutcome members: {found}"
    assert _outcome_compared_with_literal(ast.parse('x = row["outcome"] == "reached"\n')) == [1]
    assert _outcome_compared_with_literal(ast.parse('x = s["outcome"].isin(["reference", "a"])\n')) == [1]


def test_an_empty_fixed_target_table_ranks_nothing_and_draws_nothing(tmp_path):
    # the outcome masks stay boolean when the table is empty (an empty object mask would select columns)
    import pandas as pd

    from nsbench.bench.figures import runtime_distribution
    from nsbench.bench.tables import ranking

    long = pd.DataFrame(columns=["problem_label", "integrator", "target", "outcome", "wall_time", "nfev", "case_id"])
    assert ranking(long).empty
    assert runtime_distribution(long, {}, tmp_path) is None
