"""``nsbench report DIR``: report.md, a self-contained index.html (figures embedded as
base64 PNG), table.tex for papers, and the figures as PNG, SVG and PDF under ``figures/``."""

from __future__ import annotations

import base64
import html
import json
import math
from dataclasses import dataclass
from pathlib import Path

import pandas as pd

from nsbench.bench import storage
from nsbench.bench.figures import Figure, report_figures, scaling_report_figures
from nsbench.bench.reference import failed_status
from nsbench.bench.scaling import SCALING_CAPTION, scaling_summary, scaling_table
from nsbench.bench.summary import (compact, conditioning_table, display, findings, problem_summary, reference_costs, reference_grade,
                                   wrong_sequences)
from nsbench.bench.tables import DEFAULT_TARGETS, fixed_target, fixed_target_wide, problem_groups, ranking
from nsbench.bench.timing import WIDE_SPREAD, noise_line, setup_table, wide_spread

_RESULT_COLUMNS = ["problem_label", "integrator", "options", "status", "wall_time", "wall_spread",
                   "integrator_time", "engine_share", "n_repeats", "loops", "nfev", "n_events", "n_missed",
                   "n_extra", "switch_err_max", "switch_digits", "state_err_l2"]


@dataclass
class Report:
    """Paths of what :func:`write_report` wrote, and the tables it computed."""

    markdown: Path
    html: Path
    latex: Path
    figures: list[Figure]
    fixed_target: pd.DataFrame
    ranking: pd.DataFrame


def _fmt(value) -> str:
    if value is None or value is pd.NA or (isinstance(value, float) and value != value):
        return ""
    if isinstance(value, float):
        return f"{value:.3g}"
    return str(value)


def _error_cells(frame: pd.DataFrame) -> list:
    """``switch_err_max`` for reading: a run within the reference's certified error is not given a number."""
    at_ref = frame["at_ref_accuracy"] if "at_ref_accuracy" in frame else pd.Series(False, index=frame.index)
    return [f"<= {e:.2g} (at reference accuracy)" if flag is True and e == e else e
            for e, flag in zip(frame["switch_err_max"], at_ref.astype(object))]


def options_text(text) -> str:
    """An options JSON cell for reading: ``rtol=1e-09, atol=1e-11`` (floats to 4 significant digits)."""
    try:
        options = json.loads(text) if isinstance(text, str) and text.startswith("{") else None
    except ValueError:
        options = None
    if not isinstance(options, dict):
        return "" if text is None or text is pd.NA else str(text)
    return ", ".join(f"{k}={v:.4g}" if isinstance(v, float) else f"{k}={v}" for k, v in options.items())


def _readable(frame: pd.DataFrame) -> pd.DataFrame:
    return frame.assign(options=frame["options"].map(options_text)) if "options" in frame else frame


