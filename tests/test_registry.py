"""The entry-point registry: discovery, lazy loading, failures that do not spread."""

from __future__ import annotations

from importlib import metadata

import pytest

import nsbench
from nsbench import registry
from nsbench.errors import ConfigError, PluginLoadError


def test_builtins_are_registered_through_entry_points():
    eps = {ep.name for ep in metadata.entry_points(group="nsbench.integrators")}
    assert {"exact", "scipy-dop853", "henon-rk4"} <= eps
    assert set(nsbench.list_integrators()) >= eps
    assert {"one-dof", "two-dof"} <= set(nsbench.list_problems())


def test_unknown_name_suggests_a_close_one():
    with pytest.raises(ConfigError, match="did you mean 'henon-rk4'"):
        registry.load("integrators", "henon-rk5")


def test_broken_plugin_is_listed_as_unavailable(monkeypatch):
    broken = metadata.EntryPoint(name="broken-plugin", value="nsbench_no_such_module:Thing",
                                 group="nsbench.integrators")
    real = registry._entry_points

    def fake(kind):
        found = real(kind)
        if kind == "integrators":
            found["broken-plugin"] = broken
        return found

    monkeypatch.setattr(registry, "_entry_points", fake)
    status = dict((e.name, reason) for e, reason in registry.availability("integrators"))
    assert "No module named 'nsbench_no_such_module'" in status["broken-plugin"]
    assert status["exact"] is None  # the others still load
    with pytest.raises(PluginLoadError, match="failed to import"):
        registry.load("integrators", "broken-plugin")


def test_empty_registry_fails_loudly(monkeypatch):
    monkeypatch.setattr(registry, "_entry_points", lambda kind: {})
    with pytest.raises(ConfigError, match="is nsbench installed"):
        registry.names("problems")


def test_integrator_config_round_trip():
    for name in nsbench.list_integrators():
        integ = nsbench.get_integrator(name)
        again = nsbench.integrator_from_config(integ.config())
        assert again.config() == integ.config()
        assert type(again) is type(integ)
