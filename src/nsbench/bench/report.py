"""``nsbench report DIR``: report.md, a self-contained index.html (figures embedded as
base64 PNG), table.tex for papers, and the figures as PNG, SVG and PDF under ``figures/``.

The report is built once as a list of blocks (headings, paragraphs, lists,
tables, figures) and rendered by the jinja2 templates ``report.md`` and
``report.html`` (``nsbench/templates``); tables are laid out by pandas through
:mod:`nsbench.render`, and ``table.tex`` by pandas' Styler (booktabs, long
tables as ``longtable``).
"""

from __future__ import annotations

import base64
import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Sequence

import pandas as pd

from nsbench import render
from nsbench.bench import classes, columns, storage
from nsbench.bench.figures import (
    Figure,
    _styles,
    start_report_figures,
    runtime_distribution,
    saving_as,
    scaling_report_figures,
)
from nsbench.bench.labels import options_text
from nsbench.bench.reference import failed_status
from nsbench.bench.scaling import SCALING_CAPTION, scaling_summary, scaling_table
from nsbench.bench.summary import (
    compact,
    conditioning_table,
    display,
    findings,
    problem_summary,
    reference_costs,
    reference_grade,
    samples_of,
    wrong_sequences,
)
from nsbench.bench.tables import (
    DEFAULT_TARGETS,
    fixed_target,
    fixed_target_wide,
    problem_groups,
    ranking,
    work_text,
)
from nsbench.bench.timing import WIDE_SPREAD, noise_line, setup_table, wide_spread
from nsbench.status import ReferenceStatus, Status

#: The columns of the report's tables of result rows, from their declarations (nsbench.bench.columns).
_RESULT_COLUMNS = list(columns.in_table(columns.CASES))
_FAILURE_COLUMNS = list(columns.in_table(columns.FAILURES))
_PROBLEM_ERROR_COLUMNS = list(columns.in_table(columns.PROBLEM_ERRORS))


@dataclass
class Report:
    """Paths of what :func:`write_report` wrote, and the tables it computed."""

    markdown: Path
    html: Path
    latex: Path
    figures: list[Figure]
    fixed_target: pd.DataFrame
    ranking: pd.DataFrame


@dataclass
class Block:
    """One piece of a report: ``kind`` is ``h2``, ``h3``, ``p``, ``list``, ``table``, ``figure`` or ``pre``.

    ``text`` (headings, paragraphs, ``pre``; Markdown-ish: `code` and **bold**),
    ``items`` (lists), ``table`` (a frame, options JSON made readable), ``figure``;
    ``css`` a class for the HTML page.
    """

    kind: str
    text: str = ""
    items: list[str] = field(default_factory=list)
    table: pd.DataFrame | None = None
    figure: Figure | None = None
    css: str = ""

    @property
    def png_base64(self) -> str:
        return base64.b64encode(self.figure.png.read_bytes()).decode() if self.figure is not None else ""


def _table(frame: pd.DataFrame, css: str = "") -> Block:
    return Block("table", table=_readable(frame), css=f"tbl {css}".strip())


def _figure(fig: Figure, heading: bool = True) -> list[Block]:
    return ([Block("h3", fig.title)] if heading else []) + [Block("figure", figure=fig)]


def _error_cells(frame: pd.DataFrame) -> list:
    """``switch_err_max`` for reading: a run within the reference's certified error is not given a number."""
    at_ref = frame["at_ref_accuracy"] if "at_ref_accuracy" in frame else pd.Series(False, index=frame.index)
    return [
        f"<= {e:.2g} (at reference accuracy)" if flag is True and e == e else e
        for e, flag in zip(frame["switch_err_max"], at_ref.astype(object))
    ]


def _readable(frame: pd.DataFrame) -> pd.DataFrame:
    return frame.assign(options=frame["options"].map(options_text)) if "options" in frame else frame


def markdown_table(frame: pd.DataFrame) -> str:
    """A GitHub-flavoured Markdown table, options made readable (:func:`nsbench.render.markdown`)."""
    return render.markdown(_readable(frame))


def latex_table(frame: pd.DataFrame, caption: str, label: str) -> str:
    """A booktabs table (a ``longtable`` when long), options made readable (:func:`nsbench.render.latex`)."""
    return render.latex(_readable(frame), caption, label)


