"""The bench commands end to end: bench, report, compare, ingest, run; bad input exits 2."""

from __future__ import annotations

import pytest

from nsbench.cli import main
from tests.bench import _integrators as ti

TINY = """
name = "tiny"
t_span = [0, 20]
repeats = 3
min_sample_time = 0  # one run per sample: the commands, not timing, are tested
problems = [{ name = "one-dof", case = 1 }]
[integrators]
only = ["exact", "scipy-rk45"]
"""


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    d = tmp_path_factory.mktemp("cli")
    (d / "tiny.toml").write_text(TINY)
    return d


def test_bench_report_compare(tiny, capsys):
    out = tiny / "out"
    assert main(["bench", str(tiny / "tiny.toml"), "--out", str(out), "--workers", "1", "--no-progress"]) == 0
    printed = capsys.readouterr()
    text = printed.out
    # --no-progress hides the bar, not the plan: a log or a script gets what the run will do and how long
    (plan,) = [line for line in printed.err.splitlines() if line.startswith("nsbench: suite 'tiny': ")]
    assert "4 case(s): 12 timed samples after a warm-up each" in plan and "estimated about" in plan, plan
    assert "4 cases: 4 computed, 0 already stored" in text and "index.html" in text
    for name in ("results.parquet", "results.csv", "report.md", "index.html", "table.tex", "provenance.json"):
        assert (out / name).exists(), name
    assert main(["bench", str(tiny / "tiny.toml"), "--out", str(out), "--workers", "1", "--no-report"]) == 0
    assert "4 cases: 0 computed, 4 already stored" in capsys.readouterr().out
    assert main(["report", str(out)]) == 0
    assert main(["compare", str(out), str(out / "results.parquet")]) == 0
    assert (
        "4 common cases (0 only in A, 0 only in B); factor 1.5, confidence 0.99; 0 flagged" in capsys.readouterr().out
    )


def test_run_writes_the_report_and_says_each_phase_and_the_answer(tiny, capsys):
    """Without a terminal (captured streams, as in CI): a line per phase on stderr, the answer on stdout."""
    out = tiny / "latest"
    assert main(["run", "--suite", str(tiny / "tiny.toml"), "--out", str(out), "--workers", "1"]) == 0
    assert (out / "index.html").stat().st_size > 10_000
    printed = capsys.readouterr()
    assert "nsbench run took" in printed.out
    phases = [
        line
        for line in printed.err.splitlines()
        if line.startswith("nsbench: ")
        and "% done" not in line
        and not line.startswith(("nsbench: compiling", "nsbench: compiled"))
    ]  # a cold numba cache
    assert [p.split(":")[1].split()[0] for p in phases] == ["suite", "preparing", "timing", "writing"], phases
    import re

    planned = int(re.search(r"4 case\(s\): (\d+) timed samples", printed.err).group(1))
    assert f"timing: every worker is warm; {planned} timed sample(s) in {planned // 4} round(s)" in printed.err
    answer = printed.out[printed.out.index("the answer:") :].splitlines()
    report = (out / "report.md").read_text()
    first = report[report.index("## The answer") :].splitlines()[2]  # the report's first sentence
    assert answer[1] == "  " + first


def test_run_resumes_and_fresh_starts_over_and_another_version_is_named(tiny, capsys):
    import json

    out = tiny / "resumed"
    argv = ["run", "--suite", str(tiny / "tiny.toml"), "--out", str(out), "--workers", "1", "--no-progress"]
    assert main(argv) == 0
    first = capsys.readouterr().out
    assert main(argv) == 0  # the one resume convention: nothing missing, nothing computed
    assert " 0 computed" in capsys.readouterr().out and " 0 computed" not in first
    prov = json.loads((out / "provenance.json").read_text())
    (out / "provenance.json").write_text(json.dumps({**prov, "version_nsbench": "0.0.1"}))
    assert main(argv) == 0
    assert "holds cases of another nsbench (version_nsbench 0.0.1" in capsys.readouterr().err
    assert main(argv + ["--fresh"]) == 0
    assert " 0 computed" not in capsys.readouterr().out


@pytest.mark.parametrize(
    "argv, fragment",
    [
        (["bench", "nope.toml", "--out", "x"], "suite file 'nope.toml' does not exist"),
        (["report", "no-such-dir"], "'no-such-dir' is not a directory"),
        (["compare", "no-a", "no-b"], "results 'no-a' do not exist"),
        (["ingest", "no.json"], "benchmark file 'no.json' does not exist"),
        (["compare", ".", "."], "holds no results"),
        (["compare", ".", ".", "--factor", "0.5"], "factor = 0.5 must be a finite number > 1"),  # checked first
    ],
)
def test_bad_input_exits_2_with_one_line(argv, fragment, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and fragment in err


def test_bad_workers(tiny, capsys):
    assert main(["bench", str(tiny / "tiny.toml"), "--out", str(tiny / "w"), "--workers", "0"]) == 2
    assert "--workers = 0 must be >= 1" in capsys.readouterr().err


def test_a_crashed_reference_is_named_and_the_exit_status_is_1(tmp_path, register, capsys):
    register(ti.Crashing.name, ti.Crashing)
    (tmp_path / "s.toml").write_text(f"""
t_span = [0, 20]
reference = ["{ti.Crashing.name}"]
problems = [{{ name = "one-dof", case = 1 }}]
[integrators]
only = ["scipy-rk45"]
""")
    out = tmp_path / "out"
    assert main(["bench", str(tmp_path / "s.toml"), "--out", str(out), "--workers", "1", "--no-progress"]) == 1
    printed = capsys.readouterr()
    assert "INCOMPLETE: the reference of one-dof/1 could not be computed" in printed.out
    assert "exit code 3" in printed.out
    md = (out / "report.md").read_text()
    top = md[: md.index("## Fixed-target table")]
    assert "**This run is incomplete:**" in top and "The reference of `one-dof/1` could not be computed" in top
    assert "(reference failed: crashed: the worker process died (exit code 3))" in top
    assert not list((out / "references").glob("*.json"))  # a failure is not cached
    from nsbench.bench import load_results

    frame = load_results(out)
    assert (frame["status"] == "success").all()
    assert frame["reference_status"].str.startswith("reference failed").all()
