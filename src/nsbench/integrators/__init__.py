"""Integrators, one file per family, all behind the :class:`Integrator` protocol.

Look one up by registry name with :func:`get_integrator`; the built-ins are
registered through the ``nsbench.integrators`` entry-point group exactly as
plug-ins are.
"""

from __future__ import annotations

from typing import Any

from nsbench import registry
from nsbench.errors import ConfigError
from nsbench.integrators.base import (
    ArcRequest,
    ArcResult,
    Capabilities,
    CompiledArcs,
    Integrator,
    Option,
    SectionHit,
)

__all__ = [
    "Integrator",
    "CompiledArcs",
    "Capabilities",
    "Option",
    "ArcRequest",
    "ArcResult",
    "SectionHit",
    "get_integrator",
    "integrator_class",
    "integrator_from_config",
    "list_integrators",
    "ALIASES",
    "canonical_name",
]


#: Former names, kept so that stored results and old commands still work: the compiled
#: whole-run paths they named are what ``exact`` and ``henon-rk4`` do now.
ALIASES = {"exact-jit": "exact", "henon-rk4-jit": "henon-rk4"}


def canonical_name(name: str) -> str:
    """``name``, or the integrator an old alias stands for."""
    return ALIASES.get(name, name)


def integrator_class(name: str) -> type[Integrator]:
    """The registered class for ``name`` or one of its :data:`ALIASES` (imports it on first use)."""
    cls = registry.load("integrators", canonical_name(name))
    if not (isinstance(cls, type) and issubclass(cls, Integrator)):
        raise ConfigError(f"integrator {name!r} is registered as {cls!r}, which is not an Integrator subclass")
    return cls


def get_integrator(name: str, **options: Any) -> Integrator:
    """Build a registered integrator with ``options`` (validated; unknown ones are errors)."""
    return integrator_class(name)(**options)


def integrator_from_config(config: dict[str, Any]) -> Integrator:
    """Rebuild an integrator from its :meth:`Integrator.config` dict.

    Raises
    ------
    ConfigError
        Not a dict, no ``name``, or a key other than ``name`` and ``options`` (an option put
        at the top level, ``{'name': 'henon-rk4', 'h': nan}``, would otherwise be dropped
        without a word and the integrator built with its default).
    """
    if not isinstance(config, dict):
        raise ConfigError(f"integrator config must be a dict with 'name' and 'options', got {type(config).__name__}")
    if "name" not in config:
        raise ConfigError(f"integrator config needs a 'name': got {config!r}")
    unknown = sorted(set(config) - {"name", "options"})
    if unknown:
        raise ConfigError(
            f"integrator config has unknown key(s) {', '.join(map(repr, unknown))}; allowed: 'name', "
            f"'options' (options such as {unknown[0]!r} go under 'options'): got {config!r}"
        )
    if not isinstance(config.get("options", {}), dict):
        raise ConfigError(f"integrator config's 'options' must be a dict, got {config['options']!r}")
    return integrator_class(config["name"]).from_config(config)


def list_integrators() -> list[str]:
    """Names of the registered integrators."""
    return registry.names("integrators")
