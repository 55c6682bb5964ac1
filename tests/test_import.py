"""Importing nsbench stays light: no heavy backend until a component uses it."""

from __future__ import annotations

import subprocess
import sys

HEAVY = ("heyoka", "sksundae", "numba", "matplotlib")


def _loaded(code: str) -> set[str]:
    probe = f"import sys\n{code}\nprint(','.join(m for m in {HEAVY!r} if m in sys.modules))\n"
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True)
    return {m for m in out.stdout.strip().split(",") if m}


def test_import_loads_no_heavy_backend():
    assert (
        _loaded(
            "import nsbench\np = nsbench.get_problem('two-dof', case=2)\n"
            "nsbench.list_integrators()\nnsbench.list_problems()"
        )
        == set()
    )


def test_a_simulation_loads_only_the_compiled_core():
    # the hybrid core is compiled (numba); heyoka, SUNDIALS and matplotlib wait for their users
    assert _loaded("import nsbench\nnsbench.simulate(nsbench.get_problem('two-dof', case=2), 'exact', 20.0)") == {
        "numba"
    }
