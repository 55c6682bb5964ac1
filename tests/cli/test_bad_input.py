"""Every bad input to every sub-command: exit status 2, one ``nsbench: error:`` line, no traceback.

The first test is a list of concrete bad inputs (unwritable outputs, out-of-range
counts, malformed suites and JSON files, foreign result folders, unreachable Dask
schedulers...). The second feeds hypothesis-drawn bad values (text that is not a
number, nan, inf, negative, huge, fractional, empty) into the numeric options of
each sub-command. The last, generated from the parser itself, gives every option
and positional argument of every sub-command one set of values (empty, nan, +-inf,
0, -1, 1e300, 1e-300, text, unicode, and paths that are folders, files, missing,
unwritable, symbolic-link loops): each case is refused in one line, or is a success
(or a failed run, exit 1 with one line) that the test documents with its reason.

Every numeric option is parsed by nsbench itself (none uses argparse's
``type=int``/``type=float``), so a bad *value* always reaches our validation and
ends in the one-line format. Values are passed as ``--option=VALUE`` because
argparse reads a separate ``-inf`` or ``-1e12`` as an unknown flag (its own
two-line usage error, exit 2); the ``=`` form hands any text to nsbench. Every
value drawn is bad, so each call must fail before any work starts (the whole file
runs in well under a minute).
"""

from __future__ import annotations

import functools
import json
import math
import os
import socket
import subprocess
import sys

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from nsbench.cli import main

IS_ROOT = hasattr(os, "geteuid") and os.geteuid() == 0

#: Set in the fresh process of :func:`test_no_refusal_needs_compiled_code`: there every refusal below
#: is watched for the compiled code it loads.
_WATCH = "NSBENCH_TEST_WATCH_COMPILED"


@pytest.fixture
def loads_no_compiled_code(monkeypatch):
    """In a watched process, fail a refusal that needed compiled code (loaded from the disk cache or compiled).

    On a fresh install that code is compiled first, and a compilation longer than two seconds is
    announced on stderr (:mod:`nsbench.compiling`): the refusal's one line would come after
    notices. Whether a given case compiles in a test run depends on what ran before it in the same
    process, so only a fresh process watching every case tells; a case that needs compiled code is
    flagged there even though the disk cache is warm, since numba's ``Dispatcher.compile`` is
    called on a process's first use whether it then loads or compiles.
    """
    if not os.environ.get(_WATCH):
        yield
        return
    from numba.core.dispatcher import Dispatcher

    used: list[str] = []
    original = Dispatcher.compile

    def compile(self, sig):
        used.append(f"{self.py_func.__module__}.{self.py_func.__qualname__}")
        return original(self, sig)

    monkeypatch.setattr(Dispatcher, "compile", compile)
    yield
    assert not used, f"refused only after using compiled code: {sorted(set(used))}"


def _pb(names: list[str]) -> dict:
    """A minimal pytest-benchmark JSON document."""
    return {
        "version": "4.0.0",
        "datetime": "2024-01-01",
        "machine_info": {},
        "commit_info": {},
        "benchmarks": [
            {
                "name": n,
                "fullname": f"t.py::{n}",
                "group": None,
                "extra_info": {},
                "stats": {"median": 0.1, "min": 0.09, "max": 0.11, "rounds": 3, "data": [0.09, 0.1, 0.11]},
            }
            for n in names
        ],
    }


SUITES = {
    "problems_int": "problems = 5\n",
    "problems_str": 'problems = "one-dof"\n',
    "problem_name_int": "problems = [{name = 5}]\n",
    "problem_params_int": 'problems = [{name = "one-dof", params = 5}]\n',
    "problem_params_str": 'problems = [{name = "one-dof", params = {c = "abc"}}]\n',
    "problem_cases_float": 'problems = [{name = "one-dof", cases = 5.5}]\n',
    "problem_dimensional_str": 'problems = [{name = "one-dof", dimensional = "yes"}]\n',
    "t_span_inf": 't_span = [0, inf]\nproblems = [{name = "one-dof"}]\n',
    "t_span_nan": 't_span = [0, nan]\nproblems = [{name = "one-dof"}]\n',
    "t_span_str": 't_span = "abc"\nproblems = [{name = "one-dof"}]\n',
    "reference_nope": 'reference = ["nope"]\nproblems = [{name = "one-dof"}]\n',
    "reference_int": 'reference = 5\nproblems = [{name = "one-dof"}]\n',
    "repeats_str": 'repeats = "3"\nproblems = [{name = "one-dof"}]\n',
    "repeats_huge": 'repeats = 1000000000000\nproblems = [{name = "one-dof"}]\n',
    "time_limit_inf": 'time_limit = inf\nproblems = [{name = "one-dof"}]\n',
    "dense_huge": 'dense_points = 1000000000000\nproblems = [{name = "one-dof"}]\n',
    "name_int": 'name = 5\nproblems = [{name = "one-dof"}]\n',
    "targets_nan": 'targets = [nan]\nproblems = [{name = "one-dof"}]\n',
    "integrators_int": 'integrators = 5\nproblems = [{name = "one-dof"}]\n',
    "only_str": 'integrators = {only = "exact"}\nproblems = [{name = "one-dof"}]\n',
    "grids_int": 'integrators = {grids = 5}\nproblems = [{name = "one-dof"}]\n',
    "grid_options_int": 'integrators = {only = ["scipy-rk45"], grids = {scipy-rk45 = {options = 5}}}\n'
    'problems = [{name = "one-dof"}]\n',
    "exclude_int": 'integrators = {exclude = 5}\nproblems = [{name = "one-dof"}]\n',
    "skip_int": 'integrators = {skip_levels = 5}\nproblems = [{name = "one-dof"}]\n',
    "registered_str": 'integrators = {registered = "yes"}\nproblems = [{name = "one-dof"}]\n',
    # issue 52 item 6: both ended in KeyError 'problem_label' after a run of nothing
    "registered_false_only_empty": 'integrators = {registered = false, only = []}\nproblems = [{name = "one-dof"}]\n',
    "every_level_skipped": 'problems = [{name = "one-dof", case = 1}]\n[integrators]\nonly = ["henon-rk4"]\n'
    "[integrators.grids.henon-rk4]\ngrid = {h = [0.01, 0.005]}\n"
    '[integrators.skip_levels.henon-rk4]\nlevels = [0, 1]\nreason = "both skipped"\n',
    "malformed": "problems = [\n",
    "deeply_nested": "problems = " + "[" * 5000 + "]" * 5000 + "\n",  # tomllib recurses: once a RecursionError
    # 1000 x 1000 x 1000 problems: must be refused from the counts, never expanded
    "huge_grid": 'problems = [{name = "one-dof", params = {c = ['
    + ",".join(["0.1"] * 1000)
    + "], h = ["
    + ",".join(["1.0"] * 1000)
    + "], F = ["
    + ",".join(["0.0"] * 1000)
    + "]}}]\n"
    'integrators = {only = ["exact"]}\n',
    "huge_option_grid": 'problems = [{name = "one-dof"}]\nintegrators = {only = ["scipy-rk45"], grids = '
    "{scipy-rk45 = {grid = {rtol = ["
    + ",".join(["1e-6"] * 1000)
    + "], atol = ["
    + ",".join(["1e-8"] * 1000)
    + "], first_step = ["
    + ",".join(["0.1"] * 1000)
    + "]}}}}\n",
}


@pytest.fixture(scope="module")
def d(tmp_path_factory):
    """A folder of bad (and a few good) inputs; returned as a string for argv templates."""
    from nsbench.bench.ingest import ingest

    root = tmp_path_factory.mktemp("bad")
    (root / "afile").write_text("x")
    (root / "bin.bin").write_bytes(bytes(range(256)) * 4)
    (root / "latin.toml").write_bytes("name = 'caf\xe9'\n".encode("latin-1"))
    (root / "bad.json").write_text("{not json")
    (root / "list.json").write_text(json.dumps([1, 2, 3]))
    (root / "b5.json").write_text(json.dumps({"benchmarks": 5}))
    (root / "bints.json").write_text(json.dumps({"benchmarks": [1, 2]}))
    (root / "bstats.json").write_text(json.dumps({"benchmarks": [{"name": "a", "stats": "x"}]}))
    (root / "bmedian.json").write_text(json.dumps({"benchmarks": [{"name": "a", "stats": {"median": "slow"}}]}))
    (root / "bempty.json").write_text(json.dumps({"benchmarks": []}))
    (root / "good1.json").write_text(json.dumps(_pb(["a", "b"])))
    (root / "good2.json").write_text(json.dumps(_pb(["c", "d"])))
    ingest(root / "good1.json", root / "res1")
    ingest(root / "good2.json", root / "res2")
    (root / "emptydir").mkdir()
    (root / "casesfile").mkdir()
    (root / "casesfile" / "cases").write_text("not a folder")  # a worker's FileExistsError (issue 52)
    (root / "otherdir").mkdir()
    (root / "otherdir" / "notes.txt").write_text("another tool's folder")
    (root / "garbage.csv").write_text("a,b\n1,2\n")
    (root / "garbage.parquet").write_text("not parquet")
    (root / "light.toml").write_text(
        't_span = [0.0, 1.0]\nrepeats = 3\nproblems = [{name = "one-dof", case = 1}]\n'
        'integrators = {only = ["exact"]}\n'
    )  # the generated sweep's runs
    (root / "good.toml").write_text(
        't_span = [0.0, 5.0]\nproblems = [{name = "one-dof", case = 1}]\nintegrators = {only = ["exact"]}\n'
    )
    for name, text in SUITES.items():
        if not name.startswith(("malformed", "huge", "deeply")):
            if "t_span" not in text:
                text = "t_span = [0.0, 5.0]\n" + text
            if "integrators" not in text:
                text += 'integrators = {only = ["exact"]}\n'
        (root / f"{name}.toml").write_text(text)
    (root / "loop").symlink_to(root / "loop")  # a symbolic link to itself
    ro = root / "ro"
    ro.mkdir()
    ro.chmod(0o555)
    yield str(root)
    ro.chmod(0o755)


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


