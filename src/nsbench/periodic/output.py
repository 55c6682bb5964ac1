"""Files of a continuation: ``branch.csv``, ``points.csv``, ``bifurcations.csv``, ``meta.json`` and the figure.

- ``branch.csv``: one row per continuation step (see :meth:`Branch.frame`);
- ``points.csv``: the section points of each step's orbit (``branch, value, k``, the state);
- ``bifurcations.csv``: ``branch, param, value, kind, category, detail, bracket``, the
  patterns and multipliers on both sides;
- ``gaps.csv``: parameter values where no periodic orbit was found, with the reason;
- ``meta.json``: the problem, the range, the flow's integrator, versions and machine;
- ``README.md``: the branches and the located bifurcations in words and tables, the figure;
- ``branches.{png,svg,pdf}``: section points against the parameter, stable branches solid,
  unstable dashed, bifurcations marked, over the brute-force diagram when one is given.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any, Sequence

import numpy as np
import pandas as pd

from nsbench.files import write_atomic
from nsbench.periodic.continuation import Continuation
from nsbench.periodic.flow import HybridFlow, section_points


def points_frame(flow: HybridFlow, result: Continuation, problem_at, section: str) -> pd.DataFrame:
    """Section points of every step of every branch (long format)."""
    rows = []
    for br in result.branches:
        for value, orbit in zip(br.values, br.orbits):
            flow.rebind(problem_at(value))
            pts = section_points(flow, orbit, section)
            for k, y in enumerate(pts):
                rows.append(
                    {
                        "branch": br.label,
                        "value": value,
                        "k": k,
                        "stable": orbit.stable,
                        **dict(zip(orbit.problem.state_names, y)),
                    }
                )
    return pd.DataFrame(rows)


def write(out: str | Path, result: Continuation, points: pd.DataFrame, meta: dict[str, Any]) -> dict[str, Path]:
    """Write the tables and ``meta.json`` into ``out``; return their paths."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    paths = {
        "branch": out / "branch.csv",
        "points": out / "points.csv",
        "bifurcations": out / "bifurcations.csv",
        "gaps": out / "gaps.csv",
        "meta": out / "meta.json",
    }
    tables = {
        "branch": result.frame(),
        "points": points,
        "bifurcations": result.bifurcation_frame(),
        "gaps": pd.DataFrame(result.gaps, columns=["value", "reason"]),
    }
    for key, frame in tables.items():
        write_atomic(paths[key], frame.to_csv(index=False, float_format="%.17g").encode())
    write_atomic(paths["meta"], json.dumps(meta, indent=2, default=str).encode())
    paths["readme"] = out / "README.md"
    write_atomic(paths["readme"], summary(result, meta).encode())
    return paths


def summary(result: Continuation, meta: dict[str, Any]) -> str:
    """A page a reader can open first: what was continued, the branches, the bifurcations."""
    from nsbench.render import four_digits, markdown

    def _table(frame: pd.DataFrame) -> str:
        return markdown(frame, fmt=four_digits)

    p = meta.get("provenance", {})
    lines = [
        f"# Periodic orbits of {meta['problem']} case {meta['case']} along {result.param}",
        "",
        f"Range {result.start:g}..{result.stop:g} ({meta['steps']} steps at the largest step size), flow "
        f"`{meta['integrator']}`, section `{meta['section']}`, fixed parameters {meta['params'] or 'none'}"
        + (f", first orbit from rest at {meta['origin']:g}" if meta.get("origin") is not None else "")
        + f". Computed in {meta['seconds']:.0f} s with nsbench {p.get('version_nsbench', '?')} (commit {p.get('git_commit', '?')}) on "
        f"{p.get('cpu', '?')} ({p.get('cpu_count', '?')} cores).",
        "",
        "![branches](branches.png)",
        "",
        "## Bifurcations",
        "",
    ]
    bifs = [b for b in result.bifurcations if b.category != "none"]
    swaps = len(result.bifurcations) - len(bifs)
    if bifs:
        frame = pd.DataFrame(
            [{"value": f"{b.value:.12g}", "kind": b.kind, "category": b.category, "detail": b.detail} for b in bifs]
        )
        lines += [_table(frame), ""]
    else:
        lines += ["None located in the range.", ""]
    if swaps:
        lines += [f"{swaps} event-order swap(s) (two events coincide; not bifurcations) are in `bifurcations.csv`.", ""]
    lines += ["## Branches", ""]
    rows = [
        {
            "branch": br.label,
            "from": f"{br.values[0]:.10g}",
            "to": f"{br.values[-1]:.10g}",
            "steps": len(br.values),
            "events per period": len(br.orbits[0].events),
            "stable": "all"
            if all(o.stable for o in br.orbits)
            else ("none" if not any(o.stable for o in br.orbits) else "partly"),
            "end": br.end_reason,
        }
        for br in result.branches
    ]
    lines += [_table(pd.DataFrame(rows)) if rows else "No periodic orbit found.", ""]
    if result.gaps:
        lines += [
            f"{len(result.gaps)} value(s) without a periodic orbit (steady sliding or aperiodic motion): `gaps.csv`.",
            "",
        ]
    return "\n".join(lines)


