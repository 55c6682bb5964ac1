"""The tidy schema: one row per case, these columns, in this order.

Config columns hold JSON text (the dicts that rebuild the problem and the
integrator); list columns hold one value per event of the matched prefix.
Statuses are the engine's (``success``, ``step budget exhausted``, ``event storm
(Zeno)``, ``integrator failure``) plus the runner's (``unsupported``, ``time
limit``, ``error``, ``crashed``).
"""

from __future__ import annotations

from nsbench.bench.columns import DECLARED, JSON, LIST, NAMES, of_dtype, reference_table

#: ``(column, meaning)`` for every column of a result row (declared in :mod:`nsbench.bench.columns`).
COLUMNS: tuple[tuple[str, str], ...] = tuple((c.name, c.meaning) for c in DECLARED)

COLUMN_NAMES: tuple[str, ...] = NAMES
LIST_COLUMNS: tuple[str, ...] = of_dtype(LIST)
JSON_COLUMNS: tuple[str, ...] = of_dtype(JSON)
RUNNER_STATUSES = ("unsupported", "time limit", "error", "crashed")


def markdown_table() -> str:
    """The column list as a Markdown table (for docs and reports): :func:`nsbench.bench.columns.reference_table`."""
    return reference_table()
