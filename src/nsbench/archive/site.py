"""``nsbench archive site ARCHIVE --out DIR``: the leaderboard as a static HTML page.

``DIR/index.html`` and its figures (``DIR/figures/<machine>_<environment>/runtime_distribution.png``)
open in a browser from the disk, without a server: the page names only files beside it, and
holds its style sheet. First on the page are, for the first machine and environment, the
runtime distributions (ECDFs, the report's figure :func:`nsbench.bench.figures.runtime_distribution`
over every archived method under test of that machine and environment) and its leaderboard tables
(:func:`nsbench.archive.show.leaderboard`); then the other machines' blocks, then the runs. Costs are
compared only within one machine and environment, and the page says so. After the blocks, the
bifurcation targets' leaderboard, one table per (problem, bifurcation target, machine, environment)
(:func:`nsbench.archive.show.bifurcation_board`, one entry per method): each method's cheapest configuration
that located the bifurcation, ranked by cost, the page saying that no interval is recorded, and the methods
that did not locate it listed after with the reason.
"""

from __future__ import annotations

import html
from dataclasses import dataclass
from pathlib import Path

import pandas as pd

from nsbench.archive.load import Tables
from nsbench.archive.show import BIF_RANKING, NOTE, TARGETS, bifurcation_board, leaderboard
from nsbench.errors import ConfigError

#: What ``--out`` receives, each replaced, never written through a link.
WRITTEN = ("index.html", "figures")
STYLE = (
    "body{font-family:system-ui,sans-serif;margin:1em 2em;color:#222}"
    "table{border-collapse:collapse;font-size:13px;margin:.3em 0 1em}"
    "td,th{border-bottom:1px solid #ddd;padding:2px 8px;text-align:right}"
    "th{background:#f3f3f3}.box{overflow-x:auto}"
    ".first{display:flex;flex-wrap:wrap;gap:1em;align-items:flex-start}"
    ".first img{max-width:min(640px,100%);height:auto}h2{margin-top:1.2em}"
)
#: The leaderboard's columns on the page, and their headings.
SHOWN = {
    "rank": "rank",
    "tie": "tied",
    "method": "method",
    "level": "level",
    "options": "options",
    "switch_err_max": "switch err",
    "wall_time": "wall time s",
    "wall_low": "95% low",
    "wall_high": "95% high",
    "commit": "commit",
    "run_id": "run",
}


@dataclass(frozen=True)
class ArchiveSiteRequest:
    """What ``archive site`` asks for, checked at its construction (a :class:`~nsbench.errors.ConfigError`
    naming the value before anything is read or written).

    Attributes
    ----------
    archive
        The archive (schema ``nsbench-results/1``).
    out
        The folder to write ``index.html`` and ``figures/`` to (made if absent).
    """

    archive: str
    out: str

    def __post_init__(self) -> None:
        from nsbench.archive import layout
        from nsbench.files import refuse_links
        from nsbench.inputs import check_output_dir

        if not str(self.archive).strip():
            raise ConfigError("ARCHIVE expects an archive folder, got ''")
        layout.check_schema(Path(self.archive))
        check_output_dir(self.out, "--out")
        if Path(self.out).resolve() == Path(self.archive).resolve():
            raise ConfigError(f"--out {self.out!r} is the archive itself: give another folder")
        refuse_links(self.out, WRITTEN, ("figures",))


@dataclass(frozen=True)
class ArchiveSiteOutcome:
    """The page written and its figures."""

    index: Path
    figures: tuple[Path, ...]
    exit_code: int = 0


def _styles(names: list[str]) -> dict[str, dict]:
    """A colour and marker per method: matplotlib's ``tab10`` in name order (the archive's methods
    are not all registered here, so no family colours)."""
    from matplotlib import colormaps

    tab10, markers = colormaps["tab10"], "osD^v<>ph*"
    return {n: {"color": tab10(i % 10), "marker": markers[i % len(markers)]} for i, n in enumerate(sorted(names))}


def _ecdf(rows: pd.DataFrame, folder: Path) -> Path | None:
    """The report's runtime distributions of one machine and environment's methods under test."""
    from nsbench.bench.figures import runtime_distribution, saving_as
    from nsbench.bench.summary import reference_grade
    from nsbench.bench.tables import fixed_target

    long = fixed_target(rows, TARGETS)
    tested = long[~long["integrator"].map(reference_grade).astype(bool)]
    with saving_as(("png",)):
        fig = runtime_distribution(tested, _styles(sorted(tested["integrator"].unique())), folder)
    return None if fig is None else fig.png


def _table(frame: pd.DataFrame) -> str:
    from nsbench.render import html as html_table

    shown = frame[list(SHOWN)].rename(columns=SHOWN).assign(tied=frame["tie"].map({True: "=", False: ""}))
    shown["commit"] = shown["commit"].astype(str).str[:10]
    return html_table(shown)