S = ["simulate", "one-dof", "--t-end", "5"]
B = [
    "bifurcation",
    "one-dof",
    "--sweep",
    "v0=0.5:1.0:2",
    "--transient",
    "10",
    "--record",
    "4",
    "--no-progress",
    "--formats",
    "png",
    "--out",
    "{d}/bif",
]
L = ["lyapunov", "two-dof", "--case", "2", "--iterations", "80", "--members", "4", "--transient", "10"]
P = [
    "paper",
    "--no-progress",
    "--points",
    "2",
    "--record",
    "4",
    "--transient",
    "10",
    "--case",
    "1",
    "--out",
    "{d}/paper",
]
R = ["compare", "{d}/res1", "{d}/res1"]
B2 = ["bifurcation", "two-dof", "--sweep", "v0=0.5:1.0:2", "--transient", "10", "--record", "4", "--out", "{d}/b2"]
C = [
    "continuation",
    "two-dof",
    "--case",
    "1",
    "--sweep",
    "v0=0.16:0.17",
    "--steps",
    "2",
    "--no-progress",
    "--formats",
    "png",
    "--out",
    "{d}/cont",
]

CASES = [
    # ---- a whole-system method where the hybrid core's runs are needed: refused before any worker starts
    *[
        (f"bifurcation-{name}", B + ["--integrator", name], f"{name} is a whole-system method")
        for name in ("moreau-jean", "smoothing", "switch-model")
    ],
    ("lyapunov-smoothing", L + ["--integrator", "smoothing"], "a Lyapunov exponent needs an event-driven"),
    ("lyapunov-relay", ["lyapunov", "relay-feedback"], "relay-feedback has none (its event kinds: cross"),
    (
        "bifurcation-peaks-of-a-relay",
        ["bifurcation", "relay-feedback", "--sweep", "rho=0.1:0.2:2", "--out", "{d}/bif-rp"],
        "no state of relay-feedback (x1, x2, x3) has its rate among the states; use section event:cross or",
    ),
    (
        "bifurcation-unknown-section",
        ["bifurcation", "two-dof", "--sweep", "v0=0.1:0.2:2", "--section", "event:", "--out", "{d}/bif-es"],
        "section 'event:' is not allowed; choose one of peaks, strobe, stick, mapping, or event:KIND",
    ),
    (
        "bifurcation-portrait-of-a-relay",
        [
            "bifurcation",
            "relay-feedback",
            "--sweep",
            "rho=0.1:0.2:2",
            "--section",
            "event:exit",
            "--portrait",
            "0.15",
            "--out",
            "{d}/bif-r",
        ],
        "--portrait draws the locus of sticking phase of a friction oscillator (blocks on a belt); relay-feedback "
        "does not declare the belt_blocks trait",
    ),
    (
        "bifurcation-peaks-of-henon-heiles-by-heyoka",
        ["bifurcation", "henon-heiles", "--sweep", "coupling=0.9:1:2", "--integrator", "heyoka", "--out", "{d}/bh"],
        "section peaks: heyoka records no state sections on henon-heiles",
    ),
    (
        "bifurcation-mapping-of-henon-heiles",
        ["bifurcation", "henon-heiles", "--sweep", "coupling=0.9:1:2", "--section", "mapping", "--out", "{d}/bif-h"],
        "section mapping records slip events; henon-heiles has none",
    ),
    # ---- continuation (more in tests/cli/test_continuation.py)
    ("continuation-steps-nan", C + ["--steps", "nan"], "--steps = nan"),
    ("continuation-sweep-count", ["continuation", "two-dof", "--sweep", "v0=0.1:0.2:30"], "NAME=START:STOP"),
    ("continuation-origin-inf", C + ["--origin", "inf"], "--origin = inf"),
    ("continuation-out-under-file", C + ["--out", "{d}/afile/cont"], "is a file"),
    # ---- simulate: counts, reals, output files, figure format
    ("simulate-samples-nan", S + ["--samples", "nan", "--trajectory-out", "{d}/tr.csv"], "--samples = nan"),
    ("simulate-samples-inf", S + ["--samples", "inf"], "--samples = inf"),
    ("simulate-samples-neg", S + ["--samples", "-3"], "--samples = -3"),
    ("simulate-samples-frac", S + ["--samples", "2.5"], "whole number"),
    ("simulate-samples-huge", S + ["--samples", "1e12"], "10000000"),
    ("simulate-samples-text", S + ["--samples", "abc"], "not a number"),
    ("simulate-t-end-nan", ["simulate", "one-dof", "--t-end", "nan"], "--t-end = nan"),
    ("simulate-t-end-inf", ["simulate", "one-dof", "--t-end", "inf"], "--t-end = inf"),
    ("simulate-atol-inf", S + ["--integrator", "scipy-rk45", "--atol", "inf"], "--atol = inf"),
    ("simulate-h-inf", S + ["--integrator", "henon-rk4", "--h", "inf"], "--h = inf"),
    ("simulate-h-zero", S + ["--integrator", "henon-rk4", "--h", "0"], "--h = 0"),
    (
        "simulate-option-h-inf",
        S + ["--integrator", "henon-rk4", "--option", "h=inf"],
        "--option h=inf: an option value must be a finite number",
    ),
    (
        "simulate-option-h-huge",
        S + ["--integrator", "henon-rk4", "--option", "h=1e300"],
        "is longer than the whole run",
    ),
    ("simulate-h-tiny", S + ["--integrator", "henon-rk4", "--h", "1e-18"], "more than the step budget"),
    (
        "bifurcation-start-is-stop",
        ["bifurcation", "one-dof", "--sweep", "v0=0.5:0.5:20", "--out", "{d}/bif-ss"],
        "START and STOP are equal",
    ),
    (
        "bifurcation-option-h-huge",
        B + ["--integrator", "henon-rk4", "--option", "h=1e300", "--out", "{d}/bif-h"],
        "is longer than the whole run",
    ),
    ("simulate-events-out-under-file", S + ["--events-out", "{d}/afile/x.csv"], "is a file, not a folder"),
    ("simulate-events-out-is-dir", S + ["--events-out", "{d}/emptydir"], "it is a folder"),
    ("simulate-events-out-missing-dir", S + ["--events-out", "{d}/missing/x.csv"], "does not exist"),
    ("simulate-trajectory-out-under-file", S + ["--trajectory-out", "{d}/afile/x.csv"], "is a file"),
    ("simulate-plot-xyz", S + ["--plot", "{d}/p.xyz"], "png"),
    ("simulate-plot-no-extension", S + ["--plot", "{d}/p"], "no extension"),
    ("simulate-plot-under-file", S + ["--plot", "{d}/afile/p.png"], "is a file"),
    # ---- check
    ("check-unknown-integrator", ["check", "rk99"], "unknown integrator"),
    ("check-n-nan", ["check", "exact", "--problem", "chain", "--n", "nan"], "n = nan"),
    ("check-unknown-problem", ["check", "exact", "--problem", "nope"], "unknown problem"),
    # ---- run
    ("run-workers-zero", ["run", "--workers", "0", "--out", "{d}/runout"], "--workers = 0 must be >= 1"),
    ("run-workers-text", ["run", "--workers", "abc", "--out", "{d}/runout"], "not a number"),
    ("run-workers-huge", ["run", "--workers", "1e12", "--out", "{d}/runout"], "1024"),
    ("run-workers-frac", ["run", "--workers", "2.5", "--out", "{d}/runout"], "whole number"),
    ("run-out-file", ["run", "--out", "{d}/afile"], "it is a file"),
    ("run-out-under-file", ["run", "--out", "{d}/afile/sub"], "is a file, not a folder"),
    ("run-suite-binary", ["run", "--suite", "{d}/bin.bin", "--out", "{d}/runout"], "not UTF-8"),
    # ---- bench: suite files
    *[
        (f"bench-suite-{name}", ["bench", f"{{d}}/{name}.toml", "--out", f"{{d}}/bout-{name}", "--no-progress"], None)
        for name in SUITES
    ],
    (
        "bench-suite-problems-int-message",
        ["bench", "{d}/problems_int.toml", "--out", "{d}/bo"],
        "suite field 'problems' must be a list of tables (each with a 'name'), got int 5",
    ),
    (
        "bench-suite-reference-message",
        ["bench", "{d}/reference_nope.toml", "--out", "{d}/bo"],
        "unknown integrator(s) nope; registered:",
    ),
    ("bench-suite-huge-grid-message", ["bench", "{d}/huge_grid.toml", "--out", "{d}/bo"], "100000"),
    ("bench-suite-t-span-inf-message", ["bench", "{d}/t_span_inf.toml", "--out", "{d}/bo"], "finite"),
    ("bench-suite-latin1", ["bench", "{d}/latin.toml", "--out", "{d}/bo"], "not UTF-8"),
    ("bench-suite-binary", ["bench", "{d}/bin.bin", "--out", "{d}/bo"], "not UTF-8"),
    ("bench-suite-is-dir", ["bench", "{d}/emptydir", "--out", "{d}/bo"], "is a folder"),
    ("bench-out-file", ["bench", "{d}/light.toml", "--out", "{d}/afile"], "it is a file"),
    ("bench-out-under-file", ["bench", "{d}/light.toml", "--out", "{d}/afile/sub"], "is a file, not a folder"),
    ("bench-workers-negative", ["bench", "{d}/light.toml", "--out", "{d}/bo", "--workers", "-1"], "--workers = -1"),
    ("bench-workers-nan", ["bench", "{d}/light.toml", "--out", "{d}/bo", "--workers", "nan"], "--workers = nan"),
    # ---- report
    ("report-missing", ["report", "{d}/missing"], "is not a directory"),
    ("report-file", ["report", "{d}/afile"], "is not a directory"),
    ("report-empty-dir", ["report", "{d}/emptydir"], "holds no results"),
    ("report-other-tool-dir", ["report", "{d}/otherdir"], "holds no results"),
    # ---- compare
    ("compare-missing", ["compare", "{d}/missing", "{d}/res1"], "do not exist"),
    ("compare-empty-dir", ["compare", "{d}/emptydir", "{d}/res1"], "holds no results"),
    ("compare-other-tool-dir", ["compare", "{d}/res1", "{d}/otherdir"], "holds no results"),
    ("compare-binary", ["compare", "{d}/bin.bin", "{d}/res1"], "cannot read results"),
    ("compare-foreign-csv", ["compare", "{d}/garbage.csv", "{d}/res1"], "no nsbench results"),
    ("compare-garbage-parquet", ["compare", "{d}/garbage.parquet", "{d}/res1"], "Parquet"),
    ("compare-no-common-cases", ["compare", "{d}/res1", "{d}/res2"], "no common cases"),
    ("compare-factor-nan", R + ["--factor", "nan"], "factor = nan"),
    ("compare-factor-inf", R + ["--factor", "inf"], "factor = inf"),
    ("compare-factor-text", R + ["--factor", "abc"], "--factor = 'abc' is not a number"),
    ("compare-factor-one", R + ["--factor", "1"], "must be a finite number > 1"),
    ("compare-out-under-file", R + ["--out", "{d}/afile/x.csv"], "is a file"),
    ("compare-out-is-dir", R + ["--out", "{d}/emptydir"], "it is a folder"),
    ("compare-out-missing-dir", R + ["--out", "{d}/missing/x.csv"], "does not exist"),
    # ---- history
    ("archive-add-missing", ["archive", "add", "{d}/missing", "--to", "{d}/arch"], "does not exist"),
    ("archive-show-no-archive", ["archive", "show", "{d}/missing"], "is no nsbench archive"),
    ("archive-merge-one", ["archive", "merge", "{d}/missing", "--to", "{d}/arch"], "two or more archives"),
    ("archive-site-no-archive", ["archive", "site", "{d}/missing", "--out", "{d}/web"], "is no nsbench archive"),
    ("history-show-no-store", ["history", "show", "--store", "{d}/missing"], "history store"),
    ("history-add-missing", ["history", "add", "{d}/missing", "--store", "{d}/hist"], "do not exist"),
    ("history-factor-nan", ["history", "show", "--store", "{d}/missing", "--factor", "nan"], "factor = nan"),
    (
        "history-run-workers-0",
        ["history", "run", "--repo", "{d}", "--commits", "a..b", "--store", "{d}/hist", "--workers", "0"],
        "--workers = 0",
    ),
    # ---- ingest
    ("ingest-malformed-json", ["ingest", "{d}/bad.json", "--out", "{d}/io"], "is not JSON"),
    ("ingest-json-list", ["ingest", "{d}/list.json", "--out", "{d}/io"], "not a pytest-benchmark file"),
    ("ingest-benchmarks-int", ["ingest", "{d}/b5.json", "--out", "{d}/io"], "'benchmarks' must be a list"),
    ("ingest-benchmark-int", ["ingest", "{d}/bints.json", "--out", "{d}/io"], "benchmarks[0] must be a table"),
    ("ingest-stats-str", ["ingest", "{d}/bstats.json", "--out", "{d}/io"], "benchmarks[0].stats must be a table"),
    ("ingest-median-str", ["ingest", "{d}/bmedian.json", "--out", "{d}/io"], "stats.median must be a number"),
    ("ingest-no-benchmarks", ["ingest", "{d}/bempty.json", "--out", "{d}/io"], "holds no benchmarks"),
    ("ingest-binary", ["ingest", "{d}/bin.bin", "--out", "{d}/io"], "not UTF-8"),
    ("ingest-dir", ["ingest", "{d}/emptydir", "--out", "{d}/io"], "is a folder"),
    ("ingest-out-file", ["ingest", "{d}/good1.json", "--out", "{d}/afile"], "it is a file"),
    ("ingest-out-under-file", ["ingest", "{d}/good1.json", "--out", "{d}/afile/sub"], "is a file, not a folder"),
    # ---- bifurcation
    ("bifurcation-sweep-count-nan", B + ["--sweep", "v0=0.5:1.0:nan"], "COUNT = nan"),
    ("bifurcation-sweep-count-inf", B + ["--sweep", "v0=0.5:1.0:inf"], "COUNT = inf"),
    ("bifurcation-sweep-count-neg", B + ["--sweep", "v0=0.5:1.0:-3"], "COUNT = -3"),
    ("bifurcation-sweep-count-frac", B + ["--sweep", "v0=0.5:1.0:2.5"], "whole number"),
    ("bifurcation-sweep-count-huge", B + ["--sweep", "v0=0.5:1.0:1e12"], "1000000"),
    ("bifurcation-sweep-start-nan", B + ["--sweep", "v0=nan:1.0:3"], "finite"),
    ("bifurcation-record-nan", B + ["--record", "nan"], "--record = nan"),
    ("bifurcation-record-huge", B + ["--record", "1e12"], "MAX_RECORD"),
    ("bifurcation-transient-inf", B + ["--transient", "inf"], "--transient = inf"),
    ("bifurcation-transient-neg", B + ["--transient", "-1"], "--transient = -1"),
    ("bifurcation-window-zero", B + ["--window", "0"], "--window = 0"),
    ("bifurcation-workers-inf", B + ["--workers", "inf"], "--workers = inf"),
    ("bifurcation-case-nan", B + ["--case", "nan"], "--case"),
    (
        "bifurcation-case-nan-with-section",
        B + ["--case", "nan", "--section", "peaks", "--integrator", "henon-rk4"],
        "--case",
    ),
    ("bifurcation-h-inf", B + ["--integrator", "henon-rk4", "--h", "inf"], "--h = inf"),
    ("bifurcation-portrait-nan", B + ["--portrait", "nan"], "--portrait = nan"),
    (
        "bifurcation-pair-out-of-range",
        [
            "bifurcation",
            "two-dof",
            "--sweep",
            "v0=0.5:1.0:2",
            "--pair",
            "1,9",
            "--portrait",
            "0.7",
            "--out",
            "{d}/bif2",
        ],
        "--pair 1,9",
    ),
    # ---- issue 52 items 5, 6 and 12: accepted in silence, or a traceback
    ("bifurcation-pair-out-of-range-alone", B2 + ["--pair", "1,9"], "--pair 1,9: two-dof has blocks 1 to 2"),
    (
        "bifurcation-pair-one-block-twice",
        B2 + ["--pair", "1,1", "--portrait", "0.7"],
        "--pair 1,1: the locus needs two different blocks",
    ),
    (
        "bifurcation-portrait-outside-the-sweep",
        B2 + ["--portrait", "5"],
        "--portrait 5 lies outside the swept range v0 = 0.5 to 1",
    ),
    (
        "bifurcation-integrator-twice",
        B + ["--integrator", "exact", "--integrator", "exact"],
        "--integrator exact is given twice; give each integrator once",
    ),
    (
        "bifurcation-whole-system-after-exact",
        B + ["--integrator", "exact", "--integrator", "moreau-jean"],
        "moreau-jean is a whole-system method",
    ),
    ("bifurcation-sweep-case", B + ["--case", "1", "--sweep", "case=1:2:3"], "case is not a parameter"),
    ("bifurcation-param-case", B + ["--param", "case=2"], "--param case=2: case is not a parameter"),
    ("simulate-param-dimensional", S + ["--param", "dimensional=1"], "dimensional is not a parameter"),
    (
        "history-run-one-commit",
        ["history", "run", "--repo", "{d}", "--commits", "HEAD", "--store", "{d}/hist"],
        "--commits 'HEAD' is one commit, not a range A..B",
    ),
    ("version-and-more", ["--version", "extra"], "--version takes no other argument, got 'extra'"),
    (
        "bench-out-cases-is-a-file",
        ["bench", "{d}/light.toml", "--out", "{d}/casesfile"],
        "casesfile/cases' is a file, not the folder of stored cases",
    ),
    (
        "bench-suite-every-level-skipped-message",
        ["bench", "{d}/every_level_skipped.toml", "--out", "{d}/bo"],
        "the suite has no case to run: integrators.skip_levels skips every level of henon-rk4",
    ),
    (
        "bench-suite-registered-false-only-empty-message",
        ["bench", "{d}/registered_false_only_empty.toml", "--out", "{d}/bo"],
        "suite field 'integrators.only' is empty",
    ),
    ("bifurcation-formats-xyz", B + ["--formats", "xyz"], "--formats"),
    ("bifurcation-out-file", B + ["--out", "{d}/afile"], "it is a file"),
    ("bifurcation-out-under-file", B + ["--out", "{d}/afile/sub"], "is a file, not a folder"),
    ("bifurcation-dask-bad-address", B + ["--dask", "not a url", "--out", "{d}/bif-dask1"], "--dask"),
    (
        "bifurcation-dask-closed-port",
        B + ["--dask", "tcp://127.0.0.1:{port}", "--out", "{d}/bif-dask2"],
        "is the scheduler running?",
    ),
    # ---- lyapunov
    ("lyapunov-transient-neg", L + ["--transient", "-1"], "--transient = -1"),
    ("lyapunov-transient-inf", L + ["--transient", "inf"], "--transient = inf"),
    ("lyapunov-iterations-huge", L + ["--iterations", "1e12"], "MAX_ITERATIONS"),
    ("lyapunov-iterations-nan", L + ["--iterations", "nan"], "--iterations = nan"),
    ("lyapunov-members-frac", L + ["--members", "2.5"], "whole number"),
    ("lyapunov-members-huge", L + ["--members", "1e12"], "MAX_MEMBERS"),
    ("lyapunov-seed-huge", L + ["--seed", "1e12"], "MAX_SEED"),
    ("lyapunov-seed-neg", L + ["--seed", "-3"], "--seed = -3"),
    ("lyapunov-workers-huge", L + ["--workers", "1e12"], "MAX_WORKERS"),
    ("lyapunov-d0-inf", L + ["--d0", "inf"], "--d0 = inf"),
    ("lyapunov-h-inf", L + ["--integrator", "henon-rk4", "--h", "inf"], "--h = inf"),
    ("lyapunov-out-under-file", L + ["--out", "{d}/afile/x.csv"], "is a file"),
    ("lyapunov-out-is-dir", L + ["--out", "{d}/emptydir"], "it is a folder"),
    # ---- paper
    ("paper-points-nan", P + ["--points", "nan"], "--points = nan"),
    ("paper-points-frac", P + ["--points", "2.5"], "whole number"),
    ("paper-points-huge", P + ["--points", "1e12"], "MAX_SWEEP_POINTS"),
    ("paper-record-inf", P + ["--record", "inf"], "--record = inf"),
    ("paper-transient-inf", P + ["--transient", "inf"], "--transient = inf"),
    ("paper-workers-zero", P + ["--workers", "0"], "--workers = 0"),
    ("paper-case-five", P + ["--case", "5"], "--case = 5"),
    ("paper-out-file", P + ["--out", "{d}/afile"], "it is a file"),
    ("paper-out-under-file", P + ["--out", "{d}/afile/sub"], "is a file, not a folder"),
]

