"""The numba cache guard of nsbench.model.compile reads the imports of every compiled file."""

from __future__ import annotations

from nsbench.model import compile as compiled


def test_the_cache_guard_sees_every_import_of_a_compiled_file():
    """Consecutive one-line imports each count: the hybrid loop inlines the law and the rules of
    other files, so a change to any of them must drop the loop's numba cache (an earlier pattern
    swallowed every other one-line import)."""
    text = (
        "from nsbench.model.clock import monotonic_ns\n"
        "from nsbench.model.rules import (\n    settle,\n    pending_guard,\n)\n"
        "from nsbench.model.records import record_hit\n"
        "from nsbench.integrators._henon_kernel import henon_arc\n"
        "import nsbench.integrators._picard_arc\n"
    )
    found = compiled._IMPORTS.findall(text)
    modules = [frm or plain for frm, _, _, plain in found]
    assert modules == [
        "nsbench.model.clock",
        "nsbench.model.rules",
        "nsbench.model.records",
        "nsbench.integrators._henon_kernel",
        "nsbench.integrators._picard_arc",
    ]
    assert [g or n for _, g, n, _ in found][:3] == ["monotonic_ns", "\n    settle,\n    pending_guard,\n", "record_hit"]
