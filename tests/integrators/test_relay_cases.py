"""Every relay case, every integrator that runs it: ``heyoka-q``'s event sequence, no zero-length slide (issue 48).

The published relay sets (``docs/problems.md``) have ``sigma = rho = 1``: the plant's zeros are a
double root, so the sliding mode's matrix (Utkin's equivalent control) has a Jordan block and
``exact`` runs it through the matrix exponential. There its scan had no curvature bound and cleared
any step whose ends were on the guard's own side: on ``piiroinen-kuznetsov`` a slide whose exit lay
inside a scan step was missed (``event missed`` at t = 1.94, or with ``check_points=0`` another orbit,
with 12 slides per period instead of 14). ``heyoka-ld`` and ``heyoka-q`` logged zero-length
``exit, slide, exit`` triples: an exit carried in extended precision starts the next arc exactly on
its surface with a rate one rounding error into it, which heyoka reported as a root at the start.

The comparison is ``heyoka-q`` at its default tolerance (quad's epsilon): a Taylor method in 113
bits, with nothing of ``exact``'s closed form, scan or polish; the independent high-precision
solution of ``tests/problems/relay_mp.py`` checks ``heyoka-q`` itself (slow test below).
"""

from __future__ import annotations

import numpy as np
import pytest

import nsbench
from nsbench.engine import DEFAULT_CHECK_POINTS

#: The relay's cases, and Piiroinen and Kuznetsov's set from nosnoc_py's own start (0, -0.001, -0.02):
#: it starts on the surface, in the sliding mode.
CASES = {
    "default": {},
    "siconos-sliding": {"case": "siconos-sliding"},
    "siconos-multisliding": {"case": "siconos-multisliding"},
    "piiroinen-kuznetsov": {"case": "piiroinen-kuznetsov"},
    "piiroinen-kuznetsov-nosnoc-start": {"case": "piiroinen-kuznetsov", "x2_0": -0.001, "x3_0": -0.02, "x1_0": 0.0},
}
SPAN = 60.0
#: Event-time bounds against heyoka-q over [0, 60], with what was measured (2026-12-01): heyoka and
#: heyoka-ld locate each root in their own precision (7.1e-15..1.4e-14, 0); exact's and reference's
#: roots in the sliding mode are found on the matrix exponential in double without the polish of the
#: modal form, whose rounding (about 3e-14 per unit of time on piiroinen-kuznetsov) is carried along the
#: orbit (1.8e-12 there, 1.4e-13 on siconos-multisliding).
BOUNDS = {"exact": 2e-11, "reference": 2e-11, "heyoka": 1e-12, "heyoka-ld": 1e-12}


def _problem(name):
    kwargs = dict(CASES[name])
    return nsbench.get_problem("relay-feedback", **kwargs)


_RUNS: dict = {}


def _run(case, integrator):
    key = (case, integrator)
    if key not in _RUNS:
        _RUNS[key] = nsbench.simulate(_problem(case), integrator, SPAN)
    return _RUNS[key]


def _zero_length_slides(events) -> int:
    """Slides whose next event is at the same time (or earlier): a slide of zero length."""
    t, kind = events["t"].to_numpy(), events["kind"].to_numpy()
    return int(sum(1 for i in range(len(t) - 1) if kind[i] == "slide" and not t[i + 1] > t[i]))


@pytest.mark.parametrize("case", list(CASES))
def test_heyoka_q_logs_no_zero_length_slide(case):
    res = _run(case, "heyoka-q")
    assert res.ok, res.message
    assert len(res.events) >= 28 and _zero_length_slides(res.events) == 0
    assert np.all(np.diff(res.events["t"].to_numpy()) > 0.0)


@pytest.mark.parametrize("integrator", list(BOUNDS))
@pytest.mark.parametrize("case", list(CASES))
def test_every_case_gives_heyoka_qs_sequence_with_default_options(case, integrator):
    want = _run(case, "heyoka-q").events
    res = _run(case, integrator)
    assert res.ok, res.message
    got = res.events
    assert list(got["kind"]) == list(want["kind"]), f"{integrator} on {case}: another sequence"
    assert _zero_length_slides(got) == 0
    assert np.abs(got["t"].to_numpy() - want["t"].to_numpy()).max() <= BOUNDS[integrator]