READ_ONLY_CASES = [
    # ---- continuation (more in tests/cli/test_continuation.py)
    ("continuation-steps-nan", C + ["--steps", "nan"], "--steps = nan"),
    ("continuation-sweep-count", ["continuation", "two-dof", "--sweep", "v0=0.1:0.2:30"], "NAME=START:STOP"),
    ("continuation-origin-inf", C + ["--origin", "inf"], "--origin = inf"),
    ("continuation-out-under-file", C + ["--out", "{d}/afile/cont"], "is a file"),
    ("simulate-events-out-read-only", S + ["--events-out", "{d}/ro/x.csv"], "read-only"),
    ("simulate-plot-read-only", S + ["--plot", "{d}/ro/p.png"], "read-only"),
    ("run-out-read-only", ["run", "--out", "{d}/ro/sub"], "read-only"),
    ("bench-out-read-only", ["bench", "{d}/light.toml", "--out", "{d}/ro"], "read-only"),
    ("compare-out-read-only", R + ["--out", "{d}/ro/x.csv"], "read-only"),
    ("ingest-out-read-only", ["ingest", "{d}/good1.json", "--out", "{d}/ro/sub"], "read-only"),
    ("bifurcation-out-read-only", B + ["--out", "{d}/ro/sub"], "read-only"),
    ("lyapunov-out-read-only", L + ["--out", "{d}/ro/x.csv"], "read-only"),
    ("paper-out-read-only", P + ["--out", "{d}/ro/sub"], "read-only"),
]


