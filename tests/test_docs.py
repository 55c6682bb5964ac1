"""The docs say what the code does, and cannot drift from it.

- The facts the docs state that the code can check, checked: each integrator's accuracy levels
  (the integrators table, ``docs/reference/integrators.md``), the ``mode`` column as written
  (``docs/how-to/simulate.md``), the modules the package layout names (``docs/reference/layout.md``).

- Every ``nsbench ...`` command line in a fenced code block of the README and of ``docs/`` is
  parsed by the real command-line parser (:func:`nsbench.cli.build_parser`), without running it:
  an unknown option, a missing argument or a misspelt sub-command fails the test. So is every
  inline ``nsbench ...`` span of the prose that gives options.
- The cheap commands (``nsbench list``, a short ``simulate``) really run, in this process.
- Python blocks marked ``<!-- runnable -->`` on the line before their fence are executed, in a
  temporary folder; TOML blocks marked ``<!-- suite -->`` are loaded and expanded as suites.

The site itself is built by ``.ci/run`` (``mkdocs build --strict``); the command-line reference
is generated from the same parser at build time (``docs/_hooks/cli_reference.py``).
"""

from __future__ import annotations

import re
import shlex
import sys
import textwrap
import tomllib
from dataclasses import dataclass
from pathlib import Path

import pytest

from nsbench import registry
from nsbench.cli import UsageError, build_parser, main
from nsbench.integrators import integrator_class
from nsbench.problems.modes import mode_name

ROOT = Path(__file__).resolve().parents[1]
DOC_FILES = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]
SHELL_LANGS = {"", "bash", "sh", "shell", "console"}
_FENCE = re.compile(r"^(\s*)(```+|~~~+)\s*([\w+-]*)")
_MARKER = re.compile(r"^\s*<!--\s*(runnable|suite)\s*-->\s*$")
BUILTINS = [e.name for e in registry.entries("integrators") if e.distribution == "nsbench"]


def _doc(relative: str) -> str:
    return (ROOT / "docs" / relative).read_text(encoding="utf-8")


# ---------------------------------------------------------------------------- facts the docs state


def _integrator_row(name: str) -> str:
    text = _doc("reference/integrators.md")
    table = text[text.index("# Integrators") :]
    table = table[: table.index("\n\n", table.index("|---"))]
    rows = [line for line in table.splitlines() if line.startswith("| ")]
    (row,) = [r for r in rows if f"`{name}`" in r.split("|")[1]]
    return row


def _shown(value: float) -> str:
    return format(value, "g").replace("e-0", "e-")  # 1e-06 is written 1e-6


@pytest.mark.parametrize("name", BUILTINS)
def test_each_integrator_row_states_its_accuracy_levels(name):
    row = _integrator_row(name)
    cls = integrator_class(name)
    levels = cls.accuracy_levels
    if not levels:
        assert "none" in row.split("|")[-2], row
        return
    step = cls.capabilities.step_option
    values = ", ".join(_shown(level[step]) for level in levels)
    assert f"{values}" in row, (values, row)
    if len(levels) != 3:  # the usual number goes without saying; any other is stated
        words = {4: "four", 2: "two", 5: "five"}[len(levels)]
        assert row.split("|")[-2].strip().startswith(words), row


def test_the_mode_column_is_described_as_written():
    text = _doc("how-to/simulate.md")
    written = mode_name((-1, 0))
    assert written == "slip-|stick"
    assert f"`{written}`" in text and "one character per block" not in text
    assert all(f"`{p}`" in text for p in ("slip+", "stick", "slip-"))


def test_exact_locates_events_as_nsbench_list_says():
    first_line = integrator_class("exact").__doc__.strip().splitlines()[0]
    row = _integrator_row("exact")
    for words in ("curvature-bounded scan", "Newton", "double-double polish"):
        assert words in first_line and words in row, words
    assert "Brent roots" not in first_line


def test_the_layout_names_modules_that_exist():
    src = ROOT / "src" / "nsbench"
    layout = _doc("reference/layout.md")
    for name in re.findall(r"\b(_?[a-z][a-z0-9_]*\.py)\b", layout):
        assert list(src.rglob(name)), name


