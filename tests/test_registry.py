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


@pytest.mark.parametrize(
    ("config", "message"),
    [
        (
            {"name": "henon-rk4", "h": float("nan")},
            r"unknown key\(s\) 'h'; allowed: 'name', 'options' \(options such as 'h'",
        ),
        ({"name": "henon-rk4", "options": 0.01}, r"'options' must be a dict, got 0.01"),
        (["henon-rk4"], r"integrator config must be a dict with 'name' and 'options', got list"),
    ],
)
def test_an_integrator_config_with_a_misplaced_option_is_refused(config, message):
    # the option at the top level was dropped without a word: the integrator ran with its default h
    with pytest.raises(ConfigError, match=message):
        nsbench.integrator_from_config(config)


@pytest.mark.parametrize(
    ("call", "message"),
    [
        (lambda: nsbench.get_problem(5), r"problem name must be a string .*got int 5"),
        (lambda: nsbench.get_problem("two-dof", dimensional="yes"), r"dimensional = 'yes' must be True or False"),
        (lambda: nsbench.get_problem("two-dof", v0=10**400), r"parameter v0 = 1000.* is too large for a double"),
    ],
)
def test_a_problem_with_a_bad_argument_type_is_a_config_error(call, message):
    with pytest.raises(ConfigError, match=message):
        call()