def _one_error_line(capsys) -> str:
    err = capsys.readouterr().err
    assert "Traceback" not in err
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1, err
    assert lines[0].startswith("nsbench: error: "), err
    return lines[0]


def _last_wins(argv: list[str]) -> list[str]:
    """``argv`` with an option the base sets and a case sets again given once, the case's value
    (an option given twice is itself refused: the generated sweep checks that)."""
    from nsbench.cli import build_parser

    sub = next(a for a in build_parser()._actions if a.dest == "command").choices.get(argv[0] if argv else "")
    if sub is None:
        return argv
    single = {
        flag for a in sub._actions if a.nargs is None and type(a).__name__ == "_Once" for flag in a.option_strings
    }
    out: list[str] = []
    for i, token in enumerate(argv):
        if token in single and i + 1 < len(argv):
            for j in range(len(out) - 1):
                if out[j] == token:
                    del out[j : j + 2]
                    break
        out.append(token)
    return out


def _argv(template: list[str], d: str) -> list[str]:
    port = str(_free_port())
    return _last_wins([a.replace("{d}", d).replace("{port}", port) for a in template])


@pytest.mark.parametrize(
    "argv, fragment",
    [
        (["bench", "{d}/deeply_nested.toml", "--out", "{d}/deep"], "nested too deeply to be a suite"),
        (["simulate", "one-dof", "--events-out", ""], "argument --events-out: empty value ''"),
        (
            ["simulate", "one-dof", "--integrator", "henon-rk4", "--option", "h=inf"],
            "--option h=inf: an option value must be a finite number",
        ),
        (["simulate", "one-dof", "--integrator", "ofapi", "--option", "h=inf"], "must be a finite number"),
        (["simulate", "one-dof", "--integrator", "henon-rk4", "--t-end", "1e300"], "MAX_SPAN"),
        (["simulate", "one-dof", "--integrator", "henon-rk4", "--t-end", "1e7"], "more than the step budget"),
        (
            ["simulate", "one-dof", "--case", "2", "--integrator", "henon-rk4", "--param", "Omega=1e300"],
            "fewer than two steps per forcing period",
        ),
        (
            ["continuation", "two-dof", "--sweep", "v0=0.16:0.17", "--out", "{d}/A", "--out", "{d}/B"],
            "argument --out: given twice",
        ),
        (["simulate", "one-dof", "--h", "0.1", "--option", "h=0.2", "--integrator", "henon-rk4"], "give it once"),
        (["lyapunov", "two-dof", "--d0", "1e-300"], "--d0 = 1e-300 must be a finite number >= 1e-12"),
        (
            ["continuation", "relay-feedback", "--sweep", "lam=0.052:0.046", "--section", "peaks"],
            "--section: section peaks records the local maxima of a position whose rate is another state",
        ),
        (
            ["continuation", "relay-feedback", "--sweep", "lam=0.052:0.046", "--section", "event:stick"],
            "relay-feedback has none (its event kinds: cross, slide, exit, touch); use section event:cross",
        ),
        (["lyapunov", "two-dof", "--member-limit", "1e300"], "MAX_TIME_LIMIT"),
        (["continuation", "two-dof", "--sweep", "v0=0.16:0.17", "--transient", "1e300"], "MAX_SPAN"),
        (["ingest", "{d}/good1.json", "--out", "{d}/loop"], "symbolic link that leads nowhere (a loop)"),
        (["simulate", "one-dof", "--fresh"], "unrecognized arguments: --fresh"),
    ],
)
def test_the_issues_examples_exit_2_with_one_line(argv, fragment, d, capsys, loads_no_compiled_code):
    """The invocations of issue 30 that ended in a traceback or succeeded silently."""
    assert main([a.replace("{d}", d) for a in argv]) == 2
    assert fragment in _one_error_line(capsys)


