"""A results archive (schema ``nsbench-results/1``): runs from many machines, commits and plug-ins
in one folder, each re-graded on arrival against the archive's own certified references.

``nsbench archive add RUN --to ARCHIVE`` (:func:`add_run`), ``nsbench archive show ARCHIVE``
(:func:`leaderboard`), ``nsbench archive merge A B --to C`` (:func:`merge_archives`), and, in a
notebook, :func:`load`::

    import nsbench.archive
    rows, events, runs = nsbench.archive.load("nsbench-archive")
    bifurcations = nsbench.archive.load("nsbench-archive").bifurcations  # the bifurcation-target rows

The layout and every column are documented in ``docs/reference/archive-schema.md``: another tool
reads an archive with pandas or pyarrow alone.
"""

from __future__ import annotations

from nsbench.archive.add import add_run
from nsbench.archive.layout import SCHEMA
from nsbench.archive.load import Tables, load
from nsbench.archive.merge import merge_archives
from nsbench.archive.show import bifurcation_board, leaderboard

__all__ = ["SCHEMA", "Tables", "add_run", "bifurcation_board", "leaderboard", "load", "merge_archives"]