@pytest.mark.parametrize(
    "integrator, options, bound",
    [
        ("exact-mp", {}, 1e-14),
        ("ofapi", {}, 1e-12),
        ("mcpi", {}, 1e-12),
        ("henon-rk4", {"h": 1e-3}, 1e-6),
        ("scipy-dop853", {"rtol": 1e-10, "atol": 1e-12}, 1e-7),
    ],
)
@pytest.mark.parametrize("case", ["siconos-multisliding", "piiroinen-kuznetsov"])
def test_other_integrators_log_no_zero_length_slide_either(case, integrator, options, bound):
    # the sets with the most exits (5 and 2 zero-length triples of heyoka-q before). The fixed-step and
    # scipy methods at a step or tolerance that resolves the 2.2e-3 slides of piiroinen-kuznetsov (at
    # their defaults, h = 0.01 and rtol 1e-6, they are 1.4e-3 off or step over an exit); the bounds are
    # about 20 times what was measured (0, 2.1e-14, 5.7e-14, 7.2e-8, 1.9e-9 on piiroinen-kuznetsov)
    want = _run(case, "heyoka-q").events
    res = nsbench.simulate(_problem(case), nsbench.get_integrator(integrator, **options), SPAN)
    assert res.ok, res.message
    assert _zero_length_slides(res.events) == 0
    assert list(res.events["kind"]) == list(want["kind"])
    assert np.abs(res.events["t"].to_numpy() - want["t"].to_numpy()).max() <= bound


@pytest.mark.parametrize("tol", [1e-4, 1e-6, 1e-8])
def test_heyoka_at_its_loose_tolerances_gives_heyoka_qs_sequence_through_its_root_finding_warning(tol):
    """heyoka at its accuracy levels on the default relay over [0, 100] (the tutorial's suite).

    An exit from the slide starts the next arc on its switching surface, a rounding error on the wrong
    side (x1 = -4.5e-22 at t = 54.82), so the switch guard has an increasing zero within 1e-21 of the
    step's start. At ``tol = 1e-6`` heyoka 7.13's root finder gives up on that zero ("polynomial root
    finding during event detection failed due to too many iterations", on stderr) and drops it, as its
    direction filter would have: the arc's crossing, in a later step, is found. Checked here on the
    events, whatever heyoka logs: the same sequence as heyoka-q's, each time within 10 tol of it (measured
    at 1e-4, 1e-6, 1e-8: 0.21, 0.32 and 0.11 tol; the orbit is attracting, so the errors do not grow),
    and with the engine's check points on (heyoka runs without them by default: its event detection
    sees every step), no crossing stepped over."""
    span = 100.0
    want = nsbench.simulate(_problem("default"), "heyoka-q", span).events
    heyoka = nsbench.get_integrator("heyoka", tol=tol)
    res = nsbench.simulate(_problem("default"), heyoka, span, check_points=DEFAULT_CHECK_POINTS)
    assert res.ok, res.message
    assert list(res.events["kind"]) == list(want["kind"])
    assert np.abs(res.events["t"].to_numpy() - want["t"].to_numpy()).max() <= 10 * tol


def test_the_slide_exact_missed_is_found_whatever_the_span():
    # the exit at t = 1.9275 lay inside one scan step of the sliding mode when the arc's span was long
    # enough (t_end = t0 + 1): the step's ends were both on the guard's own side and nothing bounded
    # the guard between them
    from nsbench.integrators.base import ArcRequest

    p = _problem("piiroinen-kuznetsov")
    ev = _run("piiroinen-kuznetsov", "heyoka-q").events
    entry = ev.iloc[14]
    assert entry["kind"] == "slide" and ev.iloc[15]["kind"] == "exit"
    integ = nsbench.get_integrator("exact")
    integ.setup(p)
    mode = p.parse_mode("slide")
    y0 = entry[["x1", "x2", "x3"]].to_numpy(float)
    for span in (0.2, 0.5, 1.0, 3.0, 10.0):
        arc = integ.advance(
            ArcRequest(
                problem=p,
                mode=mode,
                t0=float(entry["t"]),
                y0=y0,
                t_end=float(entry["t"]) + span,
                guards=p.guards(mode),
                t_eval=np.array([]),
            )
        )
        assert arc.fired is not None and abs(arc.t - ev.iloc[15]["t"]) <= 1e-12, span