@pytest.mark.parametrize(
    "argv, fragment",
    [
        (["simulate", "one-dof", "--param", "law=viscous"], "law = 'viscous' is not a friction law; allowed: coulomb"),
        (["simulate", "one-dof", "--param", "law=weakening"], "law=weakening needs the parameter(s) delta"),
        (["simulate", "one-dof", "--case", "leine", "--param", "delta=-1"], "delta = -1 is out of range"),
        (["simulate", "one-dof", "--case", "leine", "--integrator", "exact"], "weakening friction law"),
        (["simulate", "two-dof", "--case", "leine"], "unknown case 'leine'"),
    ],
)
def test_a_bad_friction_law_exits_2_with_one_line(argv, fragment, capsys):
    assert main(argv) == 2
    assert fragment in _one_error_line(capsys)


def test_a_run_that_ends_in_a_storm_says_so_on_stderr(capsys):
    """A valid command whose run ends early exits with 1 and one line naming the failure: an integrator
    that reports its first guard at every arc's start ends in an event storm within milliseconds (the
    budget exhausted by exact below takes minutes, so it is the slow run's)."""
    from nsbench import registry
    from tests.test_engine import _AlwaysFires

    registry.register("integrators", "test-always-fires", _AlwaysFires)
    try:
        argv = ["simulate", "two-dof", "--case", "1", "--t-end", "5", "--integrator", "test-always-fires"]
        assert main(argv) == 1
    finally:
        registry.unregister("integrators", "test-always-fires")
    out, err = capsys.readouterr()
    assert "status      event storm (Zeno)" in out
    (line,) = _messages(err)
    assert line.startswith("nsbench: simulate: the run ended at t = ") and "of 5: event storm (Zeno)" in line


@pytest.mark.slow  # exact spends its whole budget of 10^7 steps: about 2 min on an idle core
def test_a_run_that_fails_says_so_on_stderr(capsys):
    """A valid command whose run ends early exits with 1 and one line naming the failure (issue 30: a
    forcing frequency of 1e300 exhausts exact's step budget, which said nothing on stderr)."""
    argv = ["simulate", "two-dof", "--case", "2", "--param", "Omega=1e300", "--t-end", "20"]
    assert main(argv) == 1
    out, err = capsys.readouterr()
    assert "status      step budget exhausted" in out
    (line,) = _messages(err)
    assert line.startswith("nsbench: simulate: the run ended at t = ") and "of 20: step budget exhausted" in line


def test_no_refusal_needs_compiled_code():
    """Every refusal above comes before any compiled code is used, so on a fresh install its one line
    is the only line (no compile notice before it).

    The cases run again in a fresh process that watches numba (:func:`loads_no_compiled_code`): in
    this one, what earlier tests loaded hides what a case would have compiled.
    """
    tests = ["test_bad_input_exits_2_with_one_line", "test_the_issues_examples_exit_2_with_one_line"]
    if not IS_ROOT:
        tests.append("test_read_only_outputs_exit_2_with_one_line")
    run = subprocess.run(
        [
            sys.executable,
            "-m",
            "pytest",
            __file__,
            "-q",
            "-p",
            "no:cacheprovider",
            "-p",
            "no:xdist",
            "-k",
            " or ".join(tests),
        ],
        env={**os.environ, _WATCH: "1"},
        capture_output=True,
        text=True,
        timeout=900,
    )
    failed = [
        line
        for line in run.stdout.splitlines()
        if line.startswith(("FAILED", "ERROR")) or "refused only after using compiled code" in line
    ]
    assert run.returncode == 0 and "passed" in run.stdout, "\n".join(failed) or run.stdout[-3000:] + run.stderr[-2000:]


def test_the_list_covers_every_sub_command():
    from nsbench.cli import COMMANDS

    covered = {argv[0] for _, argv, _ in CASES}
    assert covered >= set(COMMANDS) - {"listing"}
    assert len(CASES) + len(READ_ONLY_CASES) >= 60


@pytest.mark.parametrize("argv, fragment", [pytest.param(a, f, id=i) for i, a, f in CASES])
def test_bad_input_exits_2_with_one_line(argv, fragment, d, capsys, loads_no_compiled_code):
    assert main(_argv(argv, d)) == 2
    line = _one_error_line(capsys)
    if fragment is not None:
        assert fragment in line


@pytest.mark.skipif(IS_ROOT, reason="root writes into read-only folders")
@pytest.mark.parametrize("argv, fragment", [pytest.param(a, f, id=i) for i, a, f in READ_ONLY_CASES])
def test_read_only_outputs_exit_2_with_one_line(argv, fragment, d, capsys, loads_no_compiled_code):
    assert main(_argv(argv, d)) == 2
    assert fragment in _one_error_line(capsys)


@pytest.mark.parametrize("argv, fragment", [pytest.param(a, f, id=i) for i, a, f in READ_ONLY_CASES])
def test_read_only_outputs_as_seen_by_os_access(argv, fragment, d, capsys, monkeypatch):
    """The same cases where ``os.access`` says the folder is read-only (so that they run as root too)."""
    ro = os.path.join(d, "ro")
    real = os.access
    monkeypatch.setattr(os, "access", lambda p, mode, **kw: False if str(p).startswith(ro) else real(p, mode, **kw))
    assert main(_argv(argv, d)) == 2
    assert fragment in _one_error_line(capsys)


def test_dask_scheduler_without_workers(d, capsys, monkeypatch):
    from distributed import LocalCluster

    from nsbench.bifurcation import cluster as _dask

    monkeypatch.setattr(_dask, "WORKER_TIMEOUT", 1.0)
    with LocalCluster(n_workers=0, processes=False, dashboard_address=":0") as cluster:
        argv = _argv(B + ["--dask", cluster.scheduler_address, "--out", "{d}/bif-dask3"], d)
        assert main(argv) == 2
    line = _one_error_line(capsys)
    assert "no workers" in line and cluster.scheduler_address in line


def _subprocess(argv: list[str], **kw) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "nsbench", *argv], capture_output=True, text=True, timeout=120, **kw)


@pytest.mark.parametrize("address", ["not a url", "tcp://127.0.0.1:{port}"])
def test_dask_errors_leave_no_traceback_at_exit(address, d):
    """distributed's half-built Client must not print a traceback when the interpreter exits."""
    done = _subprocess(_argv(B + ["--dask", address, "--out", "{d}/bif-dask4"], d))
    assert done.returncode == 2
    assert "Traceback" not in done.stderr and "Exception ignored" not in done.stderr
    assert done.stderr.count("\n") == 1 and done.stderr.startswith("nsbench: error: --dask")


@pytest.mark.parametrize("argv", [["list"], ["compare", "{d}/res1", "{d}/res1", "--all"]])
def test_a_closed_stdout_pipe_ends_quietly(argv, d):
    """``nsbench compare ... | head``: the reader is gone, so no BrokenPipeError traceback."""
    read, write = os.pipe()
    os.close(read)
    try:
        proc = subprocess.Popen(
            [sys.executable, "-m", "nsbench", *_argv(argv, d)], stdout=write, stderr=subprocess.PIPE, text=True
        )
    finally:
        os.close(write)
    _, err = proc.communicate(timeout=120)
    assert err == "" and proc.returncode == 141


# ---------------------------------------------------------------------- hypothesis


def _not_a_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return True
    return False


_TEXT = st.text(max_size=12).filter(_not_a_number).filter(lambda t: "\x00" not in t)
_SPECIAL = st.sampled_from(["nan", "NaN", "-nan", "inf", "+inf", "-inf", "Infinity", "-Infinity", "1e400"])
_NEGATIVE = st.one_of(
    st.integers(max_value=-1).map(str), st.floats(max_value=-1e-9, allow_infinity=False, allow_nan=False).map(repr)
)
_FRACTION = (
    st.floats(min_value=-1e6, max_value=1e6, allow_nan=False).filter(lambda x: not float(x).is_integer()).map(repr)
)
_HUGE = st.one_of(
    st.integers(min_value=10**12).map(str), st.floats(min_value=1e12, allow_infinity=False, allow_nan=False).map(repr)
)