@dataclass(frozen=True)
class Completeness:
    """How much of its suite a results folder holds: the suite's cases, and the labels of those it lacks."""

    planned: int
    missing: tuple[str, ...]
    #: The command that computes the missing cases (recorded by the CLI), or ``''``.
    resume: str = ""

    @property
    def held(self) -> int:
        return self.planned - len(self.missing)

    @property
    def partial(self) -> bool:
        return bool(self.missing)

    def title(self) -> str:
        """The report's title: ``nsbench report``, and when cases are missing, how many of how many it holds."""
        if not self.partial:
            return "nsbench report"
        return f"nsbench report (partial: {self.held} of {self.planned} cases)"

    def text(self, shown: int = 8) -> str:
        """The sentence under the title of a partial report: what is missing and how to compute it."""
        names = ", ".join(f"`{m}`" for m in self.missing[:shown])
        more = f" and {len(self.missing) - shown} more" if len(self.missing) > shown else ""
        how = (
            f"`{self.resume}` computes only the missing cases and writes the report again"
            if self.resume
            else "running the same suite into this folder again computes only the missing cases"
        )
        return (
            f"**Partial report.** This folder holds {self.held} of the suite's {self.planned} cases: the run was "
            f"interrupted or failed before {len(self.missing)} of them ({names}{more}). Every table and figure "
            f"below is of the cases held; {how}."
        )


def completeness(frame: pd.DataFrame, prov: dict) -> Completeness | None:
    """The suite of ``prov`` (as the run recorded it) against the cases of ``frame``; ``None`` when the
    provenance holds no suite or it can no longer be built (a plug-in gone, an older layout).

    The planned cases are those of the integrators the run selected (``integrators_selected``): a suite
    that takes every registered integrator would select, when the report is written, one registered
    after the run too. A folder written before that record counts the integrators of its rows.
    """
    from nsbench.bench.suite import Suite
    from nsbench.errors import NsbenchError

    if not isinstance(prov.get("suite"), dict):
        return None
    try:
        cases = {c.case_id: c for c in Suite.from_dict(prov["suite"]).cases()}
    except (NsbenchError, TypeError, ValueError, KeyError):
        return None
    held = set(frame["case_id"]) if "case_id" in frame else set()
    recorded = prov.get("integrators_selected")
    if isinstance(recorded, list):
        selected = set(recorded)
    else:
        selected = set(frame["integrator"].unique()) if "integrator" in frame else set()
    cases = {key: c for key, c in cases.items() if c.integrator in selected}
    missing = tuple(c.label for key, c in cases.items() if key not in held)
    return Completeness(len(cases), missing, str(prov.get("resume_command", "")))


def _status_counts(frame: pd.DataFrame) -> pd.DataFrame:
    counts = frame.groupby("status").size().rename("cases").reset_index()
    return counts.sort_values("cases", ascending=False)


def _problems_text(frame: pd.DataFrame, prov: dict) -> list[str]:
    suite = prov.get("suite", {})
    span = suite.get("t_span", [frame["t0"].min(), frame["t_end"].max()])
    lines = [
        f"Suite `{suite.get('name', frame['suite'].iloc[0])}`: {len(frame)} cases, "
        f"{frame['problem_label'].nunique()} problems, {frame['integrator'].nunique()} integrators, "
        f"time span [{span[0]:g}, {span[1]:g}]."
    ]
    for label, group in problem_groups(frame):
        known = group[group["reference_status"].fillna("") != ""]  # rows of an old crash may lack it
        first = (known if len(known) else group).iloc[0]
        ref, status = first["reference"] or "none", first["reference_status"]
        lines.append(f"- `{label}`: reference `{ref}`" + ("" if status == ReferenceStatus.OK else f" ({status})"))
    return lines


def run_failures(frame: pd.DataFrame) -> list[str]:
    """What went wrong in the run itself (not an integrator's failure): failed references, crashes."""
    lines = []
    bad = frame[frame["reference_status"].map(failed_status)]
    for label, group in problem_groups(bad):
        lines.append(
            f"The reference of `{label}` could not be computed ({group['reference_status'].iloc[0]}): "
            "its cases have no accuracy metrics."
        )
    crashed = frame[frame["status"] == Status.CRASHED]
    if len(crashed):
        names = ", ".join(f"`{r.problem_label} {r.integrator}`" for r in crashed.itertuples())
        lines.append(f"{len(crashed)} case(s) crashed their worker process: {names} (see Statuses).")
    return lines


