"""``nsbench bench`` and ``nsbench run`` from Python: a request checked at its construction, one app
function, its outcome; the same rows as :func:`nsbench.bench.runner.run_suite` called directly."""

from __future__ import annotations

import pandas as pd
import pytest

from nsbench.bench.command import BenchRequest, RunRequest, run_bench
from nsbench.bench.runner import run_suite
from nsbench.bench.suite import Suite, load_suite
from nsbench.errors import ConfigError
from nsbench.status import Status

TINY = {
    "name": "tiny",
    "t_span": [0, 20],
    "repeats": 3,
    "min_sample_time": 0,
    "problems": [{"name": "one-dof", "case": 1}],
    "integrators": {"only": ["exact", "scipy-rk45"]},
}


@pytest.mark.parametrize(
    ("values", "named"),
    [
        ({"formats": "png,bmpx"}, "bmpx"),
        ({"workers": "0"}, "--workers"),
        ({"workers": "two"}, "--workers"),
        ({"suite": "no-such-suite"}, "no-such-suite"),
    ],
)
def test_bad_values_are_refused_at_the_construction(tmp_path, values, named):
    given = {"suite": TINY, "out": tmp_path / "out", **values}
    with pytest.raises(ConfigError, match=named):
        BenchRequest(**given)
    assert not (tmp_path / "out").exists()  # refused before anything ran or was written


def test_a_file_in_the_way_of_the_folder_is_refused(tmp_path):
    (tmp_path / "out").write_text("not a folder")
    with pytest.raises(ConfigError, match="--out"):
        BenchRequest(TINY, tmp_path / "out")


def test_the_request_keeps_the_parsed_values(tmp_path):
    request = BenchRequest(TINY, tmp_path / "out", workers="1", formats=" PNG , svg")
    assert request.workers == 1 and request.formats == ("png", "svg")
    assert isinstance(request.suite, Suite) and request.suite.name == "tiny"


def test_run_request_defaults_its_folder_and_its_resume_command():
    default = RunRequest()
    assert str(default.bench.out) == "reports/latest" and default.bench.resume
    assert default.bench.resume_command == "nsbench run"
    families = RunRequest("families", fresh=True, formats="png,svg")
    assert str(families.bench.out) == "reports/families" and not families.bench.resume
    assert families.bench.resume_command == "nsbench run --suite families --formats png,svg"
    with pytest.raises(ConfigError, match="--workers"):
        RunRequest(workers="-3")


def test_run_bench_gives_the_rows_run_suite_gives(tmp_path, capsys):
    outcome = run_bench(BenchRequest(TINY, tmp_path / "app", workers=1, progress=False, report=False))
    assert outcome.exit_code == 0 and outcome.failure is None and outcome.report is None
    assert "4 cases: 4 computed, 0 already stored" in capsys.readouterr().out
    direct = run_suite(load_suite(TINY), tmp_path / "direct", workers=1, progress=False)
    mine = pd.read_parquet(tmp_path / "app" / "results.parquet")
    keys = ["problem", "integrator", "options", "case"]
    assert (
        mine[keys + ["status", "n_events"]]
        .sort_values(keys)
        .reset_index(drop=True)
        .equals(direct.results[keys + ["status", "n_events"]].sort_values(keys).reset_index(drop=True))
    )
    assert set(mine["status"]) == {Status.SUCCESS.value}
