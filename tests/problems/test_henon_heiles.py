"""``henon-heiles``: the Poincare section as events, against heyoka's own benchmark set-up and the energy."""

from __future__ import annotations

import numpy as np
import pytest

import nsbench
from nsbench.errors import ConfigError, UnsupportedProblemError

SPAN = 200.0  # about 60 crossings of x = 0 (heyoka's benchmark runs to 2000: docs/problems.md)


def test_the_default_start_is_heyokas_benchmark_start():
    from nsbench.problems.henon_heiles import HEYOKA_START

    p = nsbench.get_problem("henon-heiles")
    assert p.initial_state().tolist() == [0.0, 0.2587703282931232, -0.2525875586263492, -0.2178423952983717]
    assert HEYOKA_START["x0"] == 0.0
    assert p.energy(p.initial_state()) == pytest.approx(1.0 / 12.0, abs=1e-6)  # the energy of the benchmark


def test_the_section_equals_heyokas_own_event_detection():
    # heyoka's benchmark, written out with heyoka directly (no nsbench code): x' = vx, ..., a non-terminal
    # event on x increasing through 0, tolerance 1e-15 (benchmark/hh_event.cpp of bluescarni/heyoka)
    import heyoka as hy

    vx, vy, x, y = hy.make_vars("vx", "vy", "x", "y")
    times = []
    ev = hy.nt_event(x, lambda ta, t, d_sgn: times.append(t), direction=hy.event_direction.positive)
    ta = hy.taylor_adaptive(
        [(vx, -x - 2.0 * x * y), (vy, y * y - y - x * x), (x, vx), (y, vy)],
        [-0.2525875586263492, -0.2178423952983717, 0.0, 0.2587703282931232],
        tol=1e-15,
        nt_events=[ev],
    )
    ta.propagate_until(SPAN)
    p = nsbench.get_problem("henon-heiles")
    res = nsbench.simulate(p, "reference", SPAN)
    sections = res.events[res.events["kind"] == "section"]["t"].to_numpy()
    assert len(sections) == len(times) >= 25
    # heyoka at 1e-15 in double against the quad-precision reference: the benchmark's own accuracy
    np.testing.assert_allclose(sections, times, rtol=0, atol=1e-11)
    assert np.all(res.events[res.events["kind"] == "section"]["px"] > 0)


def test_the_reference_keeps_the_energy_at_every_event():
    p = nsbench.get_problem("henon-heiles")
    res = nsbench.simulate(p, "reference", SPAN)
    h0 = p.energy(p.initial_state())
    states = res.events[["x", "y", "px", "py"]].to_numpy().T
    # quad precision: the energy moves by the rounding of the states to double (a few 1e-17)
    assert np.abs(p.energy(states) - h0).max() <= 1e-15
    assert (res.events["x"] == 0.0).mean() < 1.0 and np.abs(res.events["x"]).max() <= 1e-16


@pytest.mark.parametrize(
    "name, options, bound",
    [
        ("heyoka", {"tol": 1e-15}, 1e-11),
        ("ofapi", {}, 1e-9),
        ("scipy-dop853", {}, 1e-5),
        ("henon-rk4", {"h": 0.01}, 1e-6),
    ],
)
def test_other_integrators_find_the_same_dozens_of_crossings(name, options, bound):
    p = nsbench.get_problem("henon-heiles")
    ref = nsbench.simulate(p, "reference", SPAN).events
    res = nsbench.simulate(p, nsbench.get_integrator(name, **options), SPAN)
    assert res.ok, res.message
    assert list(res.events["kind"]) == list(ref["kind"]) and len(ref) >= 50
    assert np.abs(res.events["t"].to_numpy() - ref["t"].to_numpy()).max() <= bound


@pytest.mark.parametrize(
    "params, message", [({"mass": 1}, "unknown parameter 'mass'"), ({"y0": float("nan")}, "finite")]
)
def test_bad_parameters_are_refused(params, message):
    with pytest.raises(ConfigError, match=message):
        nsbench.get_problem("henon-heiles", **params)


def test_integrators_without_a_form_for_it_refuse_at_setup():
    p = nsbench.get_problem("henon-heiles")
    for name in ("exact", "exact-mp"):
        with pytest.raises(UnsupportedProblemError, match="linear problems only"):
            nsbench.get_integrator(name).setup(p)
    for name in ("cvode-bdf", "ida"):
        with pytest.raises(
            UnsupportedProblemError, match=r"blocks on a belt \(the friction oscillators' formulation\) only"
        ):
            nsbench.get_integrator(name).setup(p)


def test_the_bench_certifies_the_quad_reference_per_event():
    from nsbench.bench.reference import candidates, compute_reference

    p = nsbench.get_problem("henon-heiles")
    ref = compute_reference(p.config(), candidates(["exact", "reference"]), 0.0, SPAN, 10)
    # exact refuses (not piecewise linear): reference (heyoka-q), checked by heyoka-q at tol 1e-30
    assert ref.ok and ref.name == "reference" and "heyoka-q" in ref.certify_note
    assert len(ref.events) >= 50 and ref.certainty <= 1e-13


def test_the_conditioning_of_a_start_on_the_section_plane_is_measured():
    # the start lies on x = 0: moved by +1e-9 it would start on the other side (an extra event at t0), so
    # the bench moves it the other way and measures how the flow amplifies the change
    from nsbench.bench.reference import conditioning

    p = nsbench.get_problem("henon-heiles")
    ev = nsbench.simulate(p, "reference", SPAN).events
    factor, note = conditioning(p, {"name": "reference", "options": {}}, 0.0, SPAN, ev)
    assert note == "" and 1.0 < factor < 1e6