#: What makes a value bad for each kind of option (every value these draw is refused).
BAD = {
    # a count: whole number in a bounded range (every bound is below 10^12)
    "count": st.one_of(_TEXT, _SPECIAL, _NEGATIVE, _FRACTION, _HUGE, st.just(""), st.just("0")),
    # a seed: whole number from 0 to 2^32 - 1 (so 0 is allowed)
    "seed": st.one_of(_TEXT, _SPECIAL, _NEGATIVE, _FRACTION, _HUGE, st.just("")),
    # a finite number >= 0 (transient)
    "nonneg": st.one_of(_TEXT, _SPECIAL, _NEGATIVE, st.just("")),
    # a finite number > 0 (step size, window, tolerances, time limits)
    "positive": st.one_of(_TEXT, _SPECIAL, _NEGATIVE, st.just(""), st.just("0"), st.just("-0.0")),
    # any finite number (t-end, portrait value)
    "finite": st.one_of(_TEXT, _SPECIAL, st.just("")),
    # d0 in (0, 0.01); compare's factor > 1
    "d0": st.one_of(_TEXT, _SPECIAL, _NEGATIVE, st.just("0"), st.floats(min_value=0.01, max_value=1e300).map(repr)),
    "factor": st.one_of(_TEXT, _SPECIAL, _NEGATIVE, st.floats(min_value=-1e6, max_value=1.0).map(repr)),
}

#: Per sub-command: the base argv (valid, and light) and its numeric options with their kind.
NUMERIC = {
    "simulate": (
        S,
        {"--samples": "count", "--t-end": "finite", "--rtol": "positive", "--atol": "positive", "--h": "positive"},
    ),
    "run": (["run", "--out", "{d}/hyp-run"], {"--workers": "count"}),
    "bench": (["bench", "{d}/light.toml", "--out", "{d}/hyp-bench"], {"--workers": "count"}),
    "compare": (R, {"--factor": "factor"}),
    "bifurcation": (
        B,
        {
            "--record": "count",
            "--workers": "count",
            "--transient": "nonneg",
            "--window": "positive",
            "--h": "positive",
            "--portrait": "finite",
            "--point-limit": "positive",
            "--setup-limit": "positive",
        },
    ),
    "lyapunov": (
        L,
        {
            "--iterations": "count",
            "--members": "count",
            "--seed": "seed",
            "--workers": "count",
            "--transient": "nonneg",
            "--d0": "d0",
            "--h": "positive",
            "--member-limit": "positive",
        },
    ),
    "continuation": (C, {"--steps": "count", "--transient": "nonneg", "--origin": "finite"}),
    "paper": (
        P,
        {"--points": "count", "--record": "count", "--workers": "count", "--transient": "nonneg", "--case": "count"},
    ),
}


def _options(command: str) -> list[str]:
    """The numeric options of ``command`` that its parser knows (another may be added later)."""
    from nsbench.cli import build_parser

    parser = build_parser()
    sub = next(a for a in parser._actions if a.dest == "command").choices[command]
    known = {flag for action in sub._actions for flag in action.option_strings}
    return [flag for flag in NUMERIC[command][1] if flag in known]


@pytest.mark.parametrize("command", sorted(NUMERIC))
@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_bad_numbers_exit_2_with_one_line(command, data, d, capsys):
    base, kinds = NUMERIC[command]
    flag = data.draw(st.sampled_from(_options(command)), label="option")
    value = data.draw(BAD[kinds[flag]], label="value")
    if command == "bifurcation" and flag == "--h":
        base = base + ["--integrator", "henon-rk4"]
    if command == "simulate" and flag in ("--rtol", "--atol"):
        base = base + ["--integrator", "scipy-rk45"]
    if command == "simulate" and flag == "--h":
        base = base + ["--integrator", "henon-rk4"]
    capsys.readouterr()
    assert main(_argv(base, d) + [f"{flag}={value}"]) == 2
    line = _one_error_line(capsys)
    assert flag.lstrip("-") in line or "factor" in line, line


@settings(max_examples=200, deadline=None)
@given(count=BAD["count"], seed=BAD["seed"], nonneg=BAD["nonneg"], positive=BAD["positive"], finite=BAD["finite"])
def test_the_parsers_refuse_every_bad_kind(count, seed, nonneg, positive, finite):
    """The strategies against the parsers directly: each draw is refused (no value slips through)."""
    from nsbench.inputs import parse_count, parse_real
    from nsbench.errors import ConfigError

    for call in (
        lambda: parse_count(count, "--n", low=1, bound="MAX_WORKERS"),
        lambda: parse_count(seed, "--seed", low=0, bound="MAX_SEED"),
        lambda: parse_real(nonneg, "--t", low=0.0),
        lambda: parse_real(positive, "--h", low=0.0, low_open=True),
        lambda: parse_real(finite, "--x"),
    ):
        with pytest.raises(ConfigError):
            call()


# ---------------------------------------------------------------------- the API's bad arguments
def _light_suite() -> dict:
    return {"t_span": [0.0, 1.0], "problems": [{"name": "one-dof", "case": 1}], "integrators": {"only": ["exact"]}}


def _sweep_spec():
    from nsbench.bifurcation.sweep import SweepSpec

    return SweepSpec(problem="two-dof", case=1, name="v0", start=0.5, stop=1.0, count=2, transient=10.0, record=4)


def _api_calls(tmp: str) -> list[tuple[str, object, str]]:
    """(id, call, fragment of the ConfigError) of issue 52 item 5: each was accepted in silence, or
    ended in a plain TypeError, ValueError, OverflowError, AttributeError or FileNotFoundError."""
    import nsbench
    from nsbench.bench.runner import run_suite
    from nsbench.bifurcation.parallel import run_sweep

    p = nsbench.get_problem("two-dof", case=1)
    return [
        ("simulate-t-end-text", lambda: nsbench.simulate(p, "henon-rk4", "5"), "t_end = '5' must be a number"),
        ("simulate-t-end-huge", lambda: nsbench.simulate(p, "exact", 10**400), "t_end = 1000"),
        ("simulate-problem-none", lambda: nsbench.simulate(None, "exact", 5.0), "problem must be a problem from"),
        ("simulate-y0-text", lambda: nsbench.simulate(p, "exact", 5.0, y0="abcd"), "y0 must be an iterable"),
        ("simulate-options-list", lambda: nsbench.simulate(p, "exact", 5.0, options=[1]), "options = [1]"),
        ("get-problem-int", lambda: nsbench.get_problem(5), "problem name must be a string"),
        (
            "get-problem-dimensional-text",
            lambda: nsbench.get_problem("two-dof", dimensional="yes"),
            "dimensional = 'yes' must be True or False",
        ),
        ("get-problem-huge-int", lambda: nsbench.get_problem("two-dof", v0=10**400), "parameter v0 = 1000"),
        (
            "integrator-config-top-level-h",
            lambda: nsbench.integrator_from_config({"name": "henon-rk4", "h": math.nan}),
            "unknown key(s) 'h'",
        ),
        (
            "run-suite-workers-negative",
            lambda: run_suite(_light_suite(), f"{tmp}/rs", workers=-1, progress=False),
            "workers = -1 must be a whole number from 1 to 1024",
        ),
        (
            "run-suite-out-proc",
            lambda: run_suite(_light_suite(), "/proc/x", progress=False),
            "out = '/proc/x': cannot create the results folder",
        ),
        ("run-suite-out-int", lambda: run_suite(_light_suite(), 5, progress=False), "out = 5 must be the path"),
        (
            "run-sweep-chunk-size-zero",
            lambda: run_sweep(_sweep_spec(), f"{tmp}/sw", chunk_size=0, workers=0, progress=False),
            "chunk_size = 0 must be a whole number from 1",
        ),
        (
            "run-sweep-workers-negative",
            lambda: run_sweep(_sweep_spec(), f"{tmp}/sw", workers=-1, progress=False),
            "workers = -1 must be a whole number from 0 to 1024",
        ),
        (
            "run-sweep-out-proc",
            lambda: run_sweep(_sweep_spec(), "/proc/x", workers=0, progress=False),
            "out = '/proc/x': cannot create the sweep folder",
        ),
        ("run-sweep-spec-dict", lambda: run_sweep({"problem": "two-dof"}, f"{tmp}/sw"), "spec must be a SweepSpec"),
    ]


API_IDS = [
    "simulate-t-end-text",
    "simulate-t-end-huge",
    "simulate-problem-none",
    "simulate-y0-text",
    "simulate-options-list",
    "get-problem-int",
    "get-problem-dimensional-text",
    "get-problem-huge-int",
    "integrator-config-top-level-h",
    "run-suite-workers-negative",
    "run-suite-out-proc",
    "run-suite-out-int",
    "run-sweep-chunk-size-zero",
    "run-sweep-workers-negative",
    "run-sweep-out-proc",
    "run-sweep-spec-dict",
]


