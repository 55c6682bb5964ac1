"""``nsbench check``: the conformance table and its exit status."""

from __future__ import annotations

from nsbench import registry
from nsbench.cli import main
from tests.testing.test_conformance import LateEvents


def test_check_prints_a_table_and_passes(capsys):
    assert main(["check", "exact"]) == 0
    out = capsys.readouterr().out
    assert "conformance of exact" in out
    for line in ("protocol", "event-times", "config-round-trip"):
        assert any(row.split()[:2] == [line, "PASSED"] for row in out.splitlines())
    assert "convergence          SKIPPED" in out and "no step or tolerance option declared" in out
    assert "14 checks:" in out
    # the first-call flag's line, measured before the checks (exact compiles in setup: times only, no FLAG
    # asserted either way, since a ratio of wall times is no test's business)
    assert "  first call: setup " in out or "  FLAG first call: setup " in out


def test_check_exit_status_is_nonzero_on_failure(capsys):
    registry.register("integrators", "test-late-events", LateEvents)
    try:
        assert main(["check", "test-late-events", "--check", "event-times", "--check", "protocol"]) == 1
    finally:
        registry.unregister("integrators", "test-late-events")
    out = capsys.readouterr().out
    assert "event-times  FAILED" in out and "event times differ from exact" in out
    assert "protocol     PASSED" in out


def test_check_options_and_bad_input(capsys):
    assert main(["check", "henon-rk4", "--option", "h=0.02", "--check", "config-round-trip"]) == 0
    assert "{'h': 0.02}" in capsys.readouterr().out
    assert main(["check", "henon-rk5"]) == 2
    assert "did you mean 'henon-rk4'" in capsys.readouterr().err
    assert main(["check", "exact", "--check", "no-such-check"]) == 2
    assert main(["check", "exact", "--option", "scan=-1"]) == 2


def test_every_registered_integrator_runs_by_name_from_the_cli(capsys):
    from nsbench import list_integrators, registry
    from nsbench.errors import UnsupportedProblemError
    from nsbench.problems import get_problem

    for name in list_integrators():
        cls = registry.load("integrators", name)
        if getattr(cls, "unavailable", lambda: None)():
            continue  # an external engine that is not installed (listed as unavailable, with its reason)
        # the first problem it accepts: an engine with one friction level and no forcing (siconos-moreau-jean)
        # runs the block on the ground, Siconos's event-driven scheme the bouncing ball only
        for argv in (["two-dof", "--case", "2"], ["block-on-ground"], ["bouncing-ball"]):
            try:
                cls().check_problem(get_problem(*argv[:1], **({"case": 2} if len(argv) > 1 else {})))
                break
            except UnsupportedProblemError:
                continue
        assert main(["simulate", *argv, "--integrator", name, "--t-end", "20"]) == 0, name
        out = capsys.readouterr().out
        assert f"integrator  {name}" in out and "status      success" in out


def test_an_option_is_used_by_the_accuracy_checks(capsys):
    """``--option h=0.5`` is what event-times runs (RK4 at 50 times its default step: about 2e-2 off)."""
    assert main(["check", "henon-rk4", "--option", "h=0.5", "--check", "event-times"]) == 1
    out = capsys.readouterr().out
    assert "  event-times at h=0.5 (the options given)" in out
    row = next(line for line in out.splitlines() if line.split()[:2] == ["event-times", "FAILED"])
    assert "at h=0.5 (the options given): event times differ from exact by" in row and row.endswith("> 1e-05")
    assert main(["check", "henon-rk4", "--check", "event-times"]) == 0
    assert "event-times at h=0.0025 (middle accuracy level, 3 of 4)" in capsys.readouterr().out


def test_non_finite_and_repeated_options_are_refused(capsys):
    for argv, fragment in (
        (["--option", "h=inf"], "--option h=inf: an option value must be a finite number"),
        (["--option", "h=nan"], "must be a finite number"),
        (["--option", "h=1" + "0" * 400], "must be a finite number"),
        (["--option", "h=0.1", "--option", "h=0.2"], "--option h is given twice"),
    ):
        assert main(["check", "henon-rk4", *argv]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and fragment in err, err


def test_a_named_preset_is_taken_by_param(capsys):
    """``--param case=leine`` (a preset with a name, not a number) reaches the problem; the kit checks
    Leine's belt oscillator as given, and the belt-only checks say why they skip."""
    assert (
        main(
            [
                "check",
                "henon-rk4",
                "--problem",
                "one-dof",
                "--param",
                "case=leine",
                "--check",
                "event-times",
                "--check",
                "stuck-stays-stuck",
            ]
        )
        == 0
    )
    out = capsys.readouterr().out
    assert "on {'name': 'one-dof', 'case': 'leine'}" in out
    assert any(row.split()[:2] == ["event-times", "PASSED"] for row in out.splitlines())
    assert "one-dof (case='leine') runs as given" in out
    # a numbered preset is still the kit's to choose on the Coulomb belt, and a bad name is named
    assert main(["check", "exact", "--problem", "one-dof", "--param", "case=2"]) == 2
    assert "the checks choose the case" in capsys.readouterr().err
    assert main(["check", "exact", "--problem", "one-dof", "--param", "case=lein"]) == 2
    assert "lein" in capsys.readouterr().err


def test_a_check_run_in_which_nothing_applicable_ran_exits_1_and_says_so(capsys):
    # exact refuses the Henon-Heiles system at setup (not piecewise linear): every check that runs it is
    # skipped, only the configuration checks pass, and a CI gate must not read that as a pass
    assert main(["check", "exact", "--problem", "henon-heiles"]) == 1
    out = capsys.readouterr().out
    assert "nothing applicable ran" in out and "exact on henon-heiles was skipped" in out
    assert "config-round-trip    PASSED" in out
    # asking only for a configuration check is not a run in which something applicable was skipped
    assert main(["check", "exact", "--problem", "henon-heiles", "--check", "config-round-trip"]) == 0
