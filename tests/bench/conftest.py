"""Fixtures of the bench tests: registering the test-only integrators for one test."""

from __future__ import annotations

import pytest

from nsbench import registry


@pytest.fixture
def register():
    """``register(name, cls)``: a runtime registration undone after the test."""
    added = []

    def add(name, cls):
        registry.register("integrators", name, cls)
        added.append(name)

    yield add
    for name in added:
        registry.unregister("integrators", name)
