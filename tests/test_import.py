"""Importing nsbench stays light: no heavy backend until a component uses it."""

from __future__ import annotations

import subprocess
import sys

HEAVY = ("heyoka", "sksundae", "numba", "matplotlib")


def test_import_loads_no_heavy_backend():
    code = (
        "import sys, nsbench\n"
        "p = nsbench.get_problem('two-dof', case=2)\n"
        "nsbench.simulate(p, 'exact', 20.0)\n"
        "nsbench.list_integrators()\n"
        f"print(','.join(m for m in {HEAVY!r} if m in sys.modules))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == ""
