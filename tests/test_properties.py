"""Property tests over random physical parameters (hypothesis)."""

from __future__ import annotations

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import nsbench
from nsbench.status import Status

NEXT = {"stick": {"slip"}, "slip": {"stick", "reverse"}, "reverse": {"stick", "reverse"}}


@st.composite
def two_dof_params(draw, cubic: bool):
    rho2 = draw(st.floats(0.5, 2.0))
    rf1 = draw(st.floats(0.3, 1.0))
    params = dict(
        c1=draw(st.floats(0.0, 0.4)),
        c2=draw(st.floats(0.0, 0.4)),
        kappa=draw(st.floats(0.2, 5.0)),
        mu=draw(st.floats(0.2, 5.0)),
        rho2=rho2,
        rf1=rf1,
        rf2=draw(st.floats(0.3, 1.0)) * rho2,
        F=draw(st.floats(0.0, 0.8)),
        Omega=draw(st.floats(0.3, 3.0)),
        v0=draw(st.floats(0.02, 0.5)),
    )
    if cubic:
        params.update(h1=draw(st.floats(0.0, 1.5)), h2=draw(st.floats(0.0, 1.5)))
    return params


def check_run(res, problem) -> None:
    assert res.ok, res.message
    ev = res.events
    # the state sits on the belt speed after every event of that block
    for row in ev.itertuples():
        assert getattr(row, f"v{row.block}") == problem.v0
    # per block, event kinds follow the transition rules
    for block in range(1, problem.n_blocks + 1):
        kinds = ev.loc[ev["block"] == block, "kind"].tolist()
        if kinds:
            assert kinds[0] in ("stick", "reverse")  # every block starts in slip-
        for a, b in zip(kinds, kinds[1:]):
            assert b in NEXT[a], (a, b)
    # a stuck block moves with the belt
    tr = res.trajectory
    for block in range(1, problem.n_blocks + 1):
        stuck = tr[tr[f"phase{block}"] == 0]
        np.testing.assert_allclose(stuck[f"v{block}"], problem.v0, rtol=0, atol=1e-12)
        t = tr["t"].to_numpy()
        both = (tr[f"phase{block}"].to_numpy()[1:] == 0) & (tr[f"phase{block}"].to_numpy()[:-1] == 0)
        ev_t = ev.loc[ev["block"] == block, "t"].to_numpy()
        no_event = np.array([not np.any((ev_t > t[k]) & (ev_t <= t[k + 1])) for k in range(t.size - 1)])
        dx = np.diff(tr[f"x{block}"].to_numpy())
        sel = both & no_event
        np.testing.assert_allclose(dx[sel], problem.v0 * np.diff(t)[sel], rtol=1e-9, atol=1e-12)


@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(params=two_dof_params(cubic=False))
def test_exact_random_linear_problems(params):
    p = nsbench.get_problem("two-dof", case=2, **params)
    res = nsbench.simulate(p, "exact", 60.0, t_eval=np.linspace(0, 60, 601))
    check_run(res, p)


@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(params=two_dof_params(cubic=True))
def test_dop853_random_cubic_problems(params):
    p = nsbench.get_problem("two-dof", case=4, **params)
    res = nsbench.simulate(p, "scipy-dop853", 40.0, t_eval=np.linspace(0, 40, 401))
    if res.status is Status.EVENT_MISSED:
        # at its default tolerance dop853 may step over a stick and its slip (a crossing pair inside one
        # step): the core must then say so, and the flag must be true: the reference has an event there
        # that the run lacks, its events before it are the run's, and the run ends where the guard was seen
        # on its wrong side, after that event
        ref = nsbench.simulate(p, "reference", 40.0).events
        got = list(zip(res.events["kind"], res.events["block"]))
        want = list(zip(ref["kind"], ref["block"]))
        assert len(want) > len(got) and want[: len(got)] == got, (got, want)
        assert ref["t"].iloc[len(got)] <= res.t_final, (ref["t"].iloc[len(got)], res.t_final)
        return
    check_run(res, p)