def test_the_cli_runs_the_case_to_heyoka_qs_sequence(tmp_path, capsys):
    from nsbench.cli import main

    for integrator in ("exact", "reference"):
        out = tmp_path / f"{integrator}.csv"
        argv = ["simulate", "relay-feedback", "--case", "piiroinen-kuznetsov", "--integrator", integrator]
        assert main([*argv, "--t-end", "60", "--events-out", str(out)]) == 0
        printed = capsys.readouterr().out
        assert "status      success" in printed and "piiroinen-kuznetsov" in printed
        import pandas as pd

        got = pd.read_csv(out)
        want = _run("piiroinen-kuznetsov", "heyoka-q").events
        assert len(got) == len(want) == 283 and list(got["kind"]) == list(want["kind"])


def test_the_orbit_has_fourteen_slides_per_period():
    """The orbit the case settles on (the periodic-orbit code's own search), against heyoka-q's."""
    from nsbench.periodic import HybridFlow, find_orbit

    p = _problem("piiroinen-kuznetsov")
    orbit = find_orbit(HybridFlow(p), transient=200.0, window=100.0)
    kinds = [e.kind for e in orbit.events]
    assert kinds.count("slide") == 14 and kinds.count("exit") == 14 and len(kinds) == 28
    # heyoka-q's period: between an event and the 28th next one, once settled (the orbit's largest
    # multiplier is 1.8e-3: after 5 periods the transient is below rounding)
    t = nsbench.simulate(p, "heyoka-q", 60.0).events["t"].to_numpy()
    t = t[t > 30.0]
    periods = t[28:] - t[:-28]
    assert np.ptp(periods) <= 1e-12
    # the shooting residual is below 1e-12 and the period comes from exact's event times (2e-11 above)
    assert abs(orbit.period - periods[-1]) <= 1e-10


@pytest.mark.slow
def test_heyoka_q_agrees_with_an_independent_high_precision_solution():
    """tests/problems/relay_mp.py: the equations in mpmath (32 digits), no nsbench code; 16 s of CPU."""
    import mpmath as mp

    from nsbench.problems.relay_feedback import CASES as PRESETS
    from tests.problems.relay_mp import orbit_period, relay_events

    mine = relay_events(PRESETS["piiroinen-kuznetsov"], (1.0, 0.0, 0.0), SPAN)
    want = _run("piiroinen-kuznetsov", "heyoka-q").events
    assert [k for _, k in mine] == list(want["kind"])
    # heyoka-q's times are its quad roots rounded to double: within an ulp or two of the true ones
    # (measured 3.5e-15, half an ulp at t = 58; exact's 1.8e-12)
    assert max(abs(float(t) - w) for (t, _), w in zip(mine, want["t"])) <= 2e-14
    # the orbit's largest multiplier is 1.8e-3: from t = 30 on, the period changes by 8e-26 in one period
    period, change, kinds = orbit_period(mine, 28, 30.0)
    assert kinds.count("slide") == 14 and change <= mp.mpf("1e-20")
    assert abs(period - mp.mpf("5.96183694261370")) <= mp.mpf("1e-14")  # the value docs/problems.md gives


@pytest.mark.slow
def test_the_continuation_command_finds_the_fourteen_slide_orbit(tmp_path):
    """`nsbench continuation relay-feedback --case piiroinen-kuznetsov`: the branch starts on the 14-slide orbit
    and finds where its two shortest slides vanish (heyoka-q: 14 slides at zeta = 0.0502, 12 at 0.0503)."""
    import pandas as pd

    from nsbench.cli import main

    out = tmp_path / "pk"
    argv = ["continuation", "relay-feedback", "--case", "piiroinen-kuznetsov", "--sweep", "zeta=0.05:0.051"]
    assert (
        main([*argv, "--steps", "2", "--transient", "200", "--out", str(out), "--formats", "png", "--no-progress"]) == 0
    )
    branch = pd.read_csv(out / "branch.csv")
    first = branch.iloc[0]
    assert first["value"] == 0.05 and first["events_per_period"] == 28
    assert first["pattern"].split().count("slide1") == 14
    # the period of the independent solution (tests/problems/relay_mp.py, docs/problems.md) to the shooting's
    # tolerance (residual below 1e-12, exact's event times within 2e-11 of heyoka-q's above)
    assert abs(first["period"] - 5.96183694261370) <= 1e-10
    bifs = pd.read_csv(out / "bifurcations.csv")
    (zeta,) = bifs.loc[bifs["kind"] == "crossing-sliding", "value"]
    assert 0.0502 < zeta < 0.0503
    assert branch.iloc[-1]["events_per_period"] == 24