def markdown_table(frame: pd.DataFrame) -> str:
    """A GitHub-flavoured Markdown table (no optional dependency)."""
    frame = _readable(frame)
    cols = list(frame.columns)
    lines = ["| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]
    for row in frame.itertuples(index=False):
        lines.append("| " + " | ".join(_fmt(v).replace("|", "\\|") for v in row) + " |")
    return "\n".join(lines)


def _tex_escape(text: str) -> str:
    for a, b in (("\\", r"\textbackslash{}"), ("&", r"\&"), ("%", r"\%"), ("_", r"\_"),
                 ("#", r"\#"), ("{", r"\{"), ("}", r"\}"), ("$", r"\$")):
        text = text.replace(a, b) if a != "\\" else text.replace(a, "\x00")
    text = text.replace("\x00", r"\textbackslash{}")
    # text-mode < > ~ ^ print wrongly (or not at all) in LaTeX's default encoding; ± is math
    for a, b in (("<", r"$<$"), (">", r"$>$"), ("±", r"$\pm$"), ("~", r"\textasciitilde{}"),
                 ("^", r"\textasciicircum{}")):
        text = text.replace(a, b)
    return text


def latex_table(frame: pd.DataFrame, caption: str, label: str) -> str:
    """A booktabs ``table`` environment."""
    frame = _readable(frame)
    cols = list(frame.columns)
    lines = [r"\begin{table}[htbp]", r"\centering", r"\small",
             r"\begin{tabular}{" + "l" * 2 + "r" * (len(cols) - 2) + "}", r"\toprule",
             " & ".join(_tex_escape(str(c)) for c in cols) + r" \\", r"\midrule"]
    for row in frame.itertuples(index=False):
        lines.append(" & ".join(_tex_escape(_fmt(v)) for v in row) + r" \\")
    lines += [r"\bottomrule", r"\end{tabular}", rf"\caption{{{_tex_escape(caption)}}}",
              rf"\label{{{label}}}", r"\end{table}"]
    return "\n".join(lines)


def _status_counts(frame: pd.DataFrame) -> pd.DataFrame:
    counts = frame.groupby("status").size().rename("cases").reset_index()
    return counts.sort_values("cases", ascending=False)


def _problems_text(frame: pd.DataFrame, prov: dict) -> list[str]:
    suite = prov.get("suite", {})
    span = suite.get("t_span", [frame["t0"].min(), frame["t_end"].max()])
    lines = [f"Suite `{suite.get('name', frame['suite'].iloc[0])}`: {len(frame)} cases, "
             f"{frame['problem_label'].nunique()} problems, {frame['integrator'].nunique()} integrators, "
             f"time span [{span[0]:g}, {span[1]:g}]."]
    for label, group in problem_groups(frame):
        known = group[group["reference_status"].fillna("") != ""]  # rows of an old crash may lack it
        first = (known if len(known) else group).iloc[0]
        ref, status = first["reference"] or "none", first["reference_status"]
        lines.append(f"- `{label}`: reference `{ref}`" + ("" if status == "ok" else f" ({status})"))
    return lines


def run_failures(frame: pd.DataFrame) -> list[str]:
    """What went wrong in the run itself (not an integrator's failure): failed references, crashes."""
    lines = []
    bad = frame[frame["reference_status"].map(failed_status)]
    for label, group in problem_groups(bad):
        lines.append(f"The reference of `{label}` could not be computed ({group['reference_status'].iloc[0]}): "
                     "its cases have no accuracy metrics.")
    crashed = frame[frame["status"] == "crashed"]
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
        spread=wide["wall_spread"].map(lambda s: f"{100 * s:.0f}%"))
    return table.head(SPREAD_ROWS).assign(_more=len(table) - min(len(table), SPREAD_ROWS))


def _timing_text(frame: pd.DataFrame) -> str:
    ok = frame[frame["status"] == "success"]
    reps = ok["n_repeats"].dropna()
    runs = f"{int(reps.min())}" if len(reps) and reps.min() == reps.max() else \
        (f"{int(reps.min())}-{int(reps.max())}" if len(reps) else "the")
    looped = int((pd.to_numeric(ok.get("loops"), errors="coerce") > 1).sum()) if "loops" in ok else 0
    loops = (f" {looped} case(s) run shorter than the suite's minimum sample time, so each of their samples is "
             "the mean of a loop of 2, 5, 10, 20, ... back-to-back runs lasting at least that long (the count is "
             "the column loops)." if looped else "")
    return (f"Times are medians of {runs} timed samples per case (seconds per run), all after an untimed warm-up "
            "(setup and compilation apart, never while another case was timed), taken in rounds over all cases so "
            "that a case's samples are spread over the run and meet the machine's drifting speed instead of one "
            f"moment of it.{loops} '±' is half the min-max range of the samples relative to the median. An "
            "interval [a-b] of a time is the distribution-free interval of its median (order statistics; with 5 "
            "samples the range, 94 %); of a cost ratio, the 95 % Moses interval of the Hodges-Lehmann ratio "
            "(the median of the ratios of every pair of samples).")


SETUP_CAPTION = ("Set-up (compilation of numba kernels and heyoka models, SUNDIALS and other objects) is charged to "
                 "the integrator, not to an accuracy level: the first case of an integrator that a worker process "
                 "warms up compiles, and the others find it compiled, so a case's own setup_time only says which "
                 "case came first. 'first_use' is the largest set-up over the integrator's cases (and the case "
                 "that paid it), 'later' the median over its other cases. Set-up is never part of a timed sample.")


