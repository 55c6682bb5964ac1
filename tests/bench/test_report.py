"""The report: report.md, a self-contained index.html holding every figure, table.tex, PNG+SVG."""

from __future__ import annotations

import base64
import re

import pytest

from nsbench.bench import Suite, run_suite
from nsbench.bench.report import write_report
from tests.procs import inner_pytest_env


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    out = tmp_path_factory.mktemp("report")
    # The reference list leaves out `reference`, so the cubic problem has none and
    # takes the cost-only figure path.
    suite = Suite.from_dict(
        {
            "name": "rep",
            "t_span": [0.0, 30.0],
            "repeats": 3,
            "max_repeats": 3,
            "min_sample_time": 0.0,  # one run per sample: the report, not timing, is tested
            "reference": ["exact"],
            "problems": [{"name": "one-dof", "case": 1}, {"name": "two-dof", "case": 3}],
            "integrators": {
                "only": ["exact", "scipy-rk45", "henon-rk4"],
                # RK4 steps whose event error is ~1e-5 and ~1e-8:
                # 1e-6 is reached, 1e-12 is not
                "grids": {"henon-rk4": {"options": [{"h": 0.04}, {"h": 0.01}]}},
            },
        }
    )
    run_suite(suite, out, workers=1, progress=False)
    return out, write_report(out)


def test_every_figure_is_saved_as_png_and_on_request_as_svg_and_pdf(report):
    out, rep = report
    names = [f.name for f in rep.figures]
    assert names == [
        "runtime_distribution",
        "wp_time_one-dof_1",
        "wp_inttime_one-dof_1",
        "wp_nfev_one-dof_1",
        "wp_nsteps_one-dof_1",
        "event_err_one-dof_1",
        "cost_two-dof_3",
    ]
    for fig in rep.figures:  # by default PNG alone: each further format is a full draw of every figure
        assert fig.png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        assert fig.svg is None and fig.files == (fig.png,)
        assert not fig.png.with_suffix(".svg").exists() and not fig.png.with_suffix(".pdf").exists()
    every = write_report(out, formats=("svg", "pdf"))  # png is always written
    assert [f.name for f in every.figures] == names
    for fig in every.figures:
        assert fig.png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        assert fig.svg is not None and fig.svg.read_text().lstrip().startswith(("<?xml", "<svg"))
        assert fig.png.with_suffix(".pdf").read_bytes()[:5] == b"%PDF-"
        assert [p.suffix for p in fig.files] == [".png", ".svg", ".pdf"]
    write_report(out)  # back to PNG: the SVG and PDF of the earlier report would no longer match, so they go
    assert not any(fig.svg.exists() or fig.png.with_suffix(".pdf").exists() for fig in every.figures)


def test_a_bad_figure_format_is_refused_before_anything_runs(tmp_path, capsys):
    from nsbench.cli import main

    assert main(["run", "--out", str(tmp_path / "r"), "--formats", "png,jpeg"]) == 2
    err = capsys.readouterr().err
    assert "--formats: 'jpeg' not allowed; choose from png, svg, pdf" in err
    assert not (tmp_path / "r" / "cases").exists()


def test_html_is_self_contained_and_embeds_each_figure(report):
    out, rep = report
    html = rep.html.read_text()
    for fig in rep.figures:
        assert f'id="{fig.name}"' in html
        assert base64.b64encode(fig.png.read_bytes()).decode() in html
    sources = re.findall(r"src=['\"]([^'\"]+)['\"]", html)
    assert len(sources) == len(rep.figures) and all(s.startswith("data:image/png;base64,") for s in sources)
    assert "<link" not in html and "http://" not in html and "https://" not in html
    for section in ("Fixed-target table", "Ranking", "Figures", "Provenance", "version_nsbench"):
        assert section in html