def test_the_readme_stays_short():
    # issue 49: a README of at most about 200 lines; the rest lives in docs/
    assert len((ROOT / "README.md").read_text(encoding="utf-8").splitlines()) <= 200


def test_the_readme_keeps_the_set_up_commands():
    # .ci/run runs the second one's pytest command; a newcomer copies the first
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    tests = 'python -m pip install -e ".[test]" && python -m pytest -n 3 --dist loadfile'
    for command in (
        "python -m pip install -e . && nsbench run",
        tests,
        'python -m pip install -e ".[lint]" && ruff check . && ruff format --check . && mypy',
    ):
        assert f"\n{command}\n" in readme, command
    # and .ci/run runs the README's test command, not one of its own
    ci = (ROOT / ".ci" / "run").read_text(encoding="utf-8")
    assert f"\n{tests.split(' && ')[1]}\n" in ci


def test_the_readmes_links_lead_to_files():
    # the site's own links are checked by `mkdocs build --strict`; the README is not part of the site
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    targets = re.findall(r"\]\(([^)#]+)(?:#[^)]*)?\)", readme)
    assert targets
    for target in targets:
        if "://" not in target:
            assert (ROOT / target).exists(), target


# ---------------------------------------------------------------------------- code blocks


@dataclass(frozen=True)
class Block:
    """A fenced code block: where it is, its language, its marker (``runnable``, ``suite`` or ``""``)."""

    path: Path
    line: int
    lang: str
    marker: str
    text: str

    def where(self) -> str:
        return f"{self.path.relative_to(ROOT)}:{self.line}"


def blocks(path: Path) -> list[Block]:
    """The fenced code blocks of a Markdown file (an indented fence, in a list item, included)."""
    lines = path.read_text(encoding="utf-8").splitlines()
    out, i = [], 0
    while i < len(lines):
        m = _FENCE.match(lines[i])
        if not m:
            i += 1
            continue
        indent, fence, lang = m.groups()
        prev = next((lines[j] for j in range(i - 1, -1, -1) if lines[j].strip()), "")
        marker = _MARKER.match(prev)
        body, j = [], i + 1
        while j < len(lines) and not lines[j].strip().startswith(fence):
            body.append(lines[j][len(indent) :] if lines[j].startswith(indent) else lines[j])
            j += 1
        out.append(Block(path, i + 1, lang.lower(), marker.group(1) if marker else "", "\n".join(body)))
        i = j + 1
    return out


ALL_BLOCKS = [b for path in DOC_FILES for b in blocks(path)]


def nsbench_commands(text: str) -> list[list[str]]:
    """The ``nsbench`` invocations of a shell block: each as its argument list (without ``nsbench``).

    Comments are dropped, ``\\`` continues a line, a ``$`` prompt is stripped, and ``&&``, ``||``,
    ``;`` and ``|`` separate commands; ``VAR=value`` before a command is an environment setting.
    """
    joined = re.sub(r"\\\n", " ", text)
    out = []
    for raw in joined.splitlines():
        line = raw.strip()
        if line.startswith("$ "):
            line = line[2:]
        if "nsbench" not in line:
            continue
        try:
            words = shlex.split(line, comments=True)
        except ValueError:  # an unbalanced quote: not a command line (an output line of an example)
            continue
        segment: list[str] = []
        for word in [*words, "&&"]:
            if word in {"&&", "||", ";", "|"}:
                while segment and re.fullmatch(r"[A-Z_][A-Z0-9_]*=\S*", segment[0]):
                    segment.pop(0)
                if segment and segment[0] == "nsbench":
                    out.append(segment[1:])
                segment = []
            else:
                segment.append(word)
    return out


