"""Which integrator runs which problem: the coverage matrix, from the integrators' own refusals.

Each cell is what :meth:`~nsbench.integrators.base.Integrator.check_problem` of the integrator
(at its default options) says of the problem (at its default parameters): it runs, or it is
refused at set-up with the integrator's reason (``exact`` on a quadratic guard, a SUNDIALS
integrator on a problem without blocks on a belt, a whole-system method on a problem whose
events nsbench cannot infer for it). Nothing is integrated: ``check_problem`` stops before a
set-up's costly part. A plug-in integrator is asked through its declared capabilities only, as
every command does in its own process (:func:`nsbench.bifurcation.sweep.check_in_caller`): its
own ``setup`` runs in supervised workers, under ``nsbench check``. An integrator whose library is
not installed fills its row with ``unavailable`` and the install command.

``nsbench list coverage`` prints the matrix and every refusal; ``python -m nsbench.coverage FILE``
writes the docs' table (``docs/reference/coverage.md``).
"""

from __future__ import annotations

import sys
from dataclasses import dataclass
from pathlib import Path

from nsbench import registry
from nsbench.errors import NsbenchError

#: What a cell says, in the matrix: the integrator runs the problem, refuses it at set-up, is not
#: installed (its extra), or the problem itself could not be built at its defaults (a plug-in's factory).
RUNS, REFUSED, UNAVAILABLE, NOT_BUILT = "runs", "refused", "unavailable", "not built"
_MARK = {RUNS: "yes", REFUSED: "-", UNAVAILABLE: "n/a", NOT_BUILT: "!"}


@dataclass(frozen=True)
class Cell:
    """One pair of the matrix: ``status`` is :data:`RUNS`, :data:`REFUSED`, :data:`UNAVAILABLE` or
    :data:`NOT_BUILT`, ``why`` the reason (empty when it runs)."""

    integrator: str
    problem: str
    status: str
    why: str = ""


def _is_builtin(integ) -> bool:
    return type(integ).__module__.startswith("nsbench.")


def integrator_row(name: str, problems: list) -> list[Cell]:
    """The cells of integrator ``name`` on each of ``problems`` (built problem objects)."""
    from nsbench.integrators import get_integrator
    from nsbench.integrators.base import Integrator

    reason = registry.unavailable_reason("integrators", name)
    if reason is not None:
        return [Cell(name, p.name, UNAVAILABLE, reason) for p in problems]
    try:
        integ = get_integrator(name)
    except Exception as exc:  # a plug-in that cannot even be built costs its own row, with the reason
        return [Cell(name, p.name, UNAVAILABLE, f"not built: {type(exc).__name__}: {exc}") for p in problems]
    cells = []
    for problem in problems:
        try:
            if _is_builtin(integ):
                integ.check_problem(problem)
            else:
                Integrator.setup(integ, problem)  # the capabilities only: a plug-in's setup runs supervised
        except NsbenchError as exc:
            cells.append(Cell(name, problem.name, REFUSED, str(exc)))
        except Exception as exc:  # a check that fails is a refusal with its reason, never a lost listing
            cells.append(Cell(name, problem.name, REFUSED, f"its check failed: {type(exc).__name__}: {exc}"))
        else:
            cells.append(Cell(name, problem.name, RUNS))
    return cells


def coverage_matrix(
    integrators: list[str] | None = None,
    problems: list[str] | None = None,
    unbuilt: dict[str, str] | None = None,
) -> list[Cell]:
    """Every ``(integrator, problem)`` cell, integrators and problems in registry order (all by default).

    A problem that cannot be built at its defaults (a plug-in's factory failing) is left out with
    its reason as a cell of every integrator; so is each problem of ``unbuilt`` (``name: why``), which
    is not built here at all: ``nsbench list coverage`` builds a plug-in's problem first in a
    supervised worker, and names here the ones whose factory looped, crashed or raised.
    """
    from nsbench.problems import get_problem, list_problems

    unbuilt = unbuilt or {}
    built, broken = [], []
    for name in problems if problems is not None else list_problems():
        if name in unbuilt:
            broken.append((name, unbuilt[name]))
            continue
        try:
            built.append(get_problem(name))
        except Exception as exc:
            broken.append((name, f"the problem is not built: {type(exc).__name__}: {exc}"))
    cells = []
    for name in integrators if integrators is not None else registry.names("integrators"):
        cells.extend(integrator_row(name, built))
        cells.extend(Cell(name, p, NOT_BUILT, why) for p, why in broken)
    return cells


def _grid(cells: list[Cell], problems: list[str], integrators: list[str]) -> list[list[str]]:
    at = {(c.integrator, c.problem): c for c in cells}
    return [[name, *(_MARK[at[(name, p)].status] for p in problems)] for name in integrators]


def _order(cells: list[Cell]) -> tuple[list[str], list[str]]:
    integrators = list(dict.fromkeys(c.integrator for c in cells))
    problems = list(dict.fromkeys(c.problem for c in cells))
    return integrators, problems


