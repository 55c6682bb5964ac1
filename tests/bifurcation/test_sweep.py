"""Sweeps: the tidy frame, the engine path against the compiled path, resume after interruption."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import nsbench
from nsbench.bifurcation.parallel import run_sweep
from nsbench.bifurcation.storage import SweepStore
from nsbench.bifurcation.sweep import SweepSpec, parse_sweep, strobe_times
from nsbench.errors import ConfigError
from nsbench.sections import peaks

SMALL = dict(problem="two-dof", case=1, name="v0", start=0.06, stop=0.2, count=6, transient=200.0, record=12)


def test_small_sweep_with_exact(tmp_path):
    spec = SweepSpec(integrator="exact", **SMALL)
    frame = run_sweep(spec, tmp_path / "s", workers=1, progress=False)
    assert list(frame.columns) == list(spec.columns)
    assert "x2" in spec.columns and "sticks2" in spec.columns and "x3" not in spec.columns
    assert sorted(frame["index"].unique()) == list(range(6))
    assert (frame["status"] == "success").all()
    assert (frame.groupby("index").size() == 12).all()
    # every recorded peak is a peak of an independent engine run, after the transient
    v = float(spec.values[2])
    p = nsbench.get_problem("two-dof", case=1, v0=v)
    ref = nsbench.simulate(p, "exact", 400.0, sections=[peaks(p)]).sections
    ref = ref[ref["t"] >= 200.0].iloc[:12]
    got = frame[frame["index"] == 2]
    np.testing.assert_allclose(got["t"], ref["t"], rtol=0, atol=1e-12)
    np.testing.assert_allclose(got["x1"], ref["x1"], rtol=0, atol=1e-12)
    assert (got["v1"].abs() < 1e-9).all()  # peaks: v1 = 0


def test_a_sweep_with_python_arcs_agrees_with_exact(tmp_path):
    # scipy's DOP853 has no compiled kernel: the core calls it once per arc. At rtol 1e-12
    # its peaks after tau = 200 are within ~1e-9 of the closed form (1e-7 leaves room)
    a = run_sweep(SweepSpec(integrator="exact", **SMALL), tmp_path / "a", workers=1, progress=False)
    b = run_sweep(
        SweepSpec(
            integrator="scipy-dop853",
            options={"rtol": 1e-12, "atol": 1e-14},
            **{**SMALL, "count": 3, "stop": SMALL["start"] + 2 * (SMALL["stop"] - SMALL["start"]) / 5},
        ),
        tmp_path / "b",
        workers=1,
        progress=False,
    )
    a = a[a["index"] < 3]
    assert np.abs(a["x1"].to_numpy() - b["x1"].to_numpy()).max() < 1e-7
    assert (a.groupby("index")["sticks1"].first() == b.groupby("index")["sticks1"].first()).all()


def test_resume_computes_only_missing_values(tmp_path):
    spec = SweepSpec(integrator="exact", **SMALL)
    out = tmp_path / "r"
    run_sweep(spec, out, workers=1, progress=False, limit=2, chunk_size=1)
    store = SweepStore(out)
    assert store.done() == {0, 1}
    first_files = {f.name: f.stat().st_mtime_ns for f in store.points_dir.glob("*.parquet")}
    full = run_sweep(spec, out, workers=1, progress=False, chunk_size=1)
    files = {f.name: f.stat().st_mtime_ns for f in store.points_dir.glob("*.parquet")}
    assert len(files) == 6 and all(files[k] == v for k, v in first_files.items())
    fresh = run_sweep(spec, tmp_path / "fresh", workers=1, progress=False)
    assert full.drop(columns="wall_time").equals(fresh.drop(columns="wall_time"))
    with pytest.raises(ConfigError, match="different sweep"):
        run_sweep(SweepSpec(integrator="exact", **{**SMALL, "count": 7}), out, workers=1, progress=False)


def test_killed_run_keeps_whole_chunks_and_resumes(tmp_path):
    # The kill must land part-way on any machine: wait (as long as a cold numba
    # compile may take) for two stored chunks of a sweep long enough that the rest
    # cannot finish in the moment between seeing them and the kill.
    out = tmp_path / "k"
    count = 400
    cmd = [
        sys.executable,
        "-m",
        "nsbench",
        "bifurcation",
        "two-dof",
        "--case",
        "1",
        "--sweep",
        f"v0=0.06:0.2:{count}",
        "--integrator",
        "exact",
        "--transient",
        "300",
        "--record",
        "10",
        "--workers",
        "1",
        "--out",
        str(out),
        "--formats",
        "png",
        "--no-progress",
    ]
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    while proc.poll() is None and len(list((out / "points").glob("*.parquet"))) < 2:
        time.sleep(0.01)
    assert proc.poll() is None, "the sweep ended before it could be killed"
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    store = SweepStore(out)
    done = store.done()
    assert 0 < len(done) < count  # killed part-way; what is stored is whole chunks
    assert (store.load().groupby("index").size() == 10).all()
    before = {f.name for f in store.points_dir.glob("*.parquet")}
    frame = run_sweep(store.spec, out, workers=1, progress=False)
    assert sorted(frame["index"].unique()) == list(range(count))
    new = {f.name for f in store.points_dir.glob("*.parquet")} - before
    recomputed = set()
    for name in new:
        recomputed |= set(pd.read_parquet(store.points_dir / name)["index"].tolist())
    assert recomputed == set(range(count)) - done


def test_failures_are_recorded_not_raised(tmp_path):
    # r_f = 1.05 is nonphysical (kinetic > static): the sweep refuses the range early
    with pytest.raises(ConfigError, match="r_f"):
        run_sweep(
            SweepSpec(**{**SMALL, "name": "r_f", "start": 0.5, "stop": 1.05}), tmp_path / "f", workers=1, progress=False
        )
    # a point whose run stops early is kept with its status and reason
    spec = SweepSpec(integrator="henon-rk4", options={"h": 0.02}, **{**SMALL, "count": 2, "window": 5.0})
    frame = run_sweep(spec, tmp_path / "g", workers=1, progress=False)
    assert (frame["status"] == "incomplete").all() and frame["message"].str.contains("points by").all()


@pytest.mark.parametrize("text", ["v0=0.1:0.2", "v0", "v0=a:b:3", "v0=0.1:0.2:0", "v0=0.1:0.2:2.5"])
def test_bad_sweep_text(text):
    with pytest.raises(ConfigError):
        parse_sweep(text)


def test_a_sweep_without_a_range_is_refused():
    # START = STOP used to run COUNT copies of one value
    with pytest.raises(ConfigError, match="START and STOP are equal"):
        parse_sweep("v0=0.1:0.1:50")
    with pytest.raises(ConfigError, match="values of a sweep would all be the same"):
        SweepSpec(**{**SMALL, "start": 0.1, "stop": 0.1})
    assert SweepSpec(**{**SMALL, "start": 0.1, "stop": 0.1, "count": 1}).values.tolist() == [0.1]  # one value
    for bad, fragment in (
        ({"count": 0}, "count = 0"),
        ({"count": 2.0}, "count = 2.0"),
        ({"start": float("nan")}, "start = nan"),
        ({"stop": "1"}, "stop = '1'"),
    ):
        with pytest.raises(ConfigError, match=fragment):
            SweepSpec(**{**SMALL, **bad})


def test_bad_section_for_unforced_problem(tmp_path):
    with pytest.raises(ConfigError, match="strobe"):
        run_sweep(SweepSpec(section="strobe", **SMALL), tmp_path / "x", workers=1, progress=False)


@pytest.mark.parametrize(
    "problem, name, integrator, section",
    [
        ("henon-heiles", "coupling", "henon-rk4", "peaks"),
        ("relay-feedback", "rho", "exact", "event:exit"),  # no position: the states where it leaves sliding
        ("impact-oscillator", "F", "exact", "strobe"),  # forced: the command's default section
    ],
)
def test_a_sweep_of_a_library_problem_records_its_sections_classifies_and_draws(
    tmp_path, problem, name, integrator, section
):
    # Problems whose states are not the blocks' x1, v1, ... (x, y, px, py; x1, x2, x3; x, v): the values
    # are recorded, the counters are those of the table, and the classification and the diagram use
    # the problem's own state variables (they used to fail on a missing x1 or sticks2).
    from nsbench.bifurcation import detect, figures

    start, stop = {"coupling": (0.9, 1.0), "rho": (0.1, 0.2), "F": (0.5, 0.6)}[name]
    spec = SweepSpec(
        problem=problem,
        case=1,
        name=name,
        start=start,
        stop=stop,
        count=3,
        integrator=integrator,
        section=section,
        transient=20.0,
        record=3,
    )
    frame = run_sweep(spec, tmp_path / "s", workers=1, progress=False)
    assert (frame["status"] == "success").all(), frame["message"].unique()
    # each value's points are the section's points after the transient in a run of its own
    p = spec.problem_at(float(spec.values[1]))
    if section == "peaks":
        ref = nsbench.simulate(p, integrator, 20.0 + spec.record_window, sections=[peaks(p)]).sections
    elif section.startswith("event:"):
        ref = nsbench.simulate(p, integrator, 20.0 + spec.record_window).events
        ref = ref[ref["kind"] == section[len("event:") :]]
    else:
        times = strobe_times(p, 20.0, 3)
        ref = nsbench.simulate(p, integrator, float(times[-1]), t_eval=times).trajectory
    ref = ref[ref["t"] >= 20.0].iloc[:3]
    got = frame[frame["index"] == 1]
    cols = ["t", *p.state_names]
    np.testing.assert_allclose(got[cols].to_numpy(), ref[cols].to_numpy(), rtol=0, atol=1e-12)
    feats = detect.classify(frame)
    assert len(feats) == 3 and (feats["period"] >= 0).all()
    written = figures.diagram(frame, tmp_path / "diagram", formats=("png",))
    assert written[0].stat().st_size > 0
    # the counters count the problem's stick, slip and reverse events by name: none here but the
    # impact oscillator's sticking to its wall
    counts = frame[[c for c in frame.columns if c.startswith(("sticks", "slips", "reverses"))]].to_numpy()
    kinds = {"stick", "slip", "reverse"} & set(p.event_kinds)
    assert (counts == 0).all() if not kinds else kinds == {"stick"}


def test_a_section_of_events_the_problem_does_not_have_is_refused(tmp_path):
    spec = SweepSpec(
        problem="henon-heiles",
        case=1,
        name="coupling",
        start=0.9,
        stop=1.0,
        count=3,
        section="mapping",
        integrator="reference",
    )
    with pytest.raises(ConfigError, match="section mapping records slip events; henon-heiles has none"):
        run_sweep(spec, tmp_path / "s", workers=1, progress=False)


@pytest.mark.parametrize("name", ["moreau-jean", "smoothing", "switch-model"])
def test_a_whole_system_method_is_refused_before_anything_runs(tmp_path, name):
    # A sweep's values are runs of the hybrid core, which runs event-driven integrators only: a
    # whole-system method would fail every value in the workers (as it did), so it is refused first.
    spec = SweepSpec(integrator=name, **SMALL)
    with pytest.raises(ConfigError, match=f"{name} is a whole-system method .*a sweep needs an event-driven"):
        run_sweep(spec, tmp_path / "s", workers=1, progress=False)
    assert not (tmp_path / "s").exists()


def test_chunk_files_are_written_atomically(tmp_path):
    spec = SweepSpec(**SMALL)
    store = SweepStore(tmp_path / "a", spec)
    (store.points_dir / "chunk-000000-dead.tmp").write_text("partial")
    assert store.done() == set()
    assert Path(tmp_path / "a" / "meta.json").exists()


def test_the_rows_a_store_wrote_are_its_table_and_a_replaced_chunk_is_read_again(tmp_path):
    # A store keeps the rows it wrote (checked as a read checks them) instead of reading its own chunks
    # back: its table must be a new reader's, bit for bit; a chunk replaced since is read again.
    spec = SweepSpec(**SMALL)
    out = tmp_path / "s"
    frame = run_sweep(spec, out, workers=1, progress=False)
    fresh = SweepStore(out).load()
    pd.testing.assert_frame_equal(frame, fresh, check_exact=True)
    store = SweepStore(out, spec)
    first = sorted(store.points_dir.glob("chunk-*.parquet"))[0]
    written = store.write(pd.read_parquet(first))
    assert written == first and written in store._checked  # the same rows: the same chunk, kept
    pd.testing.assert_frame_equal(store.load(), fresh, check_exact=True)
    data = bytearray(written.read_bytes())
    data[len(data) // 2] ^= 0xFF  # replaced behind the store's back: the same size, another time stamp
    written.write_bytes(bytes(data))
    os.utime(written, ns=(0, 0))
    with pytest.raises(ConfigError, match="damaged"):
        store.load()


def test_motion_at_rest_is_recorded_as_its_equilibrium(tmp_path):
    # past the pure-sliding threshold the motion damps out: RK4 settles on the equilibrium and
    # has no more peaks; the value is kept as status "rest" with its final state as one point.
    spec = SweepSpec(
        problem="two-dof",
        case=1,
        name="v0",
        start=0.21,
        stop=0.22,
        count=2,
        integrator="henon-rk4",
        transient=1500.0,
        record=20,
        window=200.0,
    )
    frame = run_sweep(spec, tmp_path / "rest", workers=1, progress=False)
    assert (frame["status"] == "rest").all() and (frame["n_points"] == 1).all()
    # both blocks slipping backwards (friction +r_f on each): x1 = 2 r_f, x2 = x1 + r_f / kappa
    r_f = 5.0 / 6.0
    np.testing.assert_allclose(frame["x1"], 2 * r_f, atol=1e-8)
    np.testing.assert_allclose(frame["x2"], 3 * r_f, atol=1e-8)


def test_strobe_sweep_of_the_force_amplitude_may_start_at_zero():
    from nsbench.bifurcation.sweep import default_section

    spec = SweepSpec(problem="two-dof", case=2, name="F", start=0.0, stop=0.2, count=3, section="strobe")
    spec.check()
    assert default_section(spec.problem_at(0.0), spec.problem_at(0.2)) == "strobe"
    assert default_section(spec.problem_at(0.0)) == "peaks"
    with pytest.raises(ConfigError, match="Omega > 0"):
        SweepSpec(problem="two-dof", case=2, name="Omega", start=0.0, stop=1.0, count=3, section="strobe").check()


@pytest.mark.parametrize(
    "problem, state, resting",
    [
        ("henon-heiles", [0.0, 0.0, 0.0, 0.0], True),  # its equilibrium
        ("henon-heiles", [0.1, 0.0, 0.0, 0.0], False),  # y and py are zero, but the force is not
        ("relay-feedback", [1.0, 0.0, 0.0], False),  # x2 is zero, the other rates are not
        ("two-dof", [1.7, 0.0, 2.5, 0.0], True),  # the friction rule: both blocks stand still
    ],
)
def test_at_rest_means_an_equilibrium_of_the_problems_own_field(problem, state, resting):
    from nsbench.bifurcation.sweep import at_rest
    from nsbench.problems import get_problem

    p = get_problem(problem)
    assert at_rest(p, (0,) * p.mode_size, 0.0, np.array(state)) is resting


def test_event_sections_are_the_problems_own_kinds_and_peaks_need_a_position():
    relay = dict(problem="relay-feedback", case=1, name="rho", start=0.1, stop=0.2, count=2, integrator="exact")
    with pytest.raises(ConfigError, match="use section event:cross or event:slide or event:exit or event:touch"):
        SweepSpec(**relay, section="peaks").check()
    with pytest.raises(ConfigError, match="section event:stick records stick events; relay-feedback has none"):
        SweepSpec(**relay, section="event:stick").check()
    SweepSpec(**relay, section="event:exit").check()
    for bad in ("event:", "event: ", "impacts"):
        with pytest.raises(ConfigError, match="or event:KIND"):
            SweepSpec(**relay, section=bad)
