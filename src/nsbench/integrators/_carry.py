"""Carrying an extended-precision state across an event (``heyoka-q``, ``heyoka-ld``, ``exact-mp``).

An integrator that keeps more digits than a double keeps the time and state
where its last arc stopped at an event. The hybrid core then sends the next
request with doubles: the returned time (both parts) and the returned state,
changed only by the transition (a block that sticks has its velocity set to
exactly ``v0``). :func:`reset_velocities` says whether a request is such a
continuation, so the integrator goes on from its own digits instead.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, cast

import numpy as np

from nsbench.integrators.base import ArcRequest

if TYPE_CHECKING:  # pragma: no cover
    from nsbench.problems.oscillator import FrictionOscillator


def reset_velocities(request: ArcRequest, t: float, t_lo: float, y_out: np.ndarray) -> np.ndarray | None:
    """Indices of the velocities the transition set to ``v0``, if ``request`` continues an arc that
    returned ``(t, t_lo, y_out)``; ``None`` if it does not (it starts elsewhere, or changes any
    other entry of the state).

    ``v0`` is a double, so setting those entries to ``v0`` in any wider precision is exact.
    """
    if float(request.t0) != t or float(request.t0_lo) != t_lo:
        return None
    y0 = np.asarray(request.y0, dtype=float)
    if y0.shape != y_out.shape:
        return None
    changed = np.flatnonzero(y0 != y_out)
    v0 = float(cast("FrictionOscillator", request.problem).coefficients.v0)  # blocks on a belt: a carry starts there
    if any(j % 2 != 1 or y0[j] != v0 for j in changed):  # only a velocity reset to the belt speed
        return None
    return changed