#: Rows of the wide-spread list in a report (the widest; the rest are counted).
SPREAD_ROWS = 15


def _spread_table(frame: pd.DataFrame) -> pd.DataFrame:
    wide = wide_spread(frame)
    table = wide[["problem_label", "integrator", "options", "wall_time", "wall_time_min", "wall_time_max"]]
    table = table.rename(columns={"problem_label": "problem"}).assign(
        spread=wide["wall_spread"].map(lambda s: f"{100 * s:.0f}%")
    )
    return table.head(SPREAD_ROWS).assign(_more=len(table) - min(len(table), SPREAD_ROWS))


def _timed(frame: pd.DataFrame) -> pd.Series:
    """The rows with a timed sample: a success with a wall time."""
    wall = (
        pd.to_numeric(frame["wall_time"], errors="coerce")
        if "wall_time" in frame
        else pd.Series(float("nan"), frame.index)
    )
    return (frame["status"] == Status.SUCCESS) & wall.notna()


def _timing_text(frame: pd.DataFrame) -> str:
    if not _timed(frame).any():
        return "No case of this report was timed (none succeeded with a timed sample): it states no times."
    ok = frame[frame["status"] == Status.SUCCESS]
    reps = ok["n_repeats"].dropna()
    runs = (
        f"{int(reps.min())}"
        if len(reps) and reps.min() == reps.max()
        else (f"{int(reps.min())}-{int(reps.max())}" if len(reps) else "the")
    )
    looped = int((pd.to_numeric(ok.get("loops"), errors="coerce") > 1).sum()) if "loops" in ok else 0
    loops = (
        f" {looped} case(s) run shorter than the suite's minimum sample time, so each of their samples is "
        "the mean of a loop of 2, 5, 10, 20, ... back-to-back runs lasting at least that long (the count is "
        "the column loops)."
        if looped
        else ""
    )
    return (
        f"Times are medians of {runs} timed samples per case (seconds per run), all after an untimed warm-up "
        "(setup and compilation apart, never while another case was timed), taken in rounds over all cases so "
        "that a case's samples are spread over the run and meet the machine's drifting speed instead of one "
        f"moment of it.{loops} '±' is half the min-max range of the samples relative to the median. An "
        "interval [a-b] of a time is the distribution-free interval of its median (order statistics; with 5 "
        "samples the range, 94 %); of a cost ratio (the ratio of the two medians), the 95 % Moses interval of "
        "the scale factor between the two methods' times (from the ratios of every pair of samples)."
    )


SETUP_CAPTION = (
    "Set-up (compilation of numba kernels and heyoka models, SUNDIALS and other objects) is charged to "
    "the integrator, not to an accuracy level: the first case of an integrator that a worker process "
    "warms up compiles, and the others find it compiled, so a case's own setup_time only says which "
    "case came first. 'first_use' is the largest set-up over the integrator's cases (and the case "
    "that paid it), 'later' the median over its other cases. Set-up is never part of a timed sample."
)


def with_engine_share(frame: pd.DataFrame) -> pd.DataFrame:
    """``frame`` with ``engine_share = 1 - integrator_time / wall_time``: the part of a run's wall
    time spent in nsbench's hybrid core (events, records, callbacks) rather than in the integrator."""
    return frame.assign(engine_share=columns.engine_share(frame))  # the column's own definition


def engine_share_table(frame: pd.DataFrame) -> pd.DataFrame:
    """Per integrator, over its successful cases: median and largest engine share, and median
    wall and integrator time (what a reader needs to see whether the ranking ranks the integrator)."""
    ok = with_engine_share(frame)
    ok = ok[(ok["status"] == Status.SUCCESS) & ok["engine_share"].notna()]
    if ok.empty:
        return pd.DataFrame(columns=["integrator", "cases", "engine_share_median", "engine_share_max"])
    table = ok.groupby("integrator").agg(
        cases=("engine_share", "size"),
        engine_share_median=("engine_share", "median"),
        engine_share_max=("engine_share", "max"),
    )
    return table.sort_values("engine_share_median", ascending=False).reset_index()


ENGINE_CAPTION = (
    "Ranking and fixed-target times are wall times: the whole run as a user calls it. "
    "integrator_time is the part spent inside the integrator's own code (its compiled arc "
    "kernel, or its per-arc Python call), measured by the hybrid core's clock; engine_share "
    "= 1 - integrator_time / wall_time is nsbench's own part (event handling, records, the "
    "per-arc callback). Per integrator, over its successful cases:"
)


