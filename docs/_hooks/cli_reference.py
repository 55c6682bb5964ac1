"""MkDocs hook: write every ``nsbench`` command's ``--help`` into ``reference/cli.md``.

The page holds the marker ``<!-- nsbench-cli-help -->``; at build time it is replaced by the help
of every sub-command (and of ``history``'s own sub-commands), taken from the real argparse parser
(:func:`nsbench.cli.build_parser`), so the reference is never older than the code.
"""

from __future__ import annotations

import argparse
import os

MARKER = "<!-- nsbench-cli-help -->"


def _subparsers(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            return dict(action.choices)
    return {}


def _section(words: list[str], parser: argparse.ArgumentParser, level: int) -> list[str]:
    out = [f"{'#' * level} `nsbench {' '.join(words)}`", "", "```text", parser.format_help().rstrip(), "```", ""]
    for name, child in _subparsers(parser).items():
        out += _section([*words, name], child, level + 1)
    return out


def cli_help_markdown() -> str:
    """The help of every sub-command as Markdown sections, in the order of ``nsbench --help``."""
    os.environ["COLUMNS"] = "100"  # argparse wraps at the terminal's width: fix it for a stable page
    from nsbench.cli import build_parser

    top = build_parser()
    lines = ["## `nsbench`", "", "```text", top.format_help().rstrip(), "```", ""]
    for name, parser in _subparsers(top).items():
        lines += _section([name], parser, 3)
    return "\n".join(lines)


def on_page_markdown(markdown: str, page, config, files) -> str:  # noqa: ARG001 - MkDocs' hook signature
    if MARKER in markdown:
        return markdown.replace(MARKER, cli_help_markdown())
    return markdown