def with_engine_share(frame: pd.DataFrame) -> pd.DataFrame:
    """``frame`` with ``engine_share = 1 - integrator_time / wall_time``: the part of a run's wall
    time spent in nsbench's hybrid core (events, records, callbacks) rather than in the integrator."""
    if "integrator_time" not in frame:
        frame = frame.assign(integrator_time=math.nan)
    wall = pd.to_numeric(frame["wall_time"], errors="coerce")
    inner = pd.to_numeric(frame["integrator_time"], errors="coerce")
    return frame.assign(engine_share=(1.0 - inner / wall).where(wall > 0).clip(lower=0.0))


def engine_share_table(frame: pd.DataFrame) -> pd.DataFrame:
    """Per integrator, over its successful cases: median and largest engine share, and median
    wall and integrator time (what a reader needs to see whether the ranking ranks the integrator)."""
    ok = with_engine_share(frame)
    ok = ok[(ok["status"] == "success") & ok["engine_share"].notna()]
    if ok.empty:
        return pd.DataFrame(columns=["integrator", "cases", "engine_share_median", "engine_share_max"])
    table = ok.groupby("integrator").agg(cases=("engine_share", "size"),
                                         engine_share_median=("engine_share", "median"),
                                         engine_share_max=("engine_share", "max"))
    return table.sort_values("engine_share_median", ascending=False).reset_index()


ENGINE_CAPTION = ("Ranking and fixed-target times are wall times: the whole run as a user calls it. "
                  "integrator_time is the part spent inside the integrator's own code (its compiled arc "
                  "kernel, or its per-arc Python call), measured by the hybrid core's clock; engine_share "
                  "= 1 - integrator_time / wall_time is nsbench's own part (event handling, records, the "
                  "per-arc callback). Per integrator, over its successful cases:")


