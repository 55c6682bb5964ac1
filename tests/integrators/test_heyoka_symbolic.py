"""heyoka on a problem written symbolically whose guard restarts on its surface after a reset.

The bouncing ball writes its field and guard with ``+ - *`` (``symbolic_field``,
as a plug-in problem may), so it runs through heyoka's symbolic path. After each impact the contact
guard starts at zero, so heyoka takes the arc's first step alone and looks for
the next impact on that step's polynomial. A flight is a quadratic, whose Taylor
series ends, so heyoka's step can span many flights: the late, short flights
end before the first of the 32 samples of the step. The impact is then looked
for nearer the start, where the guard left its surface (before, it was missed
and the ball fell through the floor with status ``success``). Checked against
``exact`` (closed-form flights, every impact time and the accumulation time
to 1e-12 of the closed form: tests/problems/test_bouncing_ball.py).
"""

from __future__ import annotations

import numpy as np
import pytest

import nsbench
from nsbench.integrators._heyoka_model import illinois


@pytest.fixture(scope="module")
def ball():
    return nsbench.get_problem("bouncing-ball")


@pytest.mark.parametrize("name", ["heyoka", "heyoka-ld", "heyoka-q"])
def test_every_impact_and_the_rest_are_found(ball, name):
    want = nsbench.simulate(ball, "exact", 10.0)
    got = nsbench.simulate(ball, name, 10.0)
    assert got.ok, got.message
    # the Zeno rule's depth is decided by its error estimate (4 impacts before the rest at the defaults);
    # heyoka resolves the tail to the same depth as exact's closed-form flights
    kinds = list(got.events["kind"])
    assert kinds == list(want.events["kind"]) and kinds[-1] == "rest" and set(kinds[:-1]) == {"impact"}
    assert len(kinds) >= 5
    assert got.y_final.tolist() == [0.0, 0.0]  # at rest on the ground, not below it


@pytest.mark.parametrize("name", ["heyoka", "heyoka-ld", "heyoka-q"])
def test_the_impact_times(ball, name):
    # each impact is a root of an exact quadratic (the Taylor polynomial of a flight), refined in the
    # integrator's precision: far inside 1e-12 (measured 2.9e-14, 8.9e-16, 8.9e-16; heyoka in double
    # was 1.6e-6 to 1.4e-5 late from the fifth impact on before illinois kept halving, below)
    want = nsbench.simulate(ball, "exact", 10.0).events["t"].to_numpy()
    got = nsbench.simulate(ball, name, 10.0).events["t"].to_numpy()
    assert np.abs(got - want).max() <= 1e-12


@pytest.mark.parametrize("name", ["heyoka", "heyoka-q"])
def test_states_between_impacts(ball, name):
    # the symbolic path's states at requested times, from the polynomial of the step holding each:
    # a flight is a quadratic, so they are exact's closed form to the impact times' error (1e-12
    # above) times the speed (at most 10 here), and the grid keeps 1e-9 away from every impact
    want = nsbench.simulate(ball, "exact", 10.0)
    impacts = want.events["t"].to_numpy()
    grid = np.linspace(0.0, 10.0, 4001)
    grid = grid[np.min(np.abs(grid[:, None] - impacts[None, :]), axis=1) > 1e-9]
    ref = nsbench.simulate(ball, "exact", 10.0, t_eval=grid)
    got = nsbench.simulate(ball, name, 10.0, t_eval=grid)
    assert got.ok, got.message
    cols = list(ref.trajectory.columns[:3])
    np.testing.assert_allclose(got.trajectory[cols].to_numpy(), ref.trajectory[cols].to_numpy(), rtol=0, atol=1e-10)


def test_illinois_converges_when_one_end_reaches_the_root_first():
    # the bracket of the ball's fifth impact in heyoka's first step (t0 = the fourth impact): the secant
    # puts the left end on the root to rounding while the right end is still 1.4e-6 away, and the old
    # loop stopped there and returned the right end
    t0, v0 = 2.2142719353940254, 1.8143014628436428

    def f(t):
        return v0 * (t - t0) - 4.905 * (t - t0) ** 2

    a, b = 2.457575937412962, 2.700879939431899
    root = illinois(f, a, f(a), b, f(b))
    exact = t0 + v0 / 4.905
    assert f(root) <= 0 and abs(root - exact) <= 4 * np.spacing(exact)
