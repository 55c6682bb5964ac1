"""The requests the Python-arc glue hands an integrator are complete :class:`ArcRequest` objects.

``_PythonArcs`` fills each request's fields directly (not through the frozen dataclass's
``__init__``, which costs a few microseconds per arc). Here a real integrator
(``heyoka``) runs 2-DOF case 1 through ``nsbench.simulate`` while its ``advance`` keeps
the requests; each must have every field of the dataclass, equal what the constructor
builds from the same values, and describe the arc the loop was at (the state read-only).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import nsbench
from nsbench.integrators import get_integrator
from nsbench.integrators.base import ArcRequest

pytest.importorskip("heyoka")


def test_every_request_is_a_whole_arc_request():
    problem = nsbench.get_problem("two-dof", case=1)
    integ = get_integrator("heyoka")
    seen: list[ArcRequest] = []
    advance = integ.advance

    def keep(request):
        seen.append(request)
        return advance(request)

    integ.advance = keep
    res = nsbench.simulate(problem, integ, 40.0, t_eval=np.linspace(0.0, 40.0, 9))
    assert res.ok and len(seen) > 10
    names = [f.name for f in dataclasses.fields(ArcRequest)]
    for k, request in enumerate(seen):
        assert type(request) is ArcRequest
        built = ArcRequest(**{name: getattr(request, name) for name in names})
        assert dataclasses.replace(request).__dict__.keys() == built.__dict__.keys()
        assert request.guards == problem.guards(request.mode)
        assert not request.y0.flags.writeable
        assert request.t_end == 40.0 and request.sections == ()
        assert np.all(request.t_eval > request.t0) or request.t_eval.size == 0
        if k:  # each arc starts where the loop left the last one (the event, or its transition)
            assert request.t0 >= seen[k - 1].t0
        with pytest.raises(dataclasses.FrozenInstanceError):
            request.t0 = 0.0  # type: ignore[misc]
