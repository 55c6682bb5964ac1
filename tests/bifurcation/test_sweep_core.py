"""Sweep points through the hybrid core: the same points as ``simulate``, any number of blocks.

A sweep point is one run of the core with a stop rule (``k``-th peak, ``k``-th
slip or stick event, last stroboscopic time). The same run without the stop,
through ``nsbench.simulate``, records the same points: the two use the same
compiled arithmetic, so they agree to rounding (1e-11 leaves room for the
compensated time split, which ``simulate`` rounds once more).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import nsbench
from nsbench import registry
from nsbench.bifurcation.parallel import run_sweep
from nsbench.bifurcation.storage import SweepStore
from nsbench.bifurcation.sweep import SweepSpec, compute_point
from nsbench.integrators.scipy_ import ScipyDOP853
from nsbench.problems.oscillator import Coefficients, FrictionOscillator, Scales
from nsbench.sections import peaks, stroboscopic

STATES = ["x1", "v1", "x2", "v2"]


def _spec(**kw) -> SweepSpec:
    base = dict(
        problem="two-dof",
        case=1,
        name="v0",
        start=0.1,
        stop=0.1,
        count=1,
        integrator="exact",
        transient=100.0,
        record=30,
    )
    return SweepSpec(**{**base, **kw})


def test_peaks_and_mapping_points_are_those_of_simulate():
    p = nsbench.get_problem("two-dof", case=1, v0=0.1)
    ref = nsbench.simulate(p, "exact", 400.0, sections=[peaks(p)])
    got = compute_point(_spec(section="peaks"), 0)
    want = ref.sections[ref.sections["t"] >= 100.0].iloc[:30]
    assert (got["status"] == "success").all() and len(got) == 30
    assert np.abs(want["t"].to_numpy() - got["t"].to_numpy()).max() < 1e-11
    assert np.abs(want[STATES].to_numpy() - got[STATES].to_numpy()).max() < 1e-11

    got = compute_point(_spec(section="mapping"), 0)
    ev = ref.events[ref.events["t"] >= 100.0]
    slips = ev[ev["kind"] == "slip"].iloc[:30]
    assert np.abs(slips["t"].to_numpy() - got["t"].to_numpy()).max() < 1e-11
    assert (slips["block"].to_numpy() == got["event_block"].to_numpy()).all()
    # the counters cover the recording window: from the transient to the last point
    window = ev[ev["t"] <= got["t"].iloc[-1]]
    first = got.iloc[0]
    assert first["slips1"] + first["slips2"] == 30
    for b in (1, 2):
        assert first[f"sticks{b}"] == int(((window["kind"] == "stick") & (window["block"] == b)).sum())


def test_stroboscopic_states_are_those_of_simulate():
    p = nsbench.get_problem("two-dof", case=2)
    spec = SweepSpec(
        problem="two-dof",
        case=2,
        name="F",
        start=5 / 12,
        stop=5 / 12,
        count=1,
        integrator="exact",
        section="strobe",
        transient=100.0,
        record=20,
    )
    got = compute_point(spec, 0)
    period = 2 * np.pi / p.coefficients.w
    ref = nsbench.simulate(p, "exact", float(got["t"].iloc[-1]) + 1.0, sections=[stroboscopic(p)])
    want = ref.sections[ref.sections["t"] >= got["t"].iloc[0] - 1e-9].iloc[:20]
    assert np.allclose(np.diff(got["t"].to_numpy()), period, rtol=0, atol=1e-9)
    assert np.abs(want[STATES].to_numpy() - got[STATES].to_numpy()).max() < 1e-11


@pytest.mark.parametrize("alias, name", [("exact-jit", "exact"), ("henon-rk4-jit", "henon-rk4")])
def test_old_compiled_names_are_aliases(alias, name):
    spec = dict(section="peaks", record=10)
    a = compute_point(_spec(integrator=alias, **spec), 0).drop(columns="wall_time")
    b = compute_point(_spec(integrator=name, **spec), 0).drop(columns="wall_time")
    assert a.equals(b)


def test_rk4_on_cubic_against_a_finer_step():
    # independent accuracy check: h = 0.02 against h = 0.0025 (order 4: ~4000x smaller error)
    spec = dict(
        problem="two-dof",
        case=3,
        name="h1",
        start=0.576,
        stop=0.576,
        count=1,
        integrator="henon-rk4",
        section="peaks",
        transient=50.0,
        record=10,
    )
    coarse = compute_point(SweepSpec(**spec, options={"h": 0.02}), 0)
    fine = compute_point(SweepSpec(**spec, options={"h": 0.0025}), 0)
    assert np.abs(coarse["t"].to_numpy() - fine["t"].to_numpy()).max() < 1e-5


def _three_blocks(case=None, dimensional=False, F: float = 0.3) -> FrictionOscillator:
    """A chain of three blocks (block 1 to the ground, each to the previous), forced on the last."""
    c = Coefficients(
        m=(1.0, 0.8, 1.2),
        c=(0.05, 0.04, 0.06),
        k=(1.0, 1.3, 0.7),
        h=(0.0, 0.0, 0.0),
        fs=(5 / 6, 0.7, 0.9),
        fr=(1.0, 0.9, 1.1),
        F=float(F),
        w=0.9,
        v0=1 / 12,
    )
    return FrictionOscillator(
        c, name="three-blocks", case=None, dimensional=False, params={"F": float(F)}, parameters={}, scales=Scales()
    )


@pytest.fixture
def three_blocks():
    registry.register("problems", "three-blocks", _three_blocks)
    yield "three-blocks"
    registry.unregister("problems", "three-blocks")


def test_a_three_block_problem_sweeps(three_blocks, tmp_path):
    spec = SweepSpec(
        problem=three_blocks,
        case=None,
        name="F",
        start=0.2,
        stop=0.4,
        count=3,
        integrator="exact",
        section="strobe",
        transient=60.0,
        record=5,
    )
    frame = run_sweep(spec, tmp_path / "s", workers=1, progress=False)
    names = ["x1", "v1", "x2", "v2", "x3", "v3"]
    assert list(SweepStore(tmp_path / "s").state_names) == names
    for col in (*names, "sticks3", "slips3", "reverses3"):
        assert col in frame.columns
    assert (frame["status"] == "success").all() and len(frame) == 15
    # each point is the state of the same run through simulate at that stroboscopic time
    p = _three_blocks(F=0.4)
    last = frame[frame["index"] == 2]
    times = last["t"].to_numpy()
    ref = nsbench.simulate(p, "exact", float(times[-1]) + 1.0, t_eval=times)
    assert np.abs(ref.trajectory[names].to_numpy() - last[names].to_numpy(float)).max() < 1e-11


def test_locus_of_a_chosen_pair_of_blocks(tmp_path):
    from nsbench.bifurcation import figures
    from nsbench.bifurcation.locus import locus_run
    from nsbench.errors import ConfigError

    p = _three_blocks()
    run = locus_run(p, transient=60.0, duration=40.0, pair=(1, 3))
    assert run.pair == (1, 3) and run.integrator == "exact"
    for seg in run.sticking_segments(3):  # polylines in the (x1, x3) plane
        assert seg.shape[1] == 2
    paths = figures.locus(run, tmp_path / "locus", formats=("png",))
    assert paths[0].read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    with pytest.raises(ConfigError, match="pair"):
        locus_run(p, transient=1.0, duration=1.0, pair=(2, 2))


class _UncheckedDop853(ScipyDOP853):
    """``scipy-dop853`` as ``solve_ivp`` runs it: it declares no check of its own steps."""

    name = "test-sweep-dop853-unchecked"
    check_steps = False
    capabilities = dataclasses.replace(ScipyDOP853.capabilities, checks_steps=False)


@pytest.fixture
def unchecked():
    registry.register("integrators", _UncheckedDop853.name, _UncheckedDop853)
    yield _UncheckedDop853.name
    registry.unregister("integrators", _UncheckedDop853.name)


def test_a_sweep_value_that_steps_over_a_crossing_is_a_failure_not_a_result(unchecked):
    """Loose dop853 steps over block 1's stick near t = 25.68 of 2-DOF case 3 (tests/test_engine.py). A sweep
    value runs through the engine with simulate's check: the integrator's own per-step check, or, for
    one without it, simulate's check points; a value that fails it has its status and no point."""
    loose = {"rtol": 1e-6, "atol": 1e-8}
    v0 = nsbench.get_problem("two-dof", case=3).v0  # the case's own value: the run of tests/test_engine.py
    spec = _spec(case=3, name="v0", start=v0, stop=v0, section="stick", transient=0.0, record=50, window=40.0)
    bad = compute_point(dataclasses.replace(spec, integrator=unchecked, options=loose), 0)
    assert list(bad["status"]) == ["event missed"] and int(bad["n_points"].iloc[0]) == 0
    assert "stopped at t = " in bad["message"].iloc[0] and np.isnan(bad["t"]).all()
    # dop853 itself checks its steps: the same value, the stick times of exact to the loose tolerance
    good = compute_point(dataclasses.replace(spec, integrator="scipy-dop853", options=loose), 0)
    ref = nsbench.simulate(nsbench.get_problem("two-dof", case=3), "reference", 40.0).events
    sticks = ref[ref["kind"] == "stick"]
    assert set(good["status"]) == {"incomplete"}  # fewer than 50 sticks by t = 40: every one recorded
    np.testing.assert_array_equal(good["event_block"].to_numpy(), sticks["block"].to_numpy())
    assert np.abs(good["t"].to_numpy() - sticks["t"].to_numpy()).max() < 1e-4  # rtol 1e-6 over t <= 40