def test_markdown_and_latex(report):
    out, rep = report
    md = rep.markdown.read_text()
    for fig in rep.figures:
        assert f"figures/{fig.png.name}" in md
    assert "| problem | integrator | 1e-06 | 1e-09 | 1e-12 |" in re.sub(" +", " ", md)
    assert "reference `exact`" in md and "no reference available" in md
    tex = rep.latex.read_text()
    # 3 targets, the references, the fixed-target table (short here: a float) and the ranking
    assert tex.count(r"\begin{tabular}") == 6 and r"\label{tab:nsbench-fixed-target}" in tex
    assert "one-dof/1 & exact" in tex
    # exact is the reference of one-dof/1: reported with its cost, not as reaching targets
    ft = rep.fixed_target
    own = ft[(ft["integrator"] == "exact") & (ft["problem_label"] == "one-dof/1")]
    assert (own["outcome"] == "reference").all() and (own["wall_time"] > 0).all()
    assert "| one-dof/1 | exact | ref (" in re.sub(" +", " ", md) and "exact" not in set(rep.ranking["integrator"])
    rk4 = ft[(ft["integrator"] == "henon-rk4") & (ft["problem_label"] == "one-dof/1")].set_index("target")
    assert rk4.loc[1e-6, "outcome"] == "reached" and rk4.loc[1e-12, "outcome"] == "not reached"
    cubic = ft[ft["problem_label"] == "two-dof/3"].set_index("integrator")["outcome"]
    assert (cubic.drop("exact") == "no reference").all() and (cubic["exact"] == "unsupported").all()


def test_timing_spread_is_shown(report):
    out, rep = report
    md = rep.markdown.read_text()
    ft = rep.fixed_target
    reached = ft[ft["outcome"] == "reached"]
    assert len(reached) and reached["wall_spread"].notna().all()
    md = re.sub(" +", " ", md)
    row = md[md.index("| one-dof/1 | henon-rk4 |") :].splitlines()[0]
    assert " s ±" in row  # median ± half its min-max range
    assert "## Timing spread" in md and "Times are medians of 3 timed samples per case" in md
    assert "This run is incomplete" not in md
    # the line on the machine's noise comes first, from the loads sampled while timing
    assert md.splitlines()[2].startswith("How noisy the machine was: load average ")
    assert "a case's timed samples spread by" in md.splitlines()[2]
    # set-up is charged to each integrator once, not to the level that happened to compile
    setup = md[md.index("## Set-up per integrator") :].split("## Figures")[0]
    assert "| integrator | first_use | on | later | cases |" in setup and "| henon-rk4 |" in setup


def test_work_precision_whiskers_span_min_to_max():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np
    import pandas as pd

    from nsbench.bench.figures import _whiskers

    rows = pd.DataFrame({"wall_time_min": [0.9, 1.8, np.nan], "wall_time_max": [1.2, 2.5, np.nan]})
    fig, ax = plt.subplots()
    _whiskers(ax, rows, np.array([1.0, 2.0, 3.0]), np.array([1e-6, 1e-8, 1e-10]), "k")
    segments = [seg for coll in ax.collections for seg in coll.get_segments()]
    plt.close(fig)
    spans = sorted((float(s[0][0]), float(s[1][0])) for s in segments)
    assert spans == [(0.9, 1.2), (1.8, 2.5)]  # no whisker where the range is unknown


def test_integrator_time_and_engine_share_are_reported(report):
    from nsbench.bench import load_results
    from nsbench.bench.report import engine_share_table, with_engine_share

    out, rep = report
    frame = with_engine_share(load_results(out))
    ok = frame[frame["status"] == "success"]
    # the core's clock runs inside the wall-clock span of each run, so its time is a part of it
    assert (ok["integrator_time"] > 0).all() and (ok["integrator_time"] <= ok["wall_time"]).all()
    assert ok["engine_share"].between(0.0, 1.0).all()
    table = engine_share_table(frame)
    assert set(table["integrator"]) == set(ok["integrator"])
    md = rep.markdown.read_text()
    assert "## Integrator time and engine share" in md and "integrator_time" in md and "wall times" in md
    assert "engine_share" in rep.html.read_text()


def test_problem_labels_sort_by_their_numbers():
    """``n=2`` comes before ``n=16`` in every list of a report (natural order, not lexicographic)."""
    import pandas as pd

    from nsbench.bench.tables import natural_key, problem_groups

    labels = ["chain/2 n=16", "chain/2 n=2", "chain/2 n=64", "chain/2 n=4", "two-dof/10", "two-dof/2"]
    assert sorted(labels, key=natural_key) == [
        "chain/2 n=2",
        "chain/2 n=4",
        "chain/2 n=16",
        "chain/2 n=64",
        "two-dof/2",
        "two-dof/10",
    ]
    frame = pd.DataFrame({"problem_label": labels, "x": range(6)})
    assert [label for label, _ in problem_groups(frame)] == sorted(labels, key=natural_key)


