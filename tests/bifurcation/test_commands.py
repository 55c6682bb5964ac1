"""The sweep and continuation commands as Python functions: a request, checked once, and one call.

:func:`nsbench.bifurcation.sweep_command.run_sweeps` and
:func:`nsbench.bifurcation.continuation_command.run_continuation` are what ``nsbench bifurcation``
and ``nsbench continuation`` run; here they run without the command line, and their outcomes are
read against the files they wrote.
"""

from __future__ import annotations

import dataclasses
import json

import pandas as pd
import pytest

from nsbench.bifurcation.request import ContinuationRequest, SweepRequest
from nsbench.errors import ConfigError


def test_a_sweep_runs_from_python_and_its_outcome_is_what_it_wrote(tmp_path, capsys):
    from nsbench.bifurcation.sweep_command import run_sweeps

    request = SweepRequest(
        problem="two-dof",
        sweep="v0=0.1:0.2:6",
        transient=300,
        record=20,
        workers=1,
        out=str(tmp_path / "sweep"),
        formats=("png",),
        progress=False,
    )
    outcome = run_sweeps(request)
    assert outcome.failure is None and outcome.exit_code == 0
    assert outcome.folder == tmp_path / "sweep" and outcome.comparison is None
    (sweep,) = outcome.sweeps
    assert sweep.integrator == "exact"  # the default of a linear problem
    assert sweep.values == 6 and sweep.failed == 0
    # the outcome's tables are the files written
    feats = pd.read_csv(outcome.folder / "features.csv")
    assert len(feats) == 6 and list(feats.columns) == list(sweep.features.columns)
    assert feats["value"].tolist() == pytest.approx(sweep.features["value"].tolist())
    assert len(pd.read_csv(outcome.folder / "candidates.csv")) == len(sweep.candidates)
    assert sweep.diagram == (outcome.folder / "diagram.png",) and sweep.diagram[0].stat().st_size > 1000
    assert sorted(sweep.points["index"].unique()) == list(range(6))
    assert f"exact: 6 values (0 failed or incomplete) in {sweep.seconds:.1f} s" in capsys.readouterr().out


def test_a_continuation_runs_from_python_and_its_outcome_is_what_it_wrote(tmp_path):
    from nsbench.bifurcation.continuation_command import run_continuation

    request = ContinuationRequest(
        problem="two-dof", sweep=("v0", 0.16, 0.17), steps=2, out=str(tmp_path / "c"), formats="png", progress=False
    )
    outcome = run_continuation(request)
    assert outcome.failure is None and outcome.exit_code == 0 and outcome.folder == tmp_path / "c"
    assert outcome.integrator == "exact" and outcome.result is not None and outcome.result.branches
    branch = pd.read_csv(outcome.folder / "branch.csv")
    assert len(branch) == sum(len(b.values) for b in outcome.result.branches)
    assert branch["value"].min() == pytest.approx(0.16) and branch["value"].max() == pytest.approx(0.17)
    assert json.loads((outcome.folder / "meta.json").read_text())["steps"] == 2
    assert outcome.files["branch"] == outcome.folder / "branch.csv"
    assert outcome.figure == (outcome.folder / "branches.png",) and outcome.figure[0].stat().st_size > 0


def test_a_request_is_parsed_once_from_text_or_from_values():
    text = SweepRequest(
        problem="two-dof",
        sweep="v0=0.1:0.2:6",
        case="2",
        record="20",
        transient="3e2",
        options=["tol=1e-9"],
        h="0.01",
        portraits=("0.15",),
        pair="1,2",
        formats="png, svg",
        workers="1",
    )
    values = SweepRequest(
        problem="two-dof",
        sweep=("v0", 0.1, 0.2, 6),
        case=2,
        record=20,
        transient=300.0,
        options={"tol": 1e-9, "h": 0.01},
        portraits=(0.15,),
        pair=(1, 2),
        formats=("png", "svg"),
        workers=1,
    )
    assert text == values and text.h is None  # --h is folded into the options
    assert dataclasses.replace(text) == text  # a parsed request reads the same again
    cont = ContinuationRequest(problem="relay-feedback", sweep="k=0.5:0.6", case="A", steps="1e2")
    assert cont.case == "A" and cont.steps == 100 and cont.sweep == ("k", 0.5, 0.6)
    assert dataclasses.replace(cont) == cont


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"record": 0}, "--record = 0 must be >= 1"),
        ({"record": "1e12"}, "MAX_RECORD"),
        ({"transient": float("inf")}, "--transient = inf must be a finite number"),
        ({"case": 1.5}, "--case = '1.5' must be a case number"),
        ({"sweep": "n=1:4:4"}, "the number of blocks n cannot be swept"),
        ({"options": {"tol": float("nan")}}, "an option value must be a finite number"),
        ({"options": {"h": 0.1}, "h": 0.1}, "--h and --option h=... are both given"),
        ({"pair": (2, 2)}, "two different blocks"),
        ({"integrators": ("exact", "exact")}, "--integrator exact is given twice"),
        ({"formats": "png,bmpx"}, "--formats: bmpx not allowed"),
        ({"workers": 0}, "--workers = 0 must be >= 1"),
    ],
)
def test_a_bad_sweep_request_is_refused_at_its_construction(kwargs, message):
    with pytest.raises(ConfigError) as info:
        SweepRequest(**{"problem": "two-dof", "sweep": "v0=0.1:0.2:6", **kwargs})
    assert message in str(info.value)