def doc_commands() -> list[tuple[str, list[str]]]:
    found = []
    for b in ALL_BLOCKS:
        if b.lang in SHELL_LANGS:
            found += [(b.where(), argv) for argv in nsbench_commands(b.text)]
        elif b.lang == "yaml":  # a CI recipe: its `run:` steps are shell lines
            steps = "\n".join(m.group(1) for m in re.finditer(r"^\s*-?\s*run:\s*(.+)$", b.text, re.M))
            found += [(b.where(), argv) for argv in nsbench_commands(steps)]
    return found


def inline_commands() -> list[tuple[str, list[str]]]:
    """Inline spans of the prose such as ```nsbench check henon-rk4 --option h=0.02```, with options.

    A span that only names a command (```nsbench run```, ```nsbench simulate```) is a name, not a
    command line; one with an option (``--``) is a command line and must parse.
    """
    found = []
    for path in DOC_FILES:
        text = path.read_text(encoding="utf-8")
        text = re.sub(r"```.*?```", "", text, flags=re.S)  # fenced blocks are checked above
        for m in re.finditer(r"`(nsbench [^`\n]+)`", text):
            span = m.group(1)
            if " --" not in span or re.search(r"[A-Z]{3,}|\.\.\.|\[|<", span[len("nsbench ") :]):
                continue  # no option given, or a pattern with placeholders (`--out DIR`, `--sweep NAME=...`)
            line = text.count("\n", 0, m.start()) + 1
            found += [(f"{path.relative_to(ROOT)}:{line}", argv) for argv in nsbench_commands(span)]
    return found


def parse(argv: list[str]):
    """Parse ``nsbench ARGV`` with the real parser, as the console script does; raises on bad usage."""
    parser = build_parser()
    try:
        return parser.parse_args(argv)
    except SystemExit as exc:  # --help, --version
        if exc.code not in (0, None):
            raise UsageError(f"nsbench {' '.join(argv)}: exit status {exc.code}") from None
        return None


COMMANDS = doc_commands()
INLINE = inline_commands()


def test_the_docs_have_commands():
    # the README's set-up and quick start alone hold a dozen; a broken extractor finds none
    assert len(COMMANDS) > 100, len(COMMANDS)
    assert ["run"] in [argv for _, argv in COMMANDS]  # the README's first command


@pytest.mark.parametrize("where, argv", COMMANDS, ids=[f"{w} {' '.join(a)}"[:90] for w, a in COMMANDS])
def test_doc_command_parses(where, argv):
    try:
        parse(argv)
    except UsageError as exc:
        pytest.fail(f"{where}: `nsbench {' '.join(argv)}` does not parse: {exc}")


@pytest.mark.parametrize("where, argv", INLINE, ids=[f"{w} {' '.join(a)}"[:90] for w, a in INLINE])
def test_inline_doc_command_parses(where, argv):
    """An inline span names a command and an option of it (```nsbench simulate --integrator reference```):
    the option must exist for that command; the span may leave out the required arguments."""
    try:
        parse(argv)
    except UsageError as exc:
        named_only = str(exc).endswith("expected one argument") or "expected one argument (see" in str(exc)
        if argv[-1].startswith("--") and named_only:
            return  # the span names the option (```nsbench ingest --out```), not a value of it
        if not str(exc).startswith("the following arguments are required"):
            pytest.fail(f"{where}: `nsbench {' '.join(argv)}` does not parse: {exc}")


@pytest.mark.parametrize(
    "argv",
    [
        ["simulate", "two-dof", "--case", "2", "--no-such-option", "1"],
        ["simulat", "two-dof"],
        ["simulate", "--integrator", "exact"],
        ["history", "ad", "reports/latest"],
    ],
)
def test_a_bad_command_fails_the_check(argv):
    """The check can fail: an unknown option, a misspelt command or a missing argument is refused."""
    with pytest.raises(UsageError):
        parse(argv)


def test_extractor_reads_chains_prompts_and_comments():
    text = (
        'python -m pip install -e ".[test]" && nsbench run --fresh   # a comment --bogus\n'
        "$ nsbench check henon-rk4 --option h=0.5 \\\n    --check event-times\n"
        "NSBENCH_BENCH_T_END=20 nsbench list | head\n"
    )
    assert nsbench_commands(text) == [
        ["run", "--fresh"],
        ["check", "henon-rk4", "--option", "h=0.5", "--check", "event-times"],
        ["list"],
    ]


