"""The same sweep through a Dask LocalCluster gives identical points; faulty plug-ins cost only their values.

Each Dask worker runs its chunks in a supervised process of its own
(:func:`nsbench.bifurcation.parallel.dask_chunk`), under the same limits as a local run.
"""

from __future__ import annotations

import numpy as np
import pytest

from nsbench import registry
from nsbench.bifurcation.parallel import run_sweep
from nsbench.bifurcation.sweep import SweepSpec
from tests.bench import _integrators as faulty

distributed = pytest.importorskip("distributed")


def test_dask_local_cluster_gives_identical_points(tmp_path):
    spec = SweepSpec(
        problem="two-dof", case=2, name="F", start=0.1, stop=0.5, count=8, section="strobe", transient=150.0, record=10
    )
    local = run_sweep(spec, tmp_path / "local", workers=1, progress=False)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0") as cluster:
        remote = run_sweep(spec, tmp_path / "dask", dask=cluster.scheduler_address, progress=False)
    assert len(remote) == len(local) == 80
    assert remote.drop(columns="wall_time").equals(local.drop(columns="wall_time"))


def test_a_cluster_without_workers_stops_the_sweep_with_a_reason(tmp_path, monkeypatch):
    from nsbench.bifurcation import parallel
    from nsbench.errors import NsbenchError

    monkeypatch.setattr(parallel, "NO_WORKER_LIMIT", 3.0)
    spec = SweepSpec(problem="two-dof", case=1, name="v0", start=0.1, stop=0.2, count=2, transient=10.0, record=2)
    with (
        distributed.LocalCluster(n_workers=0, dashboard_address=":0") as cluster,
        distributed.Client(cluster) as client,
    ):
        with pytest.raises(NsbenchError, match=r"has had no worker for 3 s with \d+ chunk"):
            run_sweep(spec, tmp_path / "none", dask=client, progress=False)


@pytest.fixture(scope="module")
def cluster():
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0") as c:
        yield c


@pytest.fixture
def faulty_registered():
    classes = (faulty.HangingAt, faulty.ExitingAt, faulty.SegfaultingAt, faulty.HangingSetup)
    for cls in classes:
        registry.register("integrators", cls.name, cls)
    yield
    for cls in classes:
        registry.unregister("integrators", cls.name)


SPEC = dict(problem="two-dof", case=1, name="v0", start=0.06, stop=0.2, count=8, transient=50.0, record=5)
BAD = 5  # v0 = 0.16 lies in faulty.BAD_V0


@pytest.mark.parametrize(
    "name, status, reason",
    [
        ("hanging-at-test", "time limit", "ran past its limit of 4 s"),
        ("exiting-at-test", "crashed", "exit code 7"),
        ("segfaulting-at-test", "crashed", "signal 11 (SIGSEGV)"),
    ],
)
def test_a_faulty_plugin_on_dask_costs_only_its_value(tmp_path, cluster, faulty_registered, name, status, reason):
    # without supervision on the Dask workers, os._exit and SIGSEGV end as KilledWorker (the whole
    # sweep lost) and the hang never ends
    frame = run_sweep(
        SweepSpec(integrator=name, **SPEC),
        tmp_path / "s",
        dask=cluster.scheduler_address,
        progress=False,
        point_limit=4.0,
    )
    first = frame.groupby("index").first()
    assert first.loc[BAD, "status"] == status and reason in first.loc[BAD, "message"]
    good = first.drop(index=BAD)
    assert (good["status"] == "success").all() and len(good) == 7
    assert np.isfinite(frame.loc[frame["index"] != BAD, "x1"]).all()


def test_a_setup_that_never_ends_on_dask_fails_every_value_within_its_limit(tmp_path, cluster, faulty_registered):
    frame = run_sweep(
        SweepSpec(integrator=faulty.HangingSetup.name, **SPEC),
        tmp_path / "s",
        dask=cluster.scheduler_address,
        progress=False,
        setup_limit=3.0,
    )
    assert (frame["status"] == "time limit").all() and len(frame) == 8
    assert frame["message"].str.contains("integrator set-up ran past its limit of 3 s").all()