FT_CAPTION = (
    "Fixed-target cost: for each switching-time error target, the cheapest configuration of each "
    "integrator that reaches it (median warm wall time ± half its min-max range / nfev, the evaluations of "
    "the method's model: right-hand sides for the event-driven and smooth-model methods, for moreau-jean the "
    "one-step problems of its steps, a stick/slip status solved and tested each; 'n/a' where the method counts "
    "none); '-' not "
    "reached (a wrong event sequence never counts), 'no ref' no reference for that problem, "
    "'unsupported' the integrator refuses the problem, 'not graded' a target below the reference's "
    "certified error or the problem's double-precision floor, 'ref' the problem's reference itself "
    "(its cost; its error is 0 by construction)."
)
RANK_CAPTION = (
    "Ranking by time to reach each (problem, target), in tiers by the rule of the answer's ties: the fastest "
    "integrator there and every one whose timing cannot be told from it share rank 1 (the methods the answer "
    "calls tied for the cheapest), the fastest of the rest and those tied with it share the next rank (1 + "
    "the number ranked before them), and so on; one that does not reach a target is ranked last there. "
    "mean_rank is over the (problem, target) pairs, and integrators with the same mean_rank and targets "
    "reached share the same integer rank (the next rank skips as many). geo_mean_time is over the targets it "
    "reached; problems an integrator refuses or is the reference of are left out, and reference-grade "
    "integrators are not ranked."
)
COMPACT_CAPTION = (
    "Cheapest method under test reaching a switching-time error of {target} on each problem, or the "
    "methods tied for it (median warm wall time per run with the interval of that median), the next "
    "fastest and its cost ratio with the ratio's 95 % interval, and how many methods reach the "
    "target."
)


def write_report(
    directory: str | Path, results: pd.DataFrame | None = None, formats: Sequence[str] = ("png",)
) -> Report:
    """Write the report of the results stored in ``directory`` (or of ``results``) into it.

    ``formats`` are the figures' file formats (:data:`nsbench.bench.figures.REPORT_FORMATS`):
    PNG always, which the HTML page embeds; ``"svg"`` and ``"pdf"`` (for a LaTeX paper) on
    request, each a further draw of every figure. A format not asked for loses its files of an
    earlier report of the folder, which would no longer match.
    """
    with saving_as(formats):
        return _write_report(directory, results)