@pytest.mark.parametrize("name", API_IDS)
def test_bad_api_arguments_are_config_errors_naming_them(name, tmp_path):
    from nsbench.errors import ConfigError

    calls = {i: (call, fragment) for i, call, fragment in _api_calls(str(tmp_path))}
    assert sorted(calls) == sorted(API_IDS)
    call, fragment = calls[name]
    with pytest.raises(ConfigError) as info:  # nothing else: a plain TypeError etc. fails the test
        call()
    assert fragment in str(info.value)
    assert not (tmp_path / "rs").exists() and not (tmp_path / "sw").exists()  # refused before any work


def test_every_integrator_is_checked_before_the_first_value(d, capsys):
    # issue 52 item 12: the whole exact sweep ran (29 s), then moreau-jean was refused with exit 2
    out = f"{d}/bif-12"
    argv = B + ["--integrator", "exact", "--integrator", "moreau-jean", "--out", out]
    assert main(_argv(argv, d)) == 2
    assert "moreau-jean is a whole-system method" in _one_error_line(capsys)
    assert not os.path.exists(out)  # nothing ran, nothing was written


def test_a_truncated_provenance_is_named_by_report_and_rewritten_by_the_resume(d, tmp_path, capsys):
    # issue 52 item 6: a traceback in report and in the resume, which blocked the folder for good
    out = tmp_path / "b"
    assert main(["bench", f"{d}/light.toml", "--out", str(out), "--workers", "1", "--no-progress"]) == 0
    prov = out / "provenance.json"
    prov.write_text(prov.read_text()[:40])
    capsys.readouterr()
    assert main(["report", str(out)]) == 2
    line = _one_error_line(capsys)
    assert "provenance.json' is damaged" in line and "resuming the run (nsbench bench SUITE --out" in line
    assert main(["bench", f"{d}/light.toml", "--out", str(out), "--workers", "1", "--no-progress"]) == 0
    err = capsys.readouterr().err
    assert "Traceback" not in err and "provenance.json is damaged" in err
    assert json.loads(prov.read_text())["suite"]["integrators"] == {"only": ["exact"]}  # written again
    assert main(["report", str(out)]) == 0


# ---------------------------------------------------------------------- the generated sweep
# Every option (and positional argument) of every sub-command, found in the parser itself, is
# given every value of one set, in-process (nsbench.cli.main with captured streams, a few ms per
# refused case). Each case must end with exit status 2 and one `nsbench: error:` line, or be a
# documented success (SUCCESSES: the value is valid there, and why). A new option joins the sweep
# by itself; one whose values are paths must be named in PATHS.

SWEEP_VALUES = {
    "empty": "",
    "nan": "nan",
    "inf": "inf",
    "-inf": "-inf",
    "zero": "0",
    "negative": "-1",
    "huge": "1e300",
    "tiny": "1e-300",
    "text": "abc",
    "unicode": "\u00fc\u2202",
    # a fresh folder per case ({fresh}: empty; a success may write into it)
    "folder": "{fresh}",
    "file": "{fresh}/afile",
    "missing": "{fresh}/missing/x",
    "unwritable": "{d}/ro/x",
    "loop": "{d}/loop",
}
#: A path's value kinds. Numbers and text are file names like any other (the plain name of the
#: base command line is one), so the unicode name stands for them: each success here runs the
#: command for real, and a name more would only cost time.
PATH_KINDS = ("empty", "unicode", "folder", "file", "missing", "unwritable", "loop")
#: Options and positional arguments whose value is a path, and what it names: an output file
#: ("out-file"), an output folder ("out-dir"), or an input ("in").
PATHS = {
    ("simulate", "--events-out"): "out-file",
    ("simulate", "--trajectory-out"): "out-file",
    ("simulate", "--plot"): "out-file",
    ("run", "--out"): "out-dir",
    ("run", "--suite"): "in",
    ("bench", "suite"): "in",
    ("bench", "--out"): "out-dir",
    ("report", "directory"): "in",
    ("compare", "a"): "in",
    ("compare", "b"): "in",
    ("compare", "--out"): "out-file",
    ("ingest", "file"): "in",
    ("ingest", "--out"): "out-dir",
    ("bifurcation", "--out"): "out-dir",
    ("continuation", "--out"): "out-dir",
    ("continuation", "--diagram"): "in",
    ("lyapunov", "--out"): "out-file",
    ("paper", "--out"): "out-dir",
}
#: A valid, light command line per sub-command; the swept option replaces its value here
#: ({fresh}: a new empty folder per case, so that each success writes a folder of its own).
SWEEP_BASES = {
    "list": ["list"],
    "simulate": ["simulate", "one-dof", "--case", "2", "--t-end", "5", "--integrator", "henon-rk4"],
    "check": ["check", "henon-rk4", "--check", "config-round-trip"],
    "run": ["run", "--suite", "{d}/light.toml", "--out", "{fresh}/out", "--workers", "1", "--no-progress"],
    "bench": ["bench", "{d}/light.toml", "--out", "{fresh}/out", "--workers", "1", "--no-progress", "--no-report"],
    "report": ["report", "{d}/res1"],
    "compare": ["compare", "{d}/res1", "{d}/res1"],
    "ingest": ["ingest", "{d}/good1.json", "--out", "{fresh}/out"],
    "bifurcation": [
        "bifurcation",
        "one-dof",
        "--sweep",
        "v0=0.5:1.0:2",
        "--transient",
        "10",
        "--record",
        "4",
        "--no-progress",
        "--formats",
        "png",
        "--out",
        "{fresh}/out",
        "--workers",
        "1",
        "--integrator",
        "henon-rk4",
    ],
    "continuation": [
        "continuation",
        "two-dof",
        "--case",
        "1",
        "--sweep",
        "v0=0.16:0.17",
        "--steps",
        "2",
        "--transient",
        "10",
        "--no-progress",
        "--formats",
        "png",
        "--out",
        "{fresh}/out",
    ],
    "lyapunov": ["lyapunov", "two-dof", "--case", "1", "--iterations", "80", "--members", "4", "--transient", "1"],
    "paper": [
        "paper",
        "--no-progress",
        "--points",
        "2",
        "--record",
        "4",
        "--transient",
        "1",
        "--case",
        "1",
        "--out",
        "{fresh}/out",
        "--no-continuation",
        "--workers",
        "1",
    ],
}
#: Sub-commands with actions of their own, covered by hand-written cases instead of the generated sweep.
NESTED = {"history", "archive"}
#: Where the value of NAME=VALUE options goes (a real name of the base's problem or integrator).
ASSIGNMENTS = {"--param": "Omega={v}", "--option": "h={v}", "--sweep": None}
SWEEP_FORMS = {"bifurcation": "v0={v}:1.0:2", "continuation": "v0={v}:0.17"}