def _block(rows: pd.DataFrame, board: pd.DataFrame, out: Path, first: bool) -> tuple[str, Path | None]:
    """The HTML of one (machine, environment): its figure and its leaderboard tables."""
    from nsbench.bench.figures import slug

    machine, env = str(rows["machine"].iloc[0]), str(rows["environment"].iloc[0])
    png = _ecdf(rows, out / "figures" / slug(f"{machine}_{env}"))
    head = f"<h2>{html.escape(machine)}, environment {html.escape(env)}</h2>"
    figure = (
        f'<img src="{html.escape(png.relative_to(out).as_posix())}" alt="runtime distributions of {html.escape(machine)}">'
        if png is not None
        else "<p>No (problem, target) pair can be graded here: no runtime distribution.</p>"
    )
    tables = []
    for (problem, target), part in board.groupby(["problem", "target"], sort=False):
        tables.append(f"<h3>{html.escape(str(problem))}, switching-time error &le; {target:g}</h3>{_table(part)}")
    body = "".join(tables) or "<p>No graded run of a method under test reaches a target here.</p>"
    if first:  # the figure and the first table side by side: both on the first screen
        return f'{head}<div class="first"><div>{figure}</div><div>{body}</div></div>', png
    return f"{head}{figure}{body}", png


BIF_NOTE = (
    "Each entry's bifurcation value, located with its own flow, its error against the reference's "
    "location and its cost, as the run submitted them (not re-graded by the archive). " + BIF_RANKING
)


def _bifurcation_section(tables: Tables) -> str:
    """The bifurcation-target leaderboard, one table per (problem, target, machine, environment); '' if none."""
    from nsbench.render import html as html_table

    board = bifurcation_board(tables)
    if board.empty:
        return ""
    parts = [f"<h2>Bifurcation targets</h2><p>{html.escape(BIF_NOTE)}</p>"]
    for (problem, target, machine, env), block in board.groupby(
        ["problem", "target", "machine", "environment"], sort=False
    ):
        shown = block.drop(columns=["problem", "target", "machine", "environment", "message"])
        shown = shown.assign(
            rank=shown["rank"].map(lambda r: "" if pd.isna(r) else str(int(r))),
            tie=shown["tie"].map({True: "=", False: ""}),
        ).rename(columns={"tie": "tied", "reason": "not ranked because", "configurations": "of"})
        parts.append(
            f"<h3>{html.escape(str(problem))}, bifurcation target {html.escape(str(target))} "
            f"({html.escape(str(machine))}, environment {html.escape(str(env))})</h3>"
            f'<div class="box">{html_table(shown.assign(commit=shown["commit"].str[:10]))}</div>'
        )
    return "".join(parts)


def page(tables: Tables, out: Path) -> tuple[str, list[Path]]:
    """The site's HTML and the figures it shows (written to ``out/figures``)."""
    from nsbench.render import html as html_table

    runs = tables.runs[["run_id", "machine", "environment", "commit"]]
    rows = tables.rows[tables.rows["graded"].fillna(False).astype(bool)].merge(runs, on="run_id", how="left")
    board = leaderboard(tables)
    blocks, figures = [], []
    for k, ((machine, env), group) in enumerate(rows.groupby(["machine", "environment"], sort=True)):
        part = board[(board["machine"] == machine) & (board["environment"] == env)]
        text, png = _block(group.reset_index(drop=True), part, out, first=k == 0)
        blocks.append(text)
        figures += [png] if png is not None else []
    listed = tables.runs[
        ["run_id", "machine", "environment", "commit", "suite", "added", "n_rows", "n_graded", "marks"]
    ]
    body = (
        f"<h1>nsbench archive: leaderboard</h1><p>{html.escape(NOTE)} Ties (=): the timings of the entries of one "
        "rank cannot be told apart (the report's rule).</p>"
        + ("".join(blocks) or "<p>The archive holds no graded run.</p>")
        + _bifurcation_section(tables)
        + f"<h2>Runs</h2>{html_table(listed)}"
    )
    head = f'<meta charset="utf-8"><title>nsbench archive</title><style>{STYLE}</style>'
    return f'<!DOCTYPE html>\n<html lang="en"><head>{head}</head><body>{body}</body></html>\n', figures


def build_site(request: ArchiveSiteRequest) -> ArchiveSiteOutcome:
    """Write the request's site (every archive file checked on read: ``ConfigError`` if damaged)."""
    from nsbench.archive.load import load
    from nsbench.files import write_atomic

    # the page shows only the rows, and not their dense states and event logs (checked all the same)
    tables = load(request.archive, events=False, bulky=False)
    out = Path(request.out)
    out.mkdir(parents=True, exist_ok=True)
    text, figures = page(tables, out)
    index = write_atomic(out / "index.html", text)
    print(f"written: {index} ({len(figures)} figure(s))")
    return ArchiveSiteOutcome(index, tuple(figures))