# 24 s (two benchmark modules run by an inner pytest): behind `slow`; tests/bench/test_ingest.py ingests a real
# pytest-benchmark file on every default run, but the cost-only rows of a timed sweep are checked only here
@pytest.mark.slow
def test_ingest_report_on_real_pytest_benchmark_output(tmp_path):
    """Cost-only rows without a problem config or accuracy level (a timed sweep) next to case rows."""
    import subprocess
    import sys
    from pathlib import Path

    from nsbench.cli import main

    root = Path(__file__).resolve().parents[2]
    out = tmp_path / "bench.json"
    cmd = [
        sys.executable,
        "-m",
        "pytest",
        str(root / "benchmarks" / "test_registry.py"),
        str(root / "benchmarks" / "test_sweep_speed.py"),
        "-q",
        "-p",
        "no:cacheprovider",
        "--benchmark-only",
        f"--benchmark-json={out}",
        "-k",
        "(one-dof-1 and scipy-dop853) or (case1_v0 and henon-rk4)",
    ]
    done = subprocess.run(
        cmd, cwd=root, env=inner_pytest_env(NSBENCH_BENCH_T_END="20"), capture_output=True, text=True, timeout=600
    )
    assert done.returncode == 0, done.stdout + done.stderr
    assert main(["ingest", str(out), "--out", str(tmp_path / "pb"), "--report"]) == 0
    html = (tmp_path / "pb" / "index.html").read_text()
    assert "henon-rk4" in html and "scipy-dop853" in html


def test_table_tex_has_a_page_sized_table_per_target_then_references_and_the_supplement(report):
    out, rep = report
    tex = rep.latex.read_text()
    labels = re.findall(r"\\label\{([^}]*)\}", tex)
    assert labels == [
        "tab:nsbench-target-1e-06",
        "tab:nsbench-target-1e-09",
        "tab:nsbench-target-1e-12",
        "tab:nsbench-references",
        "tab:nsbench-fixed-target",
        "tab:nsbench-ranking",
    ]
    for t in tex.split(r"\begin{table}")[1:4]:
        assert t.count(r"\\") <= 40  # a page
    assert "±" not in tex and "<1%" not in tex  # math mode, not text-mode glyphs LaTeX misprints


def test_table_tex_compiles_without_overflow(report, tmp_path):
    """pdflatex on an article that inputs table.tex: no error, no overfull box, no float past its page."""
    from tests.test_render import compile_latex

    log = compile_latex(report[1].latex.read_text(), tmp_path)
    assert "Overfull \\hbox" not in log and "Float too large" not in log


_OVERFLOW_PROBE = """<script>
window.addEventListener('load', () => {
  const limit = document.documentElement.clientWidth + 1;
  const out = [...document.querySelectorAll('body *')].filter(
      e => e.getBoundingClientRect().right > limit && !e.closest('.wide') && !e.closest('pre'));
  document.body.setAttribute('data-overflow',
      (document.documentElement.scrollWidth > limit ? 'page ' : '') + out.map(e => e.tagName).join(' '));
});
</script></body>"""


@pytest.mark.parametrize("width", [1280, 800])
def test_the_page_does_not_overflow_in_a_browser(report, tmp_path, width):
    """Rendered headless: nothing runs past the right edge (wide tables scroll inside their own box)."""
    import shutil
    import subprocess

    browser = next((b for b in ("chromium", "chromium-browser", "google-chrome") if shutil.which(b)), None)
    if browser is None:
        pytest.skip("no Chromium on this machine (apt install chromium to run this check)")
    page = tmp_path / "probe.html"
    page.write_text(report[1].html.read_text().replace("</body>", _OVERFLOW_PROBE))
    done = subprocess.run(
        [
            browser,
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            f"--window-size={width},900",
            "--virtual-time-budget=5000",
            "--dump-dom",
            page.as_uri(),
        ],
        capture_output=True,
        text=True,
        timeout=120,
    )
    found = re.search(r'data-overflow="([^"]*)"', done.stdout)
    assert found, done.stderr[-2000:]
    assert found.group(1) == "", f"past the right edge at {width} px: {found.group(1)}"