# ---------------------------------------------------------------------------- cheap commands, run

#: Command lines of the docs that cost seconds when the compiled core is cached: they run for real.
CHEAP = (
    ["list"],
    ["simulate", "bouncing-ball", "--integrator", "exact", "--t-end", "6"],
)


@pytest.mark.parametrize("argv", CHEAP, ids=[" ".join(a) for a in CHEAP])
def test_cheap_doc_commands_run(argv, tmp_path, monkeypatch, capsys):
    assert argv in [a for _, a in COMMANDS], f"`nsbench {' '.join(argv)}` is no longer in the docs"
    monkeypatch.chdir(tmp_path)
    code = main(argv)
    out = capsys.readouterr()
    assert code == 0, out.err
    if argv[0] == "list":
        assert "two-dof" in out.out and "henon-rk4" in out.out
    else:
        # the README's comment says "4 impacts, then rest at t_Z = 4.0637": the printed log holds
        # the rest event (its time is checked against the closed form in tests/problems)
        assert "rest" in out.out, out.out


# ---------------------------------------------------------------------------- code blocks, run

RUNNABLE = [b for b in ALL_BLOCKS if b.marker == "runnable"]
SUITES = [b for b in ALL_BLOCKS if b.marker == "suite"]


def test_marked_blocks_exist():
    assert any(b.path.name == "README.md" for b in RUNNABLE)
    assert any(b.path.name == "README.md" for b in SUITES)
    for b in RUNNABLE:
        assert b.lang == "python", b.where()
    for b in SUITES:
        assert b.lang == "toml", b.where()


@pytest.mark.parametrize(
    "block", [b for b in ALL_BLOCKS if b.lang in {"python", "toml", "yaml"}], ids=lambda b: f"{b.where()} {b.lang}"
)
def test_every_code_block_is_well_formed(block):
    """Blocks that are not run are read: Python compiles (a method's fragment once dedented), TOML and
    YAML parse. A block left half-edited, or an API call with a syntax that no longer exists, fails."""
    if block.lang == "python":
        compile(textwrap.dedent(block.text), block.where(), "exec")
    elif block.lang == "toml":
        tomllib.loads(block.text)
    else:
        yaml = pytest.importorskip("yaml")  # PyYAML comes with dask
        yaml.safe_load(block.text)


@pytest.mark.parametrize("block", RUNNABLE, ids=[b.where() for b in RUNNABLE])
def test_runnable_python_block(block, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    code = compile(block.text, block.where(), "exec")
    exec(code, {"__name__": "__docs__"})  # an exception fails the test with the block's file and line


@pytest.fixture
def heun_bisect():
    """The example plug-in ``heun-bisect`` (examples/plugin), registered for this process only."""
    from nsbench import registry

    sys.path.insert(0, str(ROOT / "examples" / "plugin" / "src"))
    try:
        from nsbench_heun import HeunBisection

        registry.register("integrators", "heun-bisect", HeunBisection)
        yield HeunBisection
    finally:
        registry.unregister("integrators", "heun-bisect")
        sys.path.remove(str(ROOT / "examples" / "plugin" / "src"))


@pytest.mark.parametrize("block", SUITES, ids=[b.where() for b in SUITES])
def test_suite_block_loads_and_expands(block, heun_bisect):
    """A suite file of the docs loads (every key checked), and expands into cases of the methods it names."""
    from nsbench.bench.suite import load_suite

    data = tomllib.loads(block.text)
    suite = load_suite(data)
    cases = suite.cases()
    named = set(data["integrators"]["only"])
    assert {c.integrator for c in cases} == named
    # heun-bisect runs its grid: one case per (problem, step)
    grid = data["integrators"]["grids"]["heun-bisect"]["grid"]["h"]
    assert sorted({c.options["h"] for c in cases if c.integrator == "heun-bisect"}) == sorted(grid)
