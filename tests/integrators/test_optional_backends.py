"""The engines behind a pip extra (``[cyrk]``, ``[jax]``) without their extra: listed as
unavailable with the install command, refused at setup with it, left out of the suites that take every
registered integrator (and named there); and ``import nsbench`` imports none of their backends."""

from __future__ import annotations

import importlib.util
import subprocess
import sys

import pytest

from nsbench import registry
from nsbench.bench.suite import Suite
from nsbench.cli import build_parser, listing
from nsbench.errors import UnsupportedProblemError
from nsbench.integrators import integrator_class
from nsbench.problems import get_problem

#: Each engine behind an extra: (a registered name, its extra, its backend's import names).
ENGINES = [
    ("cyrk-dop853", "cyrk", ("CyRK",)),
    ("diffrax-tsit5", "jax", ("jax", "diffrax", "optimistix")),
    ("diffrax-dopri8", "jax", ("jax", "diffrax", "optimistix")),
]
BACKENDS = ("CyRK", "jax", "jaxlib", "diffrax", "equinox", "optimistix", "casadi", "nosnoc")


@pytest.fixture
def backends_absent(monkeypatch):
    """``find_spec`` finds none of the backends: what a checkout without the extras sees."""
    real = importlib.util.find_spec

    def fake(name, *args, **kwargs):
        if name.split(".")[0] in BACKENDS:
            return None
        return real(name, *args, **kwargs)

    monkeypatch.setattr(importlib.util, "find_spec", fake)


@pytest.mark.parametrize("name, extra, modules", ENGINES)
def test_without_its_extra_it_is_unavailable_with_the_install_command(backends_absent, name, extra, modules, capsys):
    reason = registry.unavailable_reason("integrators", name)
    assert reason is not None and f'pip install -e ".[{extra}]"' in reason
    assert all(m in reason for m in modules)
    status = dict((e.name, why) for e, why in registry.availability("integrators"))
    assert status[name] == reason and status["exact"] is None
    assert listing.main(build_parser().parse_args(["list", "integrators"])) == 0
    line = next(row for row in capsys.readouterr().out.splitlines() if row.split()[:1] == [name])
    assert "UNAVAILABLE" in line and f".[{extra}]" in line and "Traceback" not in line


@pytest.mark.parametrize("name, extra, modules", ENGINES)
def test_without_its_extra_setup_refuses_with_the_reason(backends_absent, name, extra, modules):
    integ = integrator_class(name)()
    with pytest.raises(UnsupportedProblemError, match=rf"pip install -e \"\.\[{extra}\]\""):
        integ.setup(get_problem("two-dof", case=2))


def test_a_suite_of_every_registered_integrator_leaves_them_out_and_names_them(backends_absent):
    suite = Suite(name="t", problems=[{"name": "two-dof", "case": 2}], integrators={"registered": True})
    names = suite.integrator_names()
    for name, extra, _ in ENGINES:
        assert name not in names
        assert f".[{extra}]" in suite.unavailable()[name]
    assert "exact" in names


def test_optional_names_run_where_they_can(backends_absent):
    suite = Suite(
        name="t",
        problems=[{"name": "two-dof", "case": 2}],
        integrators={"only": ["exact"], "optional": ["cyrk-dop853"]},
    )
    assert suite.integrator_names() == ["exact"]
    assert "cyrk-dop853" in suite.unavailable()


def test_importing_nsbench_imports_no_optional_backend():
    probe = (
        "import sys\nimport nsbench\nfrom nsbench import registry\n"
        "registry.availability('integrators')\n"
        "[nsbench.get_integrator(n) for n in nsbench.list_integrators()]\n"
        f"print(','.join(m for m in {BACKENDS!r} if m in sys.modules))\n"
    )
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == ""