#: Colour of each bifurcation category's vertical line (other categories: grey).
CATEGORY_COLOURS = {"fixed-point": "tab:red", "sliding": "tab:purple", "border-collision": "tab:brown"}
#: Most branches named one by one in the legend; beyond, one entry says how the colours repeat.
LEGEND_BRANCHES = 10


def figure(
    result: Continuation,
    points: pd.DataFrame,
    base: str | Path,
    *,
    variable: str = "x1",
    diagram: pd.DataFrame | None = None,
    title: str = "",
    formats: Sequence[str] = ("png", "svg", "pdf"),
) -> list[Path]:
    """Section points of every branch against the parameter; stable solid, unstable dashed (:func:`draw`)."""
    from nsbench.plotting import save

    return save(draw(result, points, variable=variable, diagram=diagram, title=title), base, formats)


def draw(
    result: Continuation,
    points: pd.DataFrame,
    *,
    variable: str = "x1",
    diagram: pd.DataFrame | None = None,
    title: str = "",
):
    """The figure of :func:`figure`, not saved: each branch in its own colour (stable parts solid,
    unstable dashed), the located bifurcations as vertical lines coloured by category.

    Within a branch the ``k``-th smallest ``variable`` of consecutive orbits with the
    same number of points and stability is one line. ``diagram``: a brute-force
    sweep's points (``value`` and ``variable`` columns), drawn beneath as grey dots.
    The legend, right of the axes, names each branch with its colour (up to
    :data:`LEGEND_BRANCHES`; beyond, how the colours repeat), the two line styles and
    the bifurcation categories drawn.
    """
    from matplotlib.lines import Line2D

    from nsbench.plotting import pyplot

    plt = pyplot()
    fig, ax = plt.subplots(figsize=(8, 4.8), constrained_layout=True)
    handles: list = []
    if diagram is not None and len(diagram) and variable in diagram:
        ax.plot(diagram["value"], diagram[variable], ",", color="0.6", alpha=0.6)
        handles.append(Line2D([], [], ls="none", marker=".", color="0.6", label="brute-force sweep"))
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    styles: set[bool] = set()
    branches = list(points.groupby("branch", sort=False)) if len(points) else []
    for i, (label, grp) in enumerate(branches):
        colour = colours[i % len(colours)]
        per_value = [
            (v, g[variable].sort_values().to_numpy(), bool(g["stable"].iloc[0]))
            for v, g in grp.groupby("value", sort=True)
        ]
        run: list = []
        for item in per_value + [(None, np.empty(0), None)]:
            if run and (item[0] is None or len(item[1]) != len(run[-1][1]) or item[2] != run[-1][2]):
                xs = np.array([r[0] for r in run])
                ys = np.array([r[1] for r in run])
                stable = bool(run[0][2])
                styles.add(stable)
                for k in range(ys.shape[1]):
                    ax.plot(
                        xs,
                        ys[:, k],
                        "-" if stable else "--",
                        color=colour,
                        lw=1.2,
                        marker="." if len(xs) == 1 else None,
                    )
                run = []
            if item[0] is not None:
                run.append(item)
        if len(branches) <= LEGEND_BRANCHES:
            handles.append(Line2D([], [], color=colour, lw=2.0, label=f"branch {label}"))
    if len(branches) > LEGEND_BRANCHES:
        handles.append(
            Line2D(
                [],
                [],
                color=colours[0],
                lw=2.0,
                label=f"{len(branches)} branches, one colour each, repeating every {len(colours)} (table Branches)",
            )
        )
    handles += [
        Line2D(
            [],
            [],
            color="k",
            ls="-" if stable else "--",
            lw=1.2,
            label="stable orbits" if stable else "unstable orbits",
        )
        for stable in sorted(styles, reverse=True)
    ]
    drawn: dict[str, str] = {}
    for b in result.bifurcations:
        if b.category == "none":
            continue
        colour = CATEGORY_COLOURS.get(b.category, "tab:gray")
        ax.axvline(b.value, color=colour, lw=0.6, alpha=0.5)
        drawn.setdefault(b.category, colour)
    handles += [Line2D([], [], color=c, lw=1.0, label=f"{cat} bifurcation") for cat, c in drawn.items()]
    ax.set_xlabel(result.param)
    ax.set_ylabel(f"{variable} at the section")
    ax.set_title(title, fontsize=9)
    if branches or handles:
        ax.legend(handles=handles, loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8, frameon=False)
    if not branches:
        ax.text(0.5, 0.5, "no periodic orbit found in the range", transform=ax.transAxes, ha="center")
    return fig