def _write_report(directory: str | Path, results: pd.DataFrame | None) -> Report:
    d = Path(directory)
    storage.check_no_links(d)  # what the report writes there replaces what is there: never through a link
    frame = with_engine_share(storage.load_results(d) if results is None else results)
    drawn = start_report_figures(frame, d / "figures")  # drawn in other processes while the tables are made
    prov = storage.read_provenance(d)
    targets = tuple(prov.get("suite", {}).get("targets", DEFAULT_TARGETS))
    long = fixed_target(frame, targets)
    wide = fixed_target_wide(long)
    # reference-grade integrators are what the others are measured against: never ranked
    tested = long[~long["integrator"].map(reference_grade).astype(bool)]
    # ties in the ranking follow the timing noise, as in the answer (summary.tied_with)
    rank = ranking(tested, {row["case_id"]: samples_of(row) for _, row in frame.iterrows()})
    summary = problem_summary(frame, targets)
    scaling = scaling_table(frame)
    scaling_fit = scaling_summary(scaling)
    scaling_figs = scaling_report_figures(frame, scaling, scaling_fit, d / "figures") if len(scaling) else []
    ecdf = runtime_distribution(tested, _styles(sorted(frame["integrator"].unique())), d / "figures")
    figures = scaling_figs + ([ecdf] if ecdf is not None else [])
    from nsbench.bench import targets as bt

    bif_rows = bt.load_rows(d)
    bif_figs = bt.report_figures(bif_rows, d / "figures") if len(bif_rows) else []

    held = completeness(frame, prov)
    blocks = [Block("p", held.text())] if held is not None and held.partial else []
    family_table = _families_table(frame, targets)
    if len(scaling):  # a scaling study's question is how the cost grows with n: its answer comes first
        blocks += [
            Block("h2", "Scaling with the number of blocks"),
            Block("p", SCALING_CAPTION),
            _table(_problem_column(scaling_fit)),
        ]
        for fig in scaling_figs:
            blocks += _figure(fig, heading=False)
        blocks += [Block("p", SCALING_DETAIL_CAPTION), _table(_scaling_view(scaling))]
    family_blocks = _family_blocks(family_table, targets)
    answer_blocks = _answer_blocks(frame, prov, summary, ecdf, classes.class_summary(frame, targets))
    blocks += answer_blocks + family_blocks if answer_leads(family_table) else family_blocks + answer_blocks
    blocks += _context_blocks(frame, prov)
    blocks += [Block("h2", "Fixed-target table"), Block("p", FT_CAPTION), _table(wide)]
    blocks += _spread_blocks(frame)
    blocks += [
        Block("h2", "Ranking"),
        Block("p", RANK_CAPTION),
        _table(rank),
        Block("h2", "Integrator time and engine share"),
        Block("p", ENGINE_CAPTION),
        _table(engine_share_table(frame)),
        Block("h2", "Set-up per integrator"),
        Block("p", SETUP_CAPTION),
        _table(setup_table(frame)),
        Block("h2", "Figures"),
    ]
    per_problem = drawn()
    figures += per_problem
    for fig in per_problem:
        blocks += _figure(fig)
    if len(bif_rows):
        blocks += [
            Block("h2", "Bifurcation-point error"),
            Block("p", "Targets and their reference values:"),
            _table(bt.reference_table(bif_rows)),
            Block("p", bt.TABLE_CAPTION),
            _table(bt.report_table(bif_rows)),
        ]
        for fig in bif_figs:
            blocks += _figure(fig)
    failures = frame[frame["status"] != Status.SUCCESS][_FAILURE_COLUMNS]
    blocks += [Block("h2", "Statuses"), _table(_status_counts(frame))]
    if len(failures):
        blocks += [Block("p", "Cases that did not succeed:"), _table(failures)]
    results_view = (
        frame[_RESULT_COLUMNS]
        .assign(switch_err_max=_error_cells(frame), nfev=frame["nfev"].map(work_text))  # 0 is no count: n/a
        .rename(columns={"problem_label": "problem"})
    )
    blocks += [Block("h2", "All cases"), _table(results_view)]
    blocks += _problem_errors(frame)
    blocks += [
        Block("h2", "Provenance"),
        Block("pre", json.dumps(prov, indent=1, default=str)),
    ]
    page = {"title": "nsbench report" if held is None else held.title(), "blocks": blocks, "provenance": prov}
    (d / "report.md").write_text(render.page("report.md", **page))
    (d / "index.html").write_text(render.page("report.html", **page))
    (d / "table.tex").write_text(_latex(prov, summary, wide, rank, reference_costs(frame), family_table))
    if len(scaling):
        (d / "scaling.csv").write_text(scaling.to_csv(index=False))
        (d / "scaling_summary.csv").write_text(scaling_fit.to_csv(index=False))
    return Report(d / "report.md", d / "index.html", d / "table.tex", figures + bif_figs, long, rank)


def _problem_errors(frame: pd.DataFrame) -> list[Block]:
    """The errors some problems define (impacts: penetration, energy; friction: break-away times), one
    row per case that has one, empty where the row's problem does not define it; nothing if no case has."""
    measured = [c for c in _PROBLEM_ERROR_COLUMNS if columns.BY_NAME[c].dtype == columns.FLOAT]
    rows = frame[frame[measured].notna().any(axis=1)] if measured else frame.iloc[:0]
    if rows.empty:
        return []
    caption = "; ".join(f"`{c}`: {columns.BY_NAME[c].meaning}" for c in measured)
    return [
        Block("h2", "Problem-specific errors"),
        _table(rows[_PROBLEM_ERROR_COLUMNS].rename(columns={"problem_label": "problem"})),
        Block("p", f"Empty where the case's problem does not define the error. {caption}."),
    ]


def _families_table(frame: pd.DataFrame, targets: tuple[float, ...]) -> pd.DataFrame:
    """The per-family table (:func:`nsbench.bench.families.families_table`) when the results hold a
    whole-system method (time-stepping, switch model, smoothing); an empty frame otherwise."""
    from nsbench.bench import families

    if not families.has_whole_system(frame):
        return pd.DataFrame()
    return families.families_table(frame, targets)


