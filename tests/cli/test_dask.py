"""``nsbench bifurcation --dask ADDRESS`` through the command line, against a local Dask cluster.

The cluster is started here (two worker processes); the command runs as a
separate process, exactly as a user would start it.
"""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from nsbench.bifurcation.storage import SweepStore

distributed = pytest.importorskip("distributed")

SWEEP = [
    "bifurcation",
    "two-dof",
    "--case",
    "1",
    "--sweep",
    "v0=0.06:0.2:8",
    "--transient",
    "50",
    "--record",
    "5",
    "--formats",
    "png",
    "--no-progress",
]


@pytest.fixture(scope="module")
def cluster():
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0") as c:
        yield c


def _nsbench(argv: list[str]) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([os.getcwd(), *sys.path])}
    return subprocess.run(
        [sys.executable, "-m", "nsbench", *argv], capture_output=True, text=True, timeout=900, env=env
    )


def test_the_command_on_a_dask_cluster_gives_the_points_of_a_local_run(tmp_path, cluster):
    local = _nsbench(SWEEP + ["--workers", "1", "--out", str(tmp_path / "local")])
    assert local.returncode == 0, local.stderr
    remote = _nsbench(SWEEP + ["--dask", cluster.scheduler_address, "--out", str(tmp_path / "dask")])
    assert remote.returncode == 0, remote.stderr
    assert "Traceback" not in remote.stderr
    a = SweepStore(tmp_path / "local").load().drop(columns="wall_time")
    b = SweepStore(tmp_path / "dask").load().drop(columns="wall_time")
    assert len(a) == 8 * 5 and (a["status"] == "success").all()
    assert b.equals(a)  # deterministic integrator, same arithmetic: the same points to the last bit
    assert (tmp_path / "dask" / "diagram.png").stat().st_size > 1000
