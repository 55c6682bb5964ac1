"""Tables and pages for readers: Markdown and HTML tables by pandas, LaTeX tables by pandas' Styler,
pages by jinja2 templates (``nsbench/templates``). Reports of every kind (bench, sweeps, continuation)
render through here, so a table looks the same wherever it is pasted.

Every cell is first turned into its display text by :func:`cell` (floats to 3
significant digits, missing values empty); the renderers only lay the text out.
"""

from __future__ import annotations

import html as _html
import math
import re
from typing import Any, Callable

import pandas as pd


def cell(value: Any) -> str:
    """The display text of one value: floats to 3 significant digits, NaN/None/NA as ''."""
    if value is None or value is pd.NA or (isinstance(value, float) and math.isnan(value)):
        return ""
    if isinstance(value, float):
        return f"{value:.3g}"
    return str(value)


#: How a value becomes the text of a cell (:func:`cell` unless a caller has its own format).
Format = Callable[[Any], str]


def four_digits(value: Any) -> str:
    """The text of a cell of the sweep and continuation reports: floats to 4 significant digits, NaN as '-'."""
    if isinstance(value, float):
        return "-" if math.isnan(value) else f"{value:.4g}"
    return str(value)


def _texts(frame: pd.DataFrame, fmt: Format = cell) -> pd.DataFrame:
    return frame.map(fmt) if len(frame.columns) else frame


def markdown(frame: pd.DataFrame, fmt: Format = cell) -> str:
    """A GitHub-flavoured Markdown table (``DataFrame.to_markdown``); ``|`` inside a cell is escaped."""
    texts = _texts(frame, fmt).map(lambda s: s.replace("|", "\\|"))
    if texts.empty:  # tabulate renders an empty frame as a bare header line without a rule
        cols = [str(c) for c in frame.columns]
        return "| " + " | ".join(cols) + " |\n|" + "---|" * len(cols)
    return texts.to_markdown(index=False, tablefmt="pipe", disable_numparse=True)


def html(frame: pd.DataFrame, classes: str = "tbl", fmt: Format = cell) -> str:
    """An HTML table (``DataFrame.to_html``), escaped, inside a box that scrolls when it is wide."""
    table = _texts(frame, fmt).to_html(index=False, border=0, classes=classes, escape=True)
    return f"<div class='wide'>{table}</div>"


def inline(text: str) -> str:
    """Escaped HTML of a line of Markdown-ish text: `code` spans as <code>, **bold** as <strong>."""
    out = _html.escape(text)
    out = re.sub(r"`([^`]*)`", r"<code>\1</code>", out)
    return re.sub(r"\*\*([^*]+)\*\*", r"<strong>\1</strong>", out)


# ---------------------------------------------------------------------- LaTeX
_TEX = (
    ("\\", "\x00"),
    ("&", r"\&"),
    ("%", r"\%"),
    ("_", r"\_"),
    ("#", r"\#"),
    ("{", r"\{"),
    ("}", r"\}"),
    ("$", r"\$"),
    ("\x00", r"\textbackslash{}"),
    # text-mode < > ~ ^ print wrongly (or not at all) in LaTeX's default OT1 encoding; ± is math
    ("<", r"$<$"),
    (">", r"$>$"),
    ("±", r"$\pm$"),
    ("~", r"\textasciitilde{}"),
    ("^", r"\textasciicircum{}"),
)


def tex_escape(text: str) -> str:
    """``text`` safe in LaTeX text mode with the default (OT1) font encoding."""
    for a, b in _TEX:
        text = text.replace(a, b)
    return text


#: Text width of an article's page (pt), and per font size the width of a character (pt, a generous
#: average: digits are 4.2 pt in Computer Modern at 8 pt) and the padding of a column (pt).
LINE_PT, PAD_PT = 345.0, 8.0
SIZES = (("\\footnotesize", 4.3), ("\\scriptsize", 3.6))
#: Rows above which a table is a ``longtable`` (breaks across pages) rather than a float.
LONG_ROWS = 30
#: A long cell wraps to about this many characters.
WRAP_CHARS = 28


def _longest_word(text: str) -> int:
    return max((len(w) for w in text.split()), default=0)


