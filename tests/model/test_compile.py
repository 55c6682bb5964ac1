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


def test_a_module_imported_from_its_package_under_another_name_counts():
    """``from nsbench.integrators import _double_double as dd``: the exact kernel inlines that
    module's functions, so editing it must drop the kernel's cache (the alias once hid it)."""
    known = {"nsbench.integrators", "nsbench.integrators._double_double", "nsbench.model.abi"}
    text = (
        "from nsbench.integrators import _double_double as dd\n"
        "from nsbench.integrators import (\n    _double_double as dd2,\n)\n"
        "from nsbench.model import abi\n"
    )
    assert compiled.imported_modules(text, known) == {
        "nsbench.integrators",
        "nsbench.integrators._double_double",
        "nsbench.model.abi",
    }