def write_report(directory: str | Path, results: pd.DataFrame | None = None) -> Report:
    """Write the report of the results stored in ``directory`` (or of ``results``) into it."""
    d = Path(directory)
    frame = with_engine_share(storage.load_results(d) if results is None else results)
    prov = storage.read_provenance(d)
    targets = tuple(prov.get("suite", {}).get("targets", DEFAULT_TARGETS))
    long = fixed_target(frame, targets)
    wide = fixed_target_wide(long)
    # reference-grade integrators are what the others are measured against: never ranked
    rank = ranking(long[~long["integrator"].map(reference_grade).astype(bool)])
    answer = _Answer(frame, targets)
    scaling = scaling_table(frame)
    scaling_fit = scaling_summary(scaling)
    scaling_figs = scaling_report_figures(frame, scaling, scaling_fit, d / "figures") if len(scaling) else []
    figures = scaling_figs + report_figures(frame, d / "figures")
    from nsbench.bench import targets as bt

    bif_rows = bt.load_rows(d)
    bif_figs = bt.report_figures(bif_rows, d / "figures") if len(bif_rows) else []
    bif = (bif_rows, bif_figs)
    results_view = frame[_RESULT_COLUMNS].assign(switch_err_max=_error_cells(frame)).rename(
        columns={"problem_label": "problem"})
    failures = frame[frame["status"] != "success"][["problem_label", "integrator", "options", "status",
                                                     "message"]]
    ft_caption = ("Fixed-target cost: for each switching-time error target, the cheapest configuration "
                  "of each integrator that reaches it (median warm wall time ± half its min-max range "
                  "/ nfev); '-' not reached "
                  "(a wrong event sequence never counts), 'no ref' no reference for that problem, "
                  "'unsupported' the integrator refuses the problem, 'not graded' a target below the "
                  "reference's certified error or the problem's double-precision floor, 'ref' the problem's "
                  "reference itself (its cost; its error is 0 by construction).")
    rank_caption = ("Ranking by time to reach each (problem, target); an integrator that does not reach "
                    "a target is ranked last there. geo_mean_time is over the targets it reached; problems "
                    "an integrator refuses or is the reference of are left out, and reference-grade "
                    "integrators are not ranked.")

    problems = run_failures(frame)
    spread = _spread_table(frame)
    more = int(spread.pop("_more").iloc[0]) if len(spread) else 0
    spread_caption = (f"Cases whose timed runs spread by more than {WIDE_SPREAD:.0%} ((max - min) / median), "
                      "widest first: their times are less certain (a busy machine, or a run that is not "
                      "repeatable)." + (f" {more} more are not listed (see wall_spread in the results)."
                                        if more else ""))
    noise = noise_line(frame, prov)
    setup = setup_table(frame)
    md = ["# nsbench report", ""]
    if noise:
        md += [noise, ""]
    if problems:
        md += ["**This run is incomplete:**", "", *[f"- {line}" for line in problems], ""]
    md += answer.markdown()
    md += [*_problems_text(frame, prov), "", _timing_text(frame), ""]
    if len(scaling):
        md += ["## Scaling with the number of blocks", "", SCALING_CAPTION, "", markdown_table(scaling_fit), ""]
        for fig in scaling_figs:
            md += [f"![{fig.title}](figures/{fig.png.name})", "", fig.caption, ""]
        md += [SCALING_DETAIL_CAPTION, "", markdown_table(_scaling_view(scaling)), ""]
    md += ["## Fixed-target table", "",
           ft_caption, "", markdown_table(wide), "", "## Timing spread", ""]
    md += ([spread_caption, "", markdown_table(spread), ""] if len(spread) else
           [f"Every timed case spreads by at most {WIDE_SPREAD:.0%} ((max - min) / median).", ""])
    engine = engine_share_table(frame)
    md += ["## Ranking", "", rank_caption, "", markdown_table(rank), "", "## Integrator time and engine share",
           "", ENGINE_CAPTION, "", markdown_table(engine), "", "## Set-up per integrator", "", SETUP_CAPTION, "",
           markdown_table(setup), "", "## Figures", ""]
    for fig in figures[len(scaling_figs):]:
        md += [f"### {fig.title}", "", f"![{fig.title}](figures/{fig.png.name})", "", fig.caption, ""]
    if len(bif_rows):
        md += ["## Bifurcation-point error", "", "Targets and their reference values:", "",
               markdown_table(bt.reference_table(bif_rows)), "", bt.TABLE_CAPTION, "",
               markdown_table(bt.report_table(bif_rows)), ""]
        for fig in bif_figs:
            md += [f"### {fig.title}", "", f"![{fig.title}](figures/{fig.png.name})", "", fig.caption, ""]
    md += ["## Statuses", "", markdown_table(_status_counts(frame)), ""]
    if len(failures):
        md += ["Cases that did not succeed:", "", markdown_table(failures), ""]
    md += ["## All cases", "", markdown_table(results_view), "", "## Provenance", ""]
    md += [f"- {k}: `{json.dumps(v, default=str)}`" for k, v in prov.items()]
    (d / "report.md").write_text("\n".join(md) + "\n")

    tex = [f"% nsbench report tables; provenance: {json.dumps({k: v for k, v in prov.items() if k != 'suite'}, default=str)}"]
    for target in answer.summary["target"].unique():  # one page-sized table per target first
        tex += [latex_table(compact(answer.summary, target),
                            f"Cheapest method under test reaching a switching-time error of {target} on each "
                            "problem, or the methods tied for it (median warm wall time per run with the interval "
                            "of that median), the next fastest and its cost ratio with the ratio's 95 % interval, "
                            "and how many methods reach the target.",
                            f"tab:nsbench-target-{target}"), ""]
    tex += ["% Supplement: every integrator and target.",
            latex_table(wide, ft_caption, "tab:nsbench-fixed-target"), "",
            latex_table(rank, rank_caption, "tab:nsbench-ranking"), ""]
    (d / "table.tex").write_text("\n".join(tex))

    if len(scaling):
        (d / "scaling.csv").write_text(scaling.to_csv(index=False))
        (d / "scaling_summary.csv").write_text(scaling_fit.to_csv(index=False))
    (d / "index.html").write_text(_html(frame, prov, wide, rank, figures, failures, results_view,
                                        ft_caption, rank_caption, problems, spread, spread_caption, engine,
                                        (scaling, scaling_fit, scaling_figs), answer, bif, noise, setup))
    return Report(d / "report.md", d / "index.html", d / "table.tex", figures + bif_figs, long, rank)


