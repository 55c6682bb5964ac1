"""The same sweep through a Dask LocalCluster gives identical points."""

from __future__ import annotations

import pytest

from nsbench.bifurcation.parallel import run_sweep
from nsbench.bifurcation.sweep import SweepSpec

distributed = pytest.importorskip("distributed")


def test_dask_local_cluster_gives_identical_points(tmp_path):
    spec = SweepSpec(problem="two-dof", case=2, name="F", start=0.1, stop=0.5, count=8,
                     section="strobe", transient=150.0, record=10)
    local = run_sweep(spec, tmp_path / "local", workers=1, progress=False)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster:
        remote = run_sweep(spec, tmp_path / "dask", dask=cluster.scheduler_address, progress=False)
    assert len(remote) == len(local) == 80
    assert remote.drop(columns="wall_time").equals(local.drop(columns="wall_time"))


def test_a_cluster_without_workers_stops_the_sweep_with_a_reason(tmp_path, monkeypatch):
    from nsbench.bifurcation import parallel
    from nsbench.errors import NsbenchError

    monkeypatch.setattr(parallel, "NO_WORKER_LIMIT", 3.0)
    monkeypatch.setattr(parallel._run_dask, "__defaults__", (3.0,))
    spec = SweepSpec(problem="two-dof", case=1, name="v0", start=0.1, stop=0.2, count=2, transient=10.0, record=2)
    with distributed.LocalCluster(n_workers=0, dashboard_address=None) as cluster, \
            distributed.Client(cluster) as client:
        with pytest.raises(NsbenchError, match=r"has had no worker for 3 s with \d+ chunk"):
            run_sweep(spec, tmp_path / "none", dask=client, progress=False)
