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
    broken = metadata.EntryPoint(
        name="broken-plugin", value="nsbench_no_such_module:Thing", group="nsbench.integrators"
    )
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


def test_the_entry_points_are_read_once_per_process(monkeypatch):
    """A plug-in installed while a run goes on is seen by none of its parts, not some: only after refresh()."""
    registry.refresh()
    before = registry.names("integrators")
    late = metadata.EntryPoint(
        name="late-plugin", value="nsbench.integrators.henon_rk4:HenonRK4", group="nsbench.integrators"
    )
    real = metadata.entry_points

    def installed_now(**kw):
        eps = list(real(**kw))
        return eps + [late] if kw.get("group") == "nsbench.integrators" else eps

    monkeypatch.setattr(registry.metadata, "entry_points", installed_now)
    try:
        assert registry.names("integrators") == before  # the snapshot of this process
        assert "late-plugin" not in nsbench.list_integrators()
        with pytest.raises(ConfigError, match="unknown integrator 'late-plugin'"):
            registry.load("integrators", "late-plugin")
        registry.refresh()
        assert "late-plugin" in registry.names("integrators")
        assert registry.load("integrators", "late-plugin").name == "henon-rk4"
    finally:
        monkeypatch.undo()
        registry.refresh()
    assert "late-plugin" not in registry.names("integrators")