ANSWER_CAPTION = ("For each switching-time error target: the cheapest method under test that reaches it (median "
                  "warm wall time per run, with the interval of that median), every other method's cost as a ratio "
                  "to the fastest with the ratio's 95 % interval, and the methods that never reach it, with why. "
                  "Methods whose times cannot be told apart from the fastest one's (the intervals of their medians "
                  "overlap, or the ratio's interval holds 1) are tied: then the cheapest column names every tied "
                  "method and 'tied' follows their ratios. A run with a wrong event sequence never reaches a "
                  "target. A target below what the reference can certify (or double precision can resolve on that "
                  "problem) is not graded.")
WRONG_CAPTION = ("Runs that succeeded with a different event sequence from the reference's (events missed / "
                 "extra, after aligning the sequences): they never reach a target and are never the cheapest.")
REFERENCE_CAPTION = ("References, shown apart and not ranked: each problem's reference (what the errors above "
                     "are measured against) and the other reference-grade integrators, with their cost. "
                     "Certified: the largest bound on the reference's event-time errors, from an independent "
                     "run at higher precision; no error is reported below it (a run within it is 'at "
                     "reference accuracy') and no target below it is graded. Conditioning: the largest switching-time change per unit change of the start positions "
                     "(the reference run again from a start moved by 1e-9); the double floor, that times the "
                     "unit roundoff, is how far rounding alone moves any double-precision solution's switching "
                     "times. A problem whose floor exceeds 1e-10 cannot be graded in double over its span.")


class _Answer:
    """The report's first section: findings in words, the per-target summary, wrong sequences, references."""

    def __init__(self, frame: pd.DataFrame, targets) -> None:
        self.summary = problem_summary(frame, targets)
        self.wrong = wrong_sequences(frame)
        self.refs = reference_costs(frame)
        self.words = findings(self.summary, self.wrong, conditioning_table(frame)) if len(self.summary) else []

    def markdown(self) -> list[str]:
        if self.summary.empty:
            return []
        md = ["## The answer", "", *[f"- {w}" for w in self.words], "", ANSWER_CAPTION, "",
              markdown_table(display(self.summary)), ""]
        if len(self.wrong):
            md += ["**Wrong event sequences.** " + WRONG_CAPTION, "", markdown_table(self.wrong), ""]
        if len(self.refs):
            md += [REFERENCE_CAPTION, "", markdown_table(self.refs), ""]
        return md

    def html(self) -> list[str]:
        if self.summary.empty:
            return []
        esc = html.escape
        parts = ["<h2>The answer</h2>",
                 "<ul class='answer'>" + "".join(f"<li>{esc(w)}</li>" for w in self.words) + "</ul>",
                 f"<p>{esc(ANSWER_CAPTION)}</p>", _html_table(display(self.summary), "summary")]
        if len(self.wrong):
            parts += [f"<p><strong>Wrong event sequences.</strong> {esc(WRONG_CAPTION)}</p>",
                      _html_table(self.wrong)]
        if len(self.refs):
            parts += [f"<p>{esc(REFERENCE_CAPTION)}</p>", _html_table(self.refs)]
        return parts


SCALING_DETAIL_CAPTION = ("Per integrator and n: the cheapest configuration reaching the target, its costs and "
                          "set-up time, and why nothing reached it where so.")


def _scaling_view(scaling: pd.DataFrame) -> pd.DataFrame:
    return scaling.drop(columns=["family"]) if scaling["family"].nunique() == 1 else scaling


def _figure_html(fig: Figure) -> str:
    esc = html.escape
    data = base64.b64encode(fig.png.read_bytes()).decode()
    return (f"<figure id='{esc(fig.name)}'><img alt='{esc(fig.title)}' "
            f"src='data:image/png;base64,{data}'><figcaption>{esc(fig.caption)}</figcaption></figure>")


def _html_table(frame: pd.DataFrame, kind: str = "") -> str:
    # a wide table scrolls inside its own box instead of running past the page
    table = _readable(frame).map(_fmt).to_html(index=False, border=0, classes=f"tbl {kind}".strip(), escape=True)
    return f"<div class='wide'>{table}</div>"