def answer_leads(family_table: pd.DataFrame) -> bool:
    """Whether the report opens with the answer (the cheapest method per target) before the answer per family.

    The families suite's question is what each family costs and leaves: its answer per family comes first. A
    suite with several event-driven methods on a problem beside the other families (the default) asks first
    which method is cheapest, with its ties.
    """
    if not len(family_table):
        return True
    driven = (family_table["family"] == "event-driven").groupby(family_table["problem"]).sum()
    return int(driven.max()) > 1


def _family_blocks(table: pd.DataFrame, targets: tuple[float, ...]) -> list[Block]:
    """The answer per family of methods (:mod:`nsbench.bench.families`) from its table; nothing when it is empty."""
    from nsbench.bench import families

    if not len(table):
        return []
    return [
        Block("h2", "The answer per family of methods"),
        Block("list", items=families.families_answer(table, targets)),
        Block("p", families.CAPTION),
        _table(table),
    ]


def _answer_blocks(
    frame: pd.DataFrame, prov: dict, summary: pd.DataFrame, ecdf: Figure | None, by_class: pd.DataFrame | None = None
) -> list[Block]:
    """The report's opening: the machine's noise, what failed in the run, the answer by problem class when the
    run has more than one class, the answer per problem in words and tables, wrong sequences, references apart,
    the runtime distributions."""
    blocks = []
    noise = noise_line(frame, prov)
    if noise:
        blocks.append(Block("p", noise, css="noise"))
    problems = run_failures(frame)
    if problems:
        blocks += [Block("p", "**This run is incomplete:**"), Block("list", items=problems)]
    absent = prov.get("unavailable_integrators") or {}
    if absent:  # engines the suite would have run, left out because their extra is not installed here
        items = [f"`{name}`: {why}" for name, why in sorted(absent.items())]
        blocks += [Block("p", "**Not run here** (left out of the suite):"), Block("list", items=items)]
    if summary.empty:
        return blocks
    wrong, refs = wrong_sequences(frame), reference_costs(frame)
    words = findings(summary, wrong, conditioning_table(frame))
    if by_class is not None and by_class["class"].nunique() > 1:
        blocks += [
            Block("h2", "The answer by problem class"),
            Block("list", items=classes.class_findings(by_class), css="answer"),
            Block("p", CLASS_CAPTION),
            _table(classes.display(by_class), "summary"),
        ]
    blocks += [
        Block("h2", "The answer"),
        Block("list", items=words, css="answer"),
        Block("p", ANSWER_CAPTION),
        _table(display(summary), "summary"),
    ]
    if len(wrong):
        blocks += [Block("p", "**Wrong event sequences.** " + WRONG_CAPTION), _table(wrong)]
    if len(refs):
        blocks += [Block("p", REFERENCE_CAPTION), _table(refs)]
    if ecdf is not None:
        blocks += [Block("h2", "Runtime distributions"), *_figure(ecdf, heading=False)]
    return blocks


def _context_blocks(frame: pd.DataFrame, prov: dict) -> list[Block]:
    text = _problems_text(frame, prov)
    return [Block("p", text[0]), Block("list", items=[t[2:] for t in text[1:]]), Block("p", _timing_text(frame))]


def _spread_blocks(frame: pd.DataFrame) -> list[Block]:
    spread = _spread_table(frame)
    if not len(spread):
        said = (
            f"Every timed case spreads by at most {WIDE_SPREAD:.0%} ((max - min) / median)."
            if _timed(frame).any()
            else "No case of this report was timed: there is no spread to report."
        )
        return [Block("h2", "Timing spread"), Block("p", said)]
    more = int(spread.pop("_more").iloc[0])
    caption = (
        f"Cases whose timed samples spread by more than {WIDE_SPREAD:.0%} ((max - min) / median), widest "
        "first: their times are less certain (a busy machine, or a run that is not repeatable)."
        + (f" {more} more are not listed (see wall_spread in the results)." if more else "")
    )
    return [Block("h2", "Timing spread"), Block("p", caption), _table(spread)]