_NEW_OUT = {"unicode", "file"}  # a new file of that name (in the test's folder), or an existing one replaced
_NEW_DIR = {"unicode", "folder", "missing"}  # an output folder is created with its parents
_OMEGA = "a forcing frequency is any finite number >= 0"
_UNFORCED = _OMEGA + "; the base problem is unforced (F = 0), so it changes nothing"
_SPAN = "a span of zero or 1e-300 time units: a valid, short run"
_SIZE = "a parameter is checked to be finite and physical, not bounded in size (docs/model.md)"
#: (sub-command, option) -> {value kind: why it is valid}: exit status 0.
SUCCESSES: dict[tuple[str, str], dict[str, str]] = {
    **{
        (cmd, opt): dict.fromkeys(_NEW_OUT, "a new file of that name, or an existing file replaced")
        for (cmd, opt), kind in PATHS.items()
        if kind == "out-file" and opt != "--plot"
    },  # a plot needs .png etc.
    **{
        (cmd, opt): dict.fromkeys(_NEW_DIR, "a new folder (with its parents), or an empty one")
        for (cmd, opt), kind in PATHS.items()
        if kind == "out-dir"
    },
    ("simulate", "--param"): dict.fromkeys(("zero", "tiny"), _OMEGA + " (0: a constant force)"),
    ("simulate", "--t-end"): {"tiny": _SPAN},
    ("check", "--option"): dict.fromkeys(("huge", "tiny"), "h > 0; config-round-trip only builds the configuration"),
    ("check", "--param"): dict.fromkeys(("zero", "huge", "tiny"), _OMEGA + "; config-round-trip builds no problem"),
    ("compare", "--factor"): {"huge": "a factor is any finite number > 1"},
    ("bifurcation", "--param"): dict.fromkeys(("zero", "huge", "tiny"), _UNFORCED),
    ("bifurcation", "--sweep"): {
        "zero": "v0 from 0 (a belt at rest) to 1: valid values of v0",
        "tiny": "v0 from 1e-300 to 1: valid values of v0",
        "huge": "v0 from 1e300 to 1: " + _SIZE,
    },
    ("bifurcation", "--transient"): dict.fromkeys(("zero", "tiny"), _SPAN),
    ("bifurcation", "--window"): {
        "tiny": "a recording window of 1e-300: every value is kept with its status "
        "(too few points), the sweep itself completes"
    },
    ("bifurcation", "--point-limit"): {
        "tiny": "every value passes its limit of 1e-300 s: each is kept with status "
        "'time limit', the sweep itself completes"
    },
    ("bifurcation", "--setup-limit"): {
        "tiny": "every set-up passes its limit of 1e-300 s: each value is kept with "
        "status 'time limit', the sweep itself completes"
    },
    **{
        ("check", opt): {
            "tiny": "a limit of a plug-in integrator's supervised worker: the base's built-in integrator "
            "runs in this process and its checks pass"
        }
        for opt in ("--time-limit", "--setup-limit")
    },
    **{
        (command, "--setup-limit"): {
            "tiny": "the limit of a plug-in problem's factory, built first in a worker: a built-in problem is "
            "built in this process, under no limit"
        }
        for command in ("simulate", "lyapunov")
    },
    ("list", "--setup-limit"): {
        "tiny": "the limit of a plug-in problem's factory under 'list coverage': the plain listing builds no problem"
    },
    ("continuation", "--param"): dict.fromkeys(("zero", "huge", "tiny"), _UNFORCED),
    ("continuation", "--sweep"): {
        **dict.fromkeys(("zero", "tiny"), "v0 from 0 or 1e-300 to 0.17: valid values of v0"),
        "huge": "v0 from 1e300 to 0.17: " + _SIZE + "; values without an orbit are a result",
    },
    ("continuation", "--transient"): dict.fromkeys(("zero", "tiny"), _SPAN),
    ("lyapunov", "--param"): dict.fromkeys(("zero", "huge", "tiny"), _UNFORCED),
    ("lyapunov", "--transient"): dict.fromkeys(("zero", "tiny"), _SPAN),
    ("lyapunov", "--seed"): {"zero": "a seed is a whole number from 0"},
    ("paper", "--transient"): dict.fromkeys(("zero", "tiny"), _SPAN),
}
#: (sub-command, option) -> {value kind: why}: a valid value whose run fails, which exits with
#: status 1 and one ``nsbench:`` line on stderr naming the failure (its details on stdout).
FAILURES: dict[tuple[str, str], dict[str, str]] = {
    ("lyapunov", "--member-limit"): {"tiny": "every member passes a limit of 1e-300 s: no exponent"},
    ("continuation", "--time-limit"): {"tiny": "the continuation passes its limit of 1e-300 s: no branch"},
    ("continuation", "--setup-limit"): {"tiny": "the flow's set-up passes its limit of 1e-300 s: no branch"},
}


def _sweep_actions(command: str):
    from nsbench.cli import build_parser

    parser = build_parser()
    sub = next(a for a in parser._actions if a.dest == "command").choices[command]
    return [a for a in sub._actions if "-h" not in a.option_strings]


def _name(action) -> str:
    return action.option_strings[-1] if action.option_strings else action.dest


def _with_value(command: str, action, value: str) -> list[str]:
    """The base command line with ``action`` set to ``value`` (replaced if the base has it)."""
    base = list(SWEEP_BASES[command])
    if not action.option_strings:  # a positional: the base's n-th positional token
        positionals = [a.dest for a in _sweep_actions(command) if not a.option_strings]
        index = positionals.index(action.dest)
        slots = [i for i, tok in enumerate(base[1:], 1) if not tok.startswith("-") and not base[i - 1].startswith("--")]
        if index < len(slots):
            base[slots[index]] = value
            return base
        return base + [value]
    flag = action.option_strings[-1]
    if flag == "--sweep":
        value = SWEEP_FORMS.get(command, "{v}").format(v=value)
    elif flag in ASSIGNMENTS and ASSIGNMENTS[flag]:
        value = ASSIGNMENTS[flag].format(v=value)
    if flag in base and action.nargs != 0:
        i = base.index(flag)
        del base[i : i + 2]
    return base + [f"{flag}={value}"]


def sweep_cases(command: str) -> list[tuple[str, str, list[str]]]:
    """``(option, value kind, argv)`` for every option of ``command`` and every value of the set."""
    cases = []
    for action in _sweep_actions(command):
        name = _name(action)
        kinds = PATH_KINDS if (command, name) in PATHS else tuple(SWEEP_VALUES)
        for kind in kinds:
            cases.append((name, kind, _with_value(command, action, SWEEP_VALUES[kind])))
    return cases


def _messages(err: str) -> list[str]:
    """The lines of stderr, but numba's first-compilation notices (nsbench.compiling: a cold cache)."""
    return [
        line
        for line in err.splitlines()
        if line.strip() and not line.startswith(("nsbench: compiling", "nsbench: compiled"))
    ]


def _run_in_process(argv: list[str], capsys) -> tuple[int | None, str, str]:
    capsys.readouterr()
    try:
        code = main(argv)
    except BaseException as exc:  # noqa: BLE001 - a traceback is what the sweep looks for
        import traceback

        return None, "", "".join(traceback.format_exception(exc))
    out, err = capsys.readouterr()
    return code, out, err


@functools.lru_cache(maxsize=None)
def _sweep_actions_cached(command: str):
    return _sweep_actions(command)


# The refusals are the default run's (each ends in milliseconds); the values documented to succeed or
# to fail run real work (a bench, a sweep, a report) and are the slow run's.
@pytest.mark.parametrize("outcome", ["refused", pytest.param("documented", marks=pytest.mark.slow)])
@pytest.mark.parametrize("command", sorted(SWEEP_BASES))
def test_generated_sweep_every_option_every_value(command, outcome, d, capsys, monkeypatch, tmp_path):
    ro = os.path.join(d, "ro")
    real = os.access
    # the read-only folder is read-only for root too, as os.access sees it (root ignores the mode)
    monkeypatch.setattr(os, "access", lambda p, mode, **kw: False if str(p).startswith(ro) else real(p, mode, **kw))
    monkeypatch.chdir(tmp_path)  # new files and folders named by a value land here
    wrong = []
    for i, (name, kind, template) in enumerate(sweep_cases(command)):
        known = (
            SUCCESSES.get((command, name), {}).get(kind) is not None
            or FAILURES.get((command, name), {}).get(kind) is not None
        )
        if known != (outcome == "documented"):
            continue
        fresh = tmp_path / f"case{i}"
        fresh.mkdir()
        (fresh / "afile").write_text("x")
        argv = [a.replace("{fresh}", str(fresh)).replace("{d}", d) for a in template]
        code, out, err = _run_in_process(argv, capsys)
        lines = _messages(err)
        refused = code == 2 and len(lines) == 1 and lines[0].startswith("nsbench: error: ") and "Traceback" not in err
        documented = SUCCESSES.get((command, name), {}).get(kind)
        failure = FAILURES.get((command, name), {}).get(kind)
        if documented is not None:
            if code != 0 or "Traceback" in err:
                wrong.append(
                    f"{name}={SWEEP_VALUES[kind]!r} ({kind}): documented success ({documented}) "
                    f"ended with {code}: {err.strip()[-300:]}"
                )
        elif failure is not None:
            if not (code == 1 and len(lines) == 1 and lines[0].startswith("nsbench: ") and "Traceback" not in err):
                wrong.append(
                    f"{name}={SWEEP_VALUES[kind]!r} ({kind}): documented failure ({failure}) "
                    f"ended with {code}: {err.strip()[-300:]}"
                )
        elif not refused:
            wrong.append(
                f"{name}={SWEEP_VALUES[kind]!r} ({kind}): exit {code}, stderr {err.strip()[-300:]!r}, "
                f"stdout {out.strip()[-200:]!r}"
            )
    assert not wrong, f"{len(wrong)} case(s) of {command}:\n" + "\n".join(wrong)


def test_the_sweep_covers_every_sub_command_and_path():
    from nsbench.cli import COMMANDS, build_parser

    parser = build_parser()
    names = set(next(a for a in parser._actions if a.dest == "command").choices)
    # `history` has actions of its own (add, show, run), which the generated sweep does not walk: its bad
    # inputs are the hand-written cases above (history-*); every other sub-command is swept
    assert names == set(SWEEP_BASES) | NESTED and len(COMMANDS) == len(SWEEP_BASES) + len(NESTED)
    assert all(any(case[0].startswith(f"{cmd}-") for case in CASES) for cmd in NESTED)
    known = {(cmd, _name(a)) for cmd in SWEEP_BASES for a in _sweep_actions(cmd)}
    assert set(PATHS) <= known and set(SUCCESSES) <= known and set(FAILURES) <= known
    total = sum(len(sweep_cases(cmd)) for cmd in SWEEP_BASES)
    assert total > 1000, total
