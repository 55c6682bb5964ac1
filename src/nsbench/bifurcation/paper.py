"""``nsbench paper``: every sweep of the paper's cases 1-4, locus figures, and the comparison table.

The sweeps are those the paper shows (cases 1-4 with Table 3 defaults); where
the paper does not state a range, one is chosen that covers the values its
text names. Each sweep's candidate bifurcation points come from
:mod:`.detect` alone; the table then sets each bifurcation the paper names
(``paper_values.csv``, values stated in the paper) beside the nearest
candidate nsbench finds on the same sweep, of the matching kind.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from nsbench.bifurcation import detect, figures
from nsbench.bifurcation.paper_report import LOCUS_VALUES, TABLE_COLUMNS, html_report, markdown_report
from nsbench.bifurcation.parallel import run_sweep
from nsbench.bifurcation.sweep import OK_STATUSES, SweepSpec

# kind named by the paper -> kind of change detect.candidates reports
KIND_MATCH = {"sliding": "sliding", "fixed-point": "period", "border-collision": "event-pattern"}


@dataclass(frozen=True)
class PaperSweep:
    case: int
    name: str
    start: float
    stop: float
    note: str = ""
    section: str | None = None  # default: strobe when forced, peaks otherwise


_COMMON = (("inv_omega_r", 1.0, 10.0, ""), ("omega_r", 1.0, 10.0, ""), ("r_f", 0.4, 1.0, ""))
SWEEPS: tuple[PaperSweep, ...] = (
    PaperSweep(1, "v0", 0.04, 0.22),
    *(PaperSweep(1, n, a, b) for n, a, b, _ in _COMMON),
    PaperSweep(2, "v0", 0.04, 0.6, "range not stated in the paper; chosen to cover 0.35 and 0.43"),
    *(PaperSweep(2, n, a, b) for n, a, b, _ in _COMMON),
    PaperSweep(
        2,
        "inv_omega_r",
        1.0,
        10.0,
        "mapping points (slip events), which the paper's statement is about",
        section="mapping",
    ),
    PaperSweep(2, "F", 0.02, 0.8, "range not stated in the paper"),
    PaperSweep(2, "F", 0.12, 0.16, "zoom on the sliding bifurcation and border-collision the paper names"),
    PaperSweep(2, "Omega", 0.05, 2.5, "the paper starts at 0; the stroboscopic section needs Omega > 0"),
    PaperSweep(3, "v0", 0.04, 0.22),
    *(PaperSweep(3, n, a, b) for n, a, b, _ in _COMMON),
    PaperSweep(3, "h1", 0.0, 1.8),
    PaperSweep(4, "v0", 0.04, 1.8, "the paper starts at 0; v0 = 0 stops the belt"),
    *(PaperSweep(4, n, a, b) for n, a, b, _ in _COMMON),
    PaperSweep(4, "F", 0.02, 0.8, "range not stated in the paper"),
    PaperSweep(4, "Omega", 0.05, 2.5, "the paper starts at 0; the stroboscopic section needs Omega > 0"),
)


def paper_values() -> pd.DataFrame:
    """The bifurcations the paper names, with their stated values (see ``paper_values.csv``)."""
    with resources.files("nsbench.bifurcation").joinpath("paper_values.csv").open() as fh:
        return pd.read_csv(fh, comment="#")


def _slug(s: PaperSweep) -> str:
    return f"case{s.case}-{s.name}-{s.start:g}-{s.stop:g}" + (f"-{s.section}" if s.section else "")


def _spec(s: PaperSweep, points: int, transient: float, record: int) -> SweepSpec:
    integrator = "exact" if s.case in (1, 2) else "henon-rk4"
    section = s.section or ("strobe" if s.case in (2, 4) else "peaks")
    return SweepSpec(
        problem="two-dof",
        case=s.case,
        name=s.name,
        start=s.start,
        stop=s.stop,
        count=points,
        integrator=integrator,
        section=section,
        transient=transient,
        record=record,
    )


def match_claims(
    claims: pd.DataFrame, found: dict[tuple[int, str], pd.DataFrame], specs: dict[str, SweepSpec] | None = None
) -> pd.DataFrame:
    """For each stated bifurcation: the nearest candidate of the matching kind, and of any kind.

    With ``specs`` (sweep slug -> spec), the matched candidate of the same kind
    is refined by bisection (:func:`detect.refine`) and reported as ``refined``.
    """
    rows = []
    for c in claims.itertuples():
        stated = 0.5 * (c.low + c.high)
        cands = [f for (case, name), f in found.items() if case == c.case and name == c.sweep]
        cands = pd.concat(cands, ignore_index=True) if cands else pd.DataFrame(columns=["kind", "value"])
        row = dict(
            case=c.case,
            sweep=c.sweep,
            paper_kind=c.kind,
            paper_value=f"{c.low:g}" if c.low == c.high else f"{c.low:g}-{c.high:g}",
            statement=c.statement,
        )
        same = cands[cands["kind"] == KIND_MATCH.get(c.kind, c.kind)]
        row["candidates_on_sweep"] = len(cands)
        for label, pool in (("", same), ("any_", cands)):
            if len(pool):
                v_all = pool["value"].to_numpy(float)
                # inside a stated interval counts as distance 0 (then nearest to its middle)
                outside = np.maximum(np.maximum(c.low - v_all, v_all - c.high), 0.0)
                j = int(np.lexsort((np.abs(v_all - stated), outside))[0])
                v = float(pool["value"].iloc[j])
                row[f"{label}found"] = v
                row[f"{label}difference"] = 0.0 if c.low <= v <= c.high else v - stated
                row[f"{label}found_kind"] = pool["kind"].iloc[j] + ": " + pool["description"].iloc[j]
                if label == "" and specs is not None:
                    cand = pool.iloc[j]
                    r = detect.refine(specs[cand["slug"]], float(cand["left"]), float(cand["right"]), str(cand["kind"]))
                    row["refined"] = r.value
                    row["refined_difference"] = 0.0 if c.low <= r.value <= c.high else r.value - stated
            else:
                row[f"{label}found"] = np.nan
                row[f"{label}difference"] = np.nan
                row[f"{label}found_kind"] = "none on this sweep"
        rows.append(row)
    frame = pd.DataFrame(rows)
    for col in TABLE_COLUMNS:
        if col not in frame:
            frame[col] = np.nan
    return frame
    return pd.DataFrame(rows)


def run_paper(
    out: str | Path = "reports/paper",
    *,
    points: int = 400,
    transient: float = 1000.0,
    record: int = 64,
    workers: int | None = None,
    only_case: int | None = None,
    progress: bool = True,
    log=print,
    continuation: bool = True,
) -> Path:
    """Regenerate every paper sweep, the locus figures and the report; return the Markdown path."""
    out = Path(out)
    (out / "figures").mkdir(parents=True, exist_ok=True)
    (out / "candidates").mkdir(parents=True, exist_ok=True)
    # raw sweep tables stay local (a rerun resumes from them); the report's tables are kept
    (out / ".gitignore").write_text("data/\n!*.csv\n")
    found: dict[tuple[int, str], list] = {}
    specs: dict[str, SweepSpec] = {}
    summary = []
    tic_all = time.perf_counter()
    for s in SWEEPS:
        if only_case is not None and s.case != only_case:
            continue
        spec = _spec(s, points, transient, record)
        tic = time.perf_counter()
        frame = run_sweep(spec, out / "data" / _slug(s), workers=workers, progress=progress)
        wall = time.perf_counter() - tic
        feats = detect.classify(frame)
        cands = detect.candidates(feats)
        cands.to_csv(out / "candidates" / f"{_slug(s)}.csv", index=False)
        cands["slug"] = _slug(s)
        specs[_slug(s)] = spec
        found.setdefault((s.case, s.name), []).append(cands)
        title = (
            f"case {s.case}: {s.name} in [{s.start:g}, {s.stop:g}], {spec.integrator}, {spec.section}, "
            f"{points} values, transient {transient:g}, {record} points each"
        )
        figures.diagram(frame, out / "figures" / f"diagram-{_slug(s)}", title=title, candidates=cands, formats=("png",))
        pts = frame.groupby("index").first()
        summary.append(
            dict(
                case=s.case,
                sweep=s.name,
                range=f"{s.start:g}..{s.stop:g}",
                integrator=spec.integrator,
                section=spec.section,
                values=len(pts),
                failed=int((~pts["status"].isin(OK_STATUSES)).sum()),
                candidates=len(cands),
                pure_sliding_values=int(feats["pure_sliding"].sum()),
                aperiodic_values=int((feats["period"] == 0).sum()),
                # per-value compute time summed (stable when a run resumes)
                point_seconds=round(float(pts["wall_time"].sum()), 1),
                note=s.note,
                slug=_slug(s),
            )
        )
        log(f"case {s.case} {s.name}: {len(pts)} values, {len(cands)} candidates, {wall:.1f} s")
    for case, name, value in LOCUS_VALUES:
        if only_case is not None and case != only_case:
            continue
        _locus(case, name, value, transient, out)
    found_frames = {k: pd.concat(v, ignore_index=True) for k, v in found.items()}
    claims = paper_values()
    if only_case is not None:
        claims = claims[claims["case"] == only_case]
    table = match_claims(claims, found_frames, specs)
    table.to_csv(out / "comparison.csv", index=False)
    continued = None
    if continuation:  # every named bifurcation located by continuation too (nsbench.periodic)
        from nsbench.bifurcation.paper_continuation import continue_claims

        ranges: dict[tuple[int, str], tuple[float, float]] = {}
        for s in SWEEPS:
            lo, hi = ranges.get((s.case, s.name), (s.start, s.stop))
            ranges[(s.case, s.name)] = (min(lo, s.start), max(hi, s.stop))
        continued = continue_claims(claims, ranges, transient=transient, log=log)
        continued.to_csv(out / "continuation.csv", index=False)
    sweeps = pd.DataFrame(summary)
    sweeps.to_csv(out / "sweeps.csv", index=False)
    total = time.perf_counter() - tic_all
    md = markdown_report(sweeps, table, found_frames, points, transient, record, total, continued)
    (out / "README.md").write_text(md)
    (out / "index.html").write_text(
        html_report(sweeps, table, found_frames, points, transient, record, total, continued)
    )
    log(f"report -> {out / 'README.md'} and {out / 'index.html'} ({total:.0f} s)")
    return out / "README.md"


def _locus(case: int, name: str, value: float, transient: float, out: Path) -> None:
    from nsbench.bifurcation.locus import locus_run
    from nsbench.problems import get_problem

    overrides: dict[str, Any] = {name: value}
    problem = get_problem("two-dof", case=case, **overrides)
    run = locus_run(problem, transient=transient, duration=120.0, value=value)
    tag = f"case{case}-{name}-{value:.6g}"
    figures.locus(
        run,
        out / "figures" / f"locus-{tag}",
        title=f"case {case}, {name} = {value:.6g}: locus of sticking phase",
        formats=("png",),
    )
    figures.portrait(
        run, out / "figures" / f"portrait-{tag}", title=f"case {case}, {name} = {value:.6g}", formats=("png",)
    )