def _latex(
    prov: dict,
    summary: pd.DataFrame,
    wide: pd.DataFrame,
    rank: pd.DataFrame,
    refs: pd.DataFrame,
    family_table: pd.DataFrame | None = None,
) -> str:
    """``table.tex``: one page-sized table per target, the per-family table (when the results hold a
    whole-system method), then the references, the fixed-target table and the ranking; ``\\input`` it
    after ``\\usepackage{booktabs,longtable,array}``."""
    meta = json.dumps({k: v for k, v in prov.items() if k != "suite"}, default=str)
    tex = ["% nsbench report tables; needs \\usepackage{booktabs,longtable,array}", f"% provenance: {meta}"]
    for target in summary["target"].unique():
        tex += [
            latex_table(
                compact(summary, target), COMPACT_CAPTION.format(target=target), f"tab:nsbench-target-{target}"
            ),
            "",
        ]
    if family_table is not None and len(family_table):
        from nsbench.bench.families import CAPTION as FAMILY_CAPTION

        # the caption's `code` marks are Markdown: in LaTeX they would print as quotes
        tex += [latex_table(family_table, FAMILY_CAPTION.replace("`", ""), "tab:nsbench-families"), ""]
    if len(refs):
        tex += [latex_table(refs, REFERENCE_CAPTION, "tab:nsbench-references"), ""]
    tex += [
        "% Supplement: every integrator and target.",
        latex_table(wide, FT_CAPTION, "tab:nsbench-fixed-target"),
        "",
        latex_table(rank, RANK_CAPTION, "tab:nsbench-ranking"),
        "",
    ]
    return "\n".join(tex)


CLASS_CAPTION = (
    "Grouped by the class each problem declares (friction, impact, sliding, smooth). For each target: "
    "the method with the smallest class cost ratio, the geometric mean over the class's graded problems "
    "of its cost (cheapest configuration reaching the target, median warm wall time) divided by the "
    "cheapest method's cost on the same problem (1: the cheapest on every problem), among the methods "
    "that reach the target on every graded problem of the class; then how many problems it is the "
    "cheapest on (and on how many more its time cannot be told from the cheapest's), the runner-up, and the methods that reach it on some problems only. "
    "Each class cost ratio has its 95 % interval (a bootstrap over the timed samples); methods whose "
    "ratio to the smallest cannot be told from 1 are tied, and all of them are named. "
    "Reference-grade integrators are not ranked. Per-problem answers, with intervals, follow."
)

ANSWER_CAPTION = (
    "For each switching-time error target: the cheapest method under test that reaches it (median "
    "warm wall time per run, with the interval of that median), every other method's cost as a ratio "
    "to the fastest (the ratio of the median times, so never below 1: the fastest is the method of smallest "
    "median) with the ratio's 95 % interval, and the methods that never reach it, with why. "
    "Methods whose times cannot be told apart from the fastest one's (the intervals of their medians "
    "overlap, or the ratio's interval holds 1) are tied: then the cheapest column names every tied "
    "method and 'tied' follows their ratios. A run with a wrong event sequence never reaches a "
    "target. A target below what the reference can certify (or double precision can resolve on that "
    "problem) is not graded."
)
WRONG_CAPTION = (
    "Runs that succeeded with a different event sequence from the reference's (events missed / "
    "extra, after aligning the sequences): they never reach a target and are never the cheapest."
)
REFERENCE_CAPTION = (
    "References, shown apart and not ranked: each problem's reference (what the errors above "
    "are measured against) and the other reference-grade integrators, with their cost. "
    "Certified: the largest bound on the reference's event-time errors, from an independent "
    "run at higher precision; no error is reported below it (a run within it is 'at "
    "reference accuracy') and no target below it is graded. Conditioning: the largest switching-time change per unit change of the start positions "
    "(the reference run again from a start moved by 1e-9); the double floor, that times the "
    "unit roundoff, is how far rounding alone moves any double-precision solution's switching "
    "times. A problem whose floor exceeds 1e-10 cannot be graded in double over its span."
)


SCALING_DETAIL_CAPTION = (
    "Per integrator and n: the cheapest configuration reaching the target, its costs and "
    "set-up time, and why nothing reached it where so."
)


def _problem_column(scaling: pd.DataFrame) -> pd.DataFrame:
    """A scaling table as printed: its ``family`` (the problem without ``n``, such as ``chain/2``) headed
    ``problem``, since the report's "family" is an integrator's family of methods."""
    return scaling.rename(columns={"family": "problem"})


def _scaling_view(scaling: pd.DataFrame) -> pd.DataFrame:
    return _problem_column(scaling.drop(columns=["family"]) if scaling["family"].nunique() == 1 else scaling)