def _layout(texts: pd.DataFrame, headers: list[str], numeric: list[bool]) -> tuple[str, str]:
    """``(font size, column format)``: ``l``/``r`` columns in ``\\footnotesize`` when the table fits the
    line; otherwise ragged-right ``p{...}`` columns that wrap at spaces, each at least as wide as its
    longest word, sharing the rest of the line by content (in ``\\scriptsize`` if the words need it)."""
    full = [max([len(s) for s in texts[c]] + [_longest_word(h)]) for c, h in zip(texts.columns, headers)]
    words = [max([_longest_word(s) for s in texts[c]] + [_longest_word(h)]) for c, h in zip(texts.columns, headers)]
    size, char = SIZES[0]
    if sum(n * char + PAD_PT for n in full) <= LINE_PT:
        return size, "".join("r" if num else "l" for num in numeric)
    if sum(w * char + PAD_PT for w in words) > 0.995 * LINE_PT:
        size, char = SIZES[1]
    least = [(w * char + PAD_PT) / LINE_PT for w in words]
    most = [(max(w, min(f, WRAP_CHARS)) * char + PAD_PT) / LINE_PT for w, f in zip(words, full)]
    spare = max(0.0, 0.995 - sum(least))  # a hair short of the line: the shares are rounded down
    extra = [m - lo for m, lo in zip(most, least)]
    share = [lo + (spare * e / sum(extra) if sum(extra) > 0 else 0.0) for lo, e in zip(least, extra)]
    return size, "".join(
        rf">{{\raggedright\arraybackslash}}p{{\dimexpr {math.floor(1000 * s) / 1000:.3f}"
        rf"\linewidth-2\tabcolsep\relax}}"
        for s in share
    )


def latex(frame: pd.DataFrame, caption: str, label: str, *, long: bool | None = None) -> str:
    """A booktabs table by ``Styler.to_latex``, in ``\\footnotesize``, wrapping cells when it is wider than a page.

    ``long`` (default: more than :data:`LONG_ROWS` rows) makes it a
    ``longtable`` that breaks across pages; otherwise it is a ``table`` float.
    Needs ``\\usepackage{booktabs}``, ``array`` (wrapped columns) and ``longtable`` (long tables).
    """
    shown = _texts(frame)
    numeric = [
        pd.api.types.is_numeric_dtype(frame[c]) and not pd.api.types.is_bool_dtype(frame[c]) for c in frame.columns
    ]
    size, fmt = _layout(shown, [str(c) for c in frame.columns], numeric)  # sized by the text as printed
    texts = shown.map(tex_escape)
    texts.columns = [tex_escape(str(c)) for c in frame.columns]
    long = len(frame) > LONG_ROWS if long is None else long
    styler = texts.style.hide(axis="index")
    if long:
        body = styler.to_latex(
            environment="longtable", hrules=True, column_format=fmt, caption=tex_escape(caption), label=label
        )
        return "{" + size + "\\setlength{\\tabcolsep}{4pt}\n" + body.rstrip() + "\n}"
    body = styler.to_latex(
        hrules=True,
        column_format=fmt,
        caption=tex_escape(caption),
        label=label,
        position="htbp",
        position_float="centering",
    )
    return body.replace("\\centering\n", f"\\centering\n{size}\n\\setlength{{\\tabcolsep}}{{4pt}}\n", 1).rstrip()


# ---------------------------------------------------------------------- pages
def page(template: str, **context: Any) -> str:
    """Render the packaged jinja2 template ``template`` (``nsbench/templates/<template>``) with ``context``.

    The environment escapes HTML in ``*.html`` templates and offers the
    filters ``markdown``, ``html``, ``inline`` and ``cell`` (this module's functions).
    """
    import jinja2

    env = jinja2.Environment(
        loader=jinja2.PackageLoader("nsbench", "templates"),
        autoescape=jinja2.select_autoescape(["html"]),
        keep_trailing_newline=True,
        trim_blocks=True,
        lstrip_blocks=True,
        undefined=jinja2.StrictUndefined,
    )
    env.filters.update(
        markdown=markdown,
        html=lambda f, classes="tbl": _markup(html(f, classes)),
        inline=lambda t: _markup(inline(t)),
        cell=cell,
    )
    return env.get_template(template).render(**context)


def _markup(text: str):
    import markupsafe

    return markupsafe.Markup(text)
