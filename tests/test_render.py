"""render: Markdown, HTML and LaTeX tables laid out by pandas, pages by jinja2; LaTeX that compiles.

The LaTeX checks run pdflatex where it is installed (``apt-get install texlive-latex-base
texlive-latex-extra``) and skip with that reason where it is not.
"""

from __future__ import annotations

import math
import re
import shutil
import subprocess
from pathlib import Path

import pandas as pd
import pytest

from nsbench import render

DOCUMENT = r"""\documentclass{article}
\usepackage{booktabs,longtable,array}
\begin{document}
\input{tables.tex}
\end{document}
"""


def compile_latex(tex: str, folder: Path) -> str:
    """The log of pdflatex run twice (longtable settles its widths on the second) on an article that
    inputs ``tex``; skips the calling test where pdflatex is absent, fails on a LaTeX error."""
    if shutil.which("pdflatex") is None:
        pytest.skip("pdflatex is not installed (apt-get install texlive-latex-base texlive-latex-extra)")
    (folder / "tables.tex").write_text(tex)
    (folder / "doc.tex").write_text(DOCUMENT)
    for _ in range(2):
        done = subprocess.run(
            ["pdflatex", "-interaction=nonstopmode", "-halt-on-error", "doc.tex"],
            cwd=folder,
            capture_output=True,
            text=True,
            timeout=300,
        )
    log = (folder / "doc.log").read_text(errors="replace")
    assert done.returncode == 0, log[-3000:]
    return log


def test_cells_and_markdown():
    frame = pd.DataFrame({"name": ["a|b", None], "x": [1.23456, math.nan], "n": [3, 4]})
    assert [render.cell(v) for v in (1.23456, math.nan, None, pd.NA, 7, "s")] == ["1.23", "", "", "", "7", "s"]
    md = render.markdown(frame)
    lines = md.splitlines()
    assert re.sub(" +", " ", lines[0]) == "| name | x | n |" and set(lines[1]) <= set("|-: ")
    assert "a\\|b" in lines[2] and "1.23" in lines[2]  # a pipe in a cell does not split it
    assert render.markdown(frame.iloc[0:0]) == "| name | x | n |\n|---|---|---|"


def test_html_escapes_and_scrolls():
    out = render.html(pd.DataFrame({"a": ["<b>x</b>"]}), "tbl summary")
    assert out.startswith("<div class='wide'>") and "&lt;b&gt;x&lt;/b&gt;" in out and "tbl summary" in out
    assert render.inline("`code` and **bold** <x>") == "<code>code</code> and <strong>bold</strong> &lt;x&gt;"


def test_latex_escapes_text_and_picks_its_environment():
    short = pd.DataFrame({"problem": ["two_dof"], "time": ["0.1 s ±4% <1%"]})
    tex = render.latex(short, "50% & more", "tab:x")
    assert r"\begin{table}[htbp]" in tex and r"\label{tab:x}" in tex and r"50\% \& more" in tex
    assert r"two\_dof" in tex and r"$\pm$4\% $<$1\%" in tex and "±" not in tex
    assert r"\begin{tabular}{ll}" in tex  # fits the line: plain columns
    long = render.latex(pd.DataFrame({"a": range(40)}), "long", "tab:y")
    assert r"\begin{longtable}" in long and r"\endhead" in long  # breaks across pages


def _wide_long_frame() -> pd.DataFrame:
    rows = []
    for i in range(70):
        rows.append(
            {
                "problem": f"two-dof/{i % 4 + 1}",
                "integrator": "scipy-dop853",
                "1e-06": f"0.{i:04d}1 s ±{i}% / 123456",
                "1e-09": "0.00123 s [0.00117-0.00131] / 98765",
                "1e-12": "not graded",
                "note": "wrong event sequence in 2 of 3 configurations",
            }
        )
    return pd.DataFrame(rows)


def test_long_and_wide_tables_compile_without_overflow(tmp_path):
    frame = _wide_long_frame()
    tex = "\n\n".join(
        [
            render.latex(frame, "A long, wide table.", "tab:long"),
            render.latex(frame.head(8), "A short, wide table.", "tab:short"),
            render.latex(frame.head(3)[["problem", "1e-12"]], "A small table.", "tab:small"),
        ]
    )
    assert tex.count(r"\raggedright") == 2 * len(frame.columns)  # the wide ones wrap
    log = compile_latex(tex, tmp_path)
    assert "Overfull \\hbox" not in log and "Float too large" not in log


def test_a_table_of_long_words_drops_to_a_smaller_font_and_still_fits(tmp_path):
    # five columns whose longest words (15 characters) need 362 pt in \footnotesize, 310 pt in \scriptsize
    words = {f"column{i}": ["x" * 12, "reference-grade"] for i in range(5)}
    tex = render.latex(pd.DataFrame(words), "Five columns of long words.", "tab:words")
    assert r"\scriptsize" in tex
    log = compile_latex(tex, tmp_path)
    assert "Overfull \\hbox" not in log


def test_pages_render_blocks_through_templates():
    from types import SimpleNamespace

    blocks = [
        SimpleNamespace(kind="h2", text="Part", css="", items=[], table=None, figure=None),
        SimpleNamespace(kind="p", text="`x` **y**", css="noise", items=[], table=None, figure=None),
        SimpleNamespace(kind="list", text="", css="", items=["one", "two"], table=None, figure=None),
        SimpleNamespace(kind="table", text="", css="tbl", items=[], table=pd.DataFrame({"a": [1.5]}), figure=None),
    ]
    md = render.page("report.md", title="T", blocks=blocks, provenance={})
    assert md.startswith("# T\n\n## Part\n\n`x` **y**\n\n- one\n- two\n\n|")
    page = render.page("report.html", title="T <1>", blocks=blocks, provenance={})
    assert "<title>T &lt;1&gt;</title>" in page and "<h2>Part</h2>" in page
    assert '<p class="noise"><code>x</code> <strong>y</strong></p>' in page and "<li>one</li>" in page
    assert "<td>1.5</td>" in page