def _inline(text: str) -> str:
    """Escaped HTML of a line of report text, its `code` spans as <code> (no raw markdown in the page)."""
    import re

    return re.sub(r"`([^`]*)`", r"<code>\1</code>", html.escape(text))


def _html(frame, prov, wide, rank, figures, failures, results_view, ft_caption, rank_caption, problems,
          spread, spread_caption, engine, scaling_parts, answer, bif=None, noise="", setup=None) -> str:
    esc = html.escape
    parts = ["<!DOCTYPE html>", "<html lang='en'><head><meta charset='utf-8'>",
             "<title>nsbench report</title><style>",
             "body{font-family:system-ui,sans-serif;max-width:1100px;margin:2em auto;padding:0 1em}"
             ".tbl{border-collapse:collapse;font-size:13px}.tbl td,.tbl th{padding:2px 8px;"
             "border-bottom:1px solid #ddd;text-align:left;vertical-align:top}"
             ".summary td:nth-child(-n+4){white-space:nowrap}figure{margin:1.5em 0}"
             "figcaption{font-size:13px;color:#444}img{max-width:100%}pre{background:#f6f6f6;padding:1em;"
             "overflow-x:auto}.wide{overflow-x:auto;max-width:100%}.answer{background:#f3f7fb;"
             "border-left:4px solid #2b6cb0;padding:0.6em 1em 0.6em 2em}",
             "</style></head><body>", "<h1>nsbench report</h1>"]
    if noise:
        parts.append(f"<p class='noise'>{esc(noise)}</p>")
    if problems:
        parts.append("<p><strong>This run is incomplete:</strong></p><ul>"
                     + "".join(f"<li>{_inline(p)}</li>" for p in problems) + "</ul>")
    parts += answer.html()
    text = _problems_text(frame, prov)
    parts.append(f"<p>{_inline(text[0])}</p><ul>" + "".join(f"<li>{_inline(t[2:])}</li>" for t in text[1:]) + "</ul>")
    parts.append(f"<p>{esc(_timing_text(frame))}</p>")
    scaling, scaling_fit, scaling_figs = scaling_parts
    if len(scaling):
        parts += ["<h2>Scaling with the number of blocks</h2>", f"<p>{esc(SCALING_CAPTION)}</p>",
                  _html_table(scaling_fit), *(_figure_html(fig) for fig in scaling_figs),
                  f"<p>{esc(SCALING_DETAIL_CAPTION)}</p>", _html_table(_scaling_view(scaling))]
    parts += ["<h2>Fixed-target table</h2>", f"<p>{esc(ft_caption)}</p>",
              _html_table(wide), "<h2>Timing spread</h2>"]
    parts += ([f"<p>{esc(spread_caption)}</p>", _html_table(spread)] if len(spread) else
              [f"<p>Every timed case spreads by at most {WIDE_SPREAD:.0%} ((max - min) / median).</p>"])
    parts += ["<h2>Ranking</h2>", f"<p>{esc(rank_caption)}</p>", _html_table(rank),
              "<h2>Integrator time and engine share</h2>", f"<p>{esc(ENGINE_CAPTION)}</p>", _html_table(engine)]
    if setup is not None:
        parts += ["<h2>Set-up per integrator</h2>", f"<p>{esc(SETUP_CAPTION)}</p>", _html_table(setup)]
    parts += ["<h2>Figures</h2>"]
    for fig in figures[len(scaling_figs):]:
        parts.append(_figure_html(fig))
    if bif is not None and len(bif[0]):
        from nsbench.bench import targets as bt

        parts += ["<h2>Bifurcation-point error</h2>", "<p>Targets and their reference values:</p>",
                  _html_table(bt.reference_table(bif[0])), f"<p>{esc(bt.TABLE_CAPTION)}</p>",
                  _html_table(bt.report_table(bif[0])), *(_figure_html(fig) for fig in bif[1])]
    parts += ["<h2>Statuses</h2>", _html_table(_status_counts(frame))]
    if len(failures):
        parts += ["<p>Cases that did not succeed:</p>", _html_table(failures)]
    parts += ["<h2>All cases</h2>", _html_table(results_view), "<h2>Provenance</h2>",
              f"<pre>{esc(json.dumps(prov, indent=1, default=str))}</pre>", "</body></html>"]
    return "\n".join(parts)