@pytest.mark.parametrize(
    "argv, default",
    [
        (
            ["bifurcation", "two-dof", "--sweep", "v0=0.1:0.2:6"],
            SweepRequest(problem="two-dof", sweep="v0=0.1:0.2:6"),
        ),
        (
            ["continuation", "two-dof", "--sweep", "v0=0.2:0.28"],
            ContinuationRequest(problem="two-dof", sweep="v0=0.2:0.28"),
        ),
    ],
)
def test_the_command_lines_defaults_are_the_requests(argv, default):
    # the parser writes its defaults as text (its --help shows them); they read as the request's own
    import importlib

    from nsbench.cli import build_parser

    args = build_parser(argv[0]).parse_args(argv)
    assert importlib.import_module(f"nsbench.cli.{argv[0]}").request(args) == default


def test_a_lyapunov_estimate_runs_from_python_as_the_command_runs_it(tmp_path, capsys):
    # the same members, seed and integrator: the same estimate as largest_exponent called directly
    from nsbench.bifurcation.lyapunov import largest_exponent
    from nsbench.bifurcation.lyapunov_command import run_lyapunov
    from nsbench.bifurcation.request import LyapunovRequest
    from nsbench.problems import get_problem

    out = tmp_path / "logs.csv"
    request = LyapunovRequest(
        problem="two-dof", case="1", params={"v0": 0.1}, iterations="200", members="4", seed="3", out=str(out)
    )
    outcome = run_lyapunov(request)
    assert outcome.failure is None and outcome.exit_code == 0 and outcome.result is not None
    direct = largest_exponent(get_problem("two-dof", case=1, v0=0.1), "exact", iterations=200, members=4, seed=3)
    assert outcome.result.exponent == direct.exponent  # deterministic: seeded members on a linear case
    logs = pd.read_csv(out)
    assert len(logs) == 200 and logs["log_growth"].tolist() == pytest.approx(direct.logs.ravel().tolist())
    assert f"log growth per member and iteration -> {out}" in capsys.readouterr().out


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"members": 2}, "--members = 2 must be >= 4"),
        ({"iterations": "1e4.5"}, "--iterations"),
        ({"seed": 0.5}, "--seed"),
        ({"d0": 0.5}, "--d0"),
        ({"h": 0}, "--h = 0"),
        ({"member_limit": -1}, "--member-limit"),
        ({"transient": float("inf")}, "--transient = inf must be a finite number"),
    ],
)
def test_a_bad_lyapunov_request_is_refused_at_its_construction(kwargs, message):
    from nsbench.bifurcation.request import LyapunovRequest

    with pytest.raises(ConfigError) as info:
        LyapunovRequest(**{"problem": "two-dof", **kwargs})
    assert message in str(info.value)


def test_the_lyapunov_command_lines_defaults_are_the_requests():
    from nsbench.bifurcation.request import LyapunovRequest
    from nsbench.cli import build_parser
    from nsbench.cli.lyapunov import request

    args = build_parser("lyapunov").parse_args(["lyapunov", "two-dof", "--case", "1"])
    assert request(args) == LyapunovRequest(problem="two-dof", case="1")
    assert LyapunovRequest(problem="two-dof", h="0.01").options == {"h": 0.01}
