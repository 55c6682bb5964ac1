"""The command line: simulate, list, and one clear line with exit status 2 on bad input."""

from __future__ import annotations

import subprocess
import sys

import pandas as pd
import pytest

from nsbench.cli import main


def test_simulate_writes_the_event_log(tmp_path, capsys):
    out = tmp_path / "ev.csv"
    code = main(
        ["simulate", "two-dof", "--case", "2", "--integrator", "exact", "--t-end", "300", "--events-out", str(out)]
    )
    assert code == 0
    ev = pd.read_csv(out)
    assert list(ev.columns) == ["t", "kind", "block", "x1", "v1", "x2", "v2", "mode"]
    assert len(ev) > 100
    text = capsys.readouterr().out
    assert "stick@1" in text and "nfev=" in text and "wall time" in text


def test_simulate_trajectory_and_plot(tmp_path):
    traj, png = tmp_path / "tr.csv", tmp_path / "p.png"
    code = main(
        [
            "simulate",
            "one-dof",
            "--integrator",
            "henon-rk4",
            "--h",
            "0.02",
            "--t-end",
            "40",
            "--trajectory-out",
            str(traj),
            "--plot",
            str(png),
            "--samples",
            "401",
        ]
    )
    assert code == 0
    tr = pd.read_csv(traj)
    assert len(tr) == 401 and list(tr.columns) == ["t", "x1", "v1", "phase1"]
    assert png.stat().st_size > 10_000


def test_simulate_never_reports_success_over_a_stepped_over_crossing(capsys):
    """dop853 at its loosest level steps over block 1's stick near t = 25.68 on case 3 and the slip after
    it (the relative velocity dips across zero and back inside one step) when only its step ends are looked
    at (``test-dop853-unchecked``, a plug-in that declares no check of its steps). Without a trajectory
    asked for, the run used to say 'success' with 20 of the 22 events; the samples are always checked.
    ``scipy-dop853`` itself checks every step and finds the stick: 'success' on the right sequence."""
    import dataclasses

    from nsbench import get_problem, registry, simulate
    from nsbench.integrators.scipy_ import ScipyDOP853

    class Unchecked(ScipyDOP853):
        name = "test-dop853-unchecked"
        check_steps = False
        capabilities = dataclasses.replace(ScipyDOP853.capabilities, checks_steps=False)

    args = ["simulate", "two-dof", "--case", "3", "--rtol", "1e-6", "--atol", "1e-8", "--t-end", "40"]
    registry.register("integrators", Unchecked.name, Unchecked)
    try:
        code = main([*args, "--integrator", Unchecked.name])
    finally:
        registry.unregister("integrators", Unchecked.name)
    out, err = capsys.readouterr()
    assert code == 1 and "status      event missed: a guard of mode slip-|slip- was on its wrong side" in out
    assert err.startswith("nsbench: simulate: the run ended at t = ") and "event missed" in err
    t_final = float(out.split("t_final")[1].split()[0])
    # the flag is true: a run six orders tighter has a stick of block 1 before the reported time, after the
    # last event the loose run found
    problem = get_problem("two-dof", case=3)
    loose = simulate(problem, Unchecked(rtol=1e-6, atol=1e-8), 40.0, check_points=3001)
    tight = simulate(problem, "scipy-dop853", 40.0, options={"rtol": 1e-12, "atol": 1e-14}).events
    assert loose.status.value == "event missed" and loose.t_final == pytest.approx(t_final, abs=1e-4)
    between = tight[(tight["t"] > loose.events["t"].iloc[-1]) & (tight["t"] <= t_final)]
    assert ("stick", 1) in list(zip(between["kind"], between["block"]))
    # the built-in dop853 checks each of its steps: the same loose run locates the stick and ends on the
    # tight run's events
    code = main([*args, "--integrator", "scipy-dop853"])
    out = capsys.readouterr().out
    assert code == 0 and "status      success" in out and f"events      {len(tight)} (" in out


def test_simulate_dimensional_units(tmp_path):
    out = tmp_path / "ev.csv"
    code = main(
        [
            "simulate",
            "two-dof",
            "--case",
            "1",
            "--dimensional",
            "--param",
            "m1=4",
            "--param",
            "k1=1",
            "--t-end",
            "100",
            "--events-out",
            str(out),
        ]
    )
    assert code == 0
    ev = pd.read_csv(out)
    assert ev["t"].max() > 50  # seconds, not tau = t / 2


@pytest.mark.parametrize(
    "argv, fragment",
    [
        (["simulate", "three-dof"], "unknown problem 'three-dof'"),
        (["simulate", "two-dof", "--integrator", "rk99"], "unknown integrator 'rk99'"),
        (["simulate", "two-dof", "--param", "zeta=1"], "unknown parameter 'zeta'"),
        (["simulate", "two-dof", "--param", "c1=-1"], "c1 = -1 is out of range"),
        (["simulate", "two-dof", "--param", "c1"], "--param expects NAME=VALUE"),
        (["simulate", "two-dof", "--param", "v0=abc"], "v0 = 'abc' is not a number"),
        (["simulate", "two-dof", "--dimensional", "--param", "fs1=3"], "fs1 must be <= static friction"),
        (["simulate", "two-dof", "--case", "9"], "unknown case '9'"),
        (["simulate", "two-dof", "--case", "3", "--integrator", "exact"], "linear problems only"),
        (["simulate", "two-dof", "--integrator", "exact", "--h", "0.1"], "unknown option 'h'"),
        (["simulate", "two-dof", "--t-end", "-5"], "must be greater than t0"),
        (["simulate", "two-dof", "--param", "m1=nan", "--dimensional"], "m1 = nan is not allowed"),
    ],
)
def test_bad_input_exits_2_with_one_line(argv, fragment, capsys):
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("nsbench: error: ")
    assert fragment in err


def test_console_script_has_no_traceback_on_bad_input():
    out = subprocess.run(
        [sys.executable, "-m", "nsbench", "simulate", "two-dof", "--case", "0"], capture_output=True, text=True
    )
    assert out.returncode == 2
    assert "Traceback" not in out.stderr and "unknown case" in out.stderr


def test_list(capsys):
    assert main(["list", "integrators"]) == 0
    text = capsys.readouterr().out
    for name in ("exact", "scipy-dop853", "henon-rk4", "scipy-lsoda"):
        assert name in text
    assert main(["list"]) == 0
    assert "two-dof" in capsys.readouterr().out


def test_list_gives_whole_summaries_and_true_capabilities(capsys):
    from nsbench.cli.listing import summary

    class Plugin:
        """A method whose summary ``spans``
        two lines.

        Details that are not part of the summary.
        """

    assert summary(Plugin) == "A method whose summary spans two lines."
    assert main(["list", "integrators"]) == 0
    lines = {line.split()[0]: line for line in capsys.readouterr().out.splitlines()[1:]}
    assert "closed form" in lines["exact"] and "fixed-step" not in lines["exact"]
    assert "reference-grade" in lines["exact"] and "fixed-step" in lines["henon-rk4"]
    assert "``" not in "".join(lines.values())