def text(cells: list[Cell], reasons: bool = True) -> str:
    """The matrix for a terminal: problems numbered across, one integrator per row; then (``reasons``)
    every refusal and every unavailable integrator with its reason."""
    integrators, problems = _order(cells)
    width = max(len(n) for n in integrators) if integrators else 10
    lines = ["coverage (yes: runs; -: refused at set-up; n/a: not installed; !: problem not built), problems:"]
    lines += [f"  {i:>2} {p}" for i, p in enumerate(problems, 1)]
    lines.append("  " + " " * width + "".join(f"{i:>4}" for i in range(1, len(problems) + 1)))
    for row in _grid(cells, problems, integrators):
        lines.append(f"  {row[0]:<{width}}" + "".join(f"{mark:>4}" for mark in row[1:]))
    if reasons:
        refused = [c for c in cells if c.status == REFUSED]
        if refused:
            lines.append("refused:")
            lines += [f"  {c.integrator} on {c.problem}: {c.why}" for c in refused]
        missing = {c.integrator: c.why for c in cells if c.status == UNAVAILABLE}
        if missing:
            lines.append("unavailable:")
            lines += [f"  {name}: {why}" for name, why in missing.items()]
        unbuilt = {c.problem: c.why for c in cells if c.status == NOT_BUILT}
        if unbuilt:
            lines.append("not built:")
            lines += [f"  {name}: {why}" for name, why in unbuilt.items()]
    return "\n".join(lines)


def _declarations(integrators: list[str], problems: list[str]) -> list[str]:
    """The traits each problem declares and the ones each integrator accepts (``Capabilities.accepts``):
    the data the refusals follow, as the docs' page lists it."""
    from nsbench.integrators.base import accepted_traits
    from nsbench.problems import get_problem
    from nsbench.problems.base import TRAIT_NAMES, problem_traits

    lines = [
        "A problem declares its traits (`nsbench.problems.base.Traits`); an integrator declares in",
        "`Capabilities.accepts` the traits of the problems it runs (any of them): it refuses a",
        "problem that declares none. An integrator not listed below accepts every problem, through",
        "its hybrid law; its other refusals (a nonlinear field, a contact it has no kernel for) are",
        "its own, with their reasons in the next section.",
        "",
        "| problem | " + " | ".join(f"`{t}`" for t in TRAIT_NAMES) + " |",
        "|---|" + "---|" * len(TRAIT_NAMES),
    ]
    for name in problems:
        try:
            traits = problem_traits(get_problem(name))
        except Exception:  # not built at its defaults: its cells say why
            continue
        lines.append(f"| `{name}` | " + " | ".join("yes" if getattr(traits, t) else "" for t in TRAIT_NAMES) + " |")
    lines += ["", "| integrator | accepts problems with |", "|---|---|"]
    for name in integrators:
        try:
            accepts = accepted_traits(registry.load("integrators", name))
        except Exception:  # a plug-in that does not load: its row says why
            continue
        if accepts is not None:
            lines.append(f"| `{name}` | " + " or ".join(f"`{t}`" for t in accepts) + " |")
    return lines


def markdown(cells: list[Cell]) -> str:
    """The docs' page: the matrix as a table and each refusal's reason, for the integrators installed
    where it was written (the others are named)."""
    integrators, problems = _order(cells)
    present = [n for n in integrators if not all(c.status == UNAVAILABLE for c in cells if c.integrator == n)]
    absent = [n for n in integrators if n not in present]
    out = [
        "# Coverage: which integrator runs which problem",
        "",
        "Written by `python -m nsbench.coverage docs/reference/coverage.md` from each integrator's own",
        "refusals (`check_problem` at its default options, each problem at its defaults); nothing is",
        "integrated. `nsbench list coverage` prints the same matrix for what is installed, plug-ins",
        "included. `yes`: runs; `-`: refused at set-up (the reason below). `tests/test_coverage.py` fails",
        "when this page is stale, and checks each pair against what `simulate` does with it.",
        "",
        "| integrator | " + " | ".join(problems) + " |",
        "|---|" + "---|" * len(problems),
    ]
    for name, *marks in _grid(cells, problems, present):
        out.append(f"| `{name}` | " + " | ".join(marks) + " |")
    if absent:
        out += [
            "",
            "Not installed where this page was written (their extras): " + ", ".join(f"`{n}`" for n in absent) + ".",
        ]
    out += ["", "## What each side declares", ""]
    out += _declarations(present, problems)
    out += ["", "## Why a pair is refused", ""]
    for c in cells:
        if c.status == REFUSED and c.integrator in present:
            out.append(f"- `{c.integrator}` on `{c.problem}`: {c.why.replace('|', '/')}")
    return "\n".join(out) + "\n"


def main(argv: list[str] | None = None) -> int:
    """``python -m nsbench.coverage FILE``: write the docs' page (for the built-in integrators and problems)."""
    args = sys.argv[1:] if argv is None else argv
    if len(args) != 1:
        print("usage: python -m nsbench.coverage FILE", file=sys.stderr)
        return 2
    cells = coverage_matrix(builtin_integrators(), builtin_problems())
    Path(args[0]).write_text(markdown(cells), encoding="utf-8")
    return 0


def builtin_integrators() -> list[str]:
    """The integrators nsbench itself registers (no plug-in), in registry order."""
    return [e.name for e in registry.entries("integrators") if e.distribution in (None, "nsbench")]


def builtin_problems() -> list[str]:
    """The problems nsbench itself registers (no plug-in), in registry order."""
    return [e.name for e in registry.entries("problems") if e.distribution in (None, "nsbench")]


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
