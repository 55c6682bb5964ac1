"""Exception types for nsbench.

User-facing mistakes (unknown names, nonphysical parameters, malformed options)
raise :class:`ConfigError`, a ``ValueError``, with a message that names the bad
value and what is allowed. Numerical failures inside a run are *not* errors:
they come back as a :class:`~nsbench.results.Status` on the result.
"""

from __future__ import annotations


class NsbenchError(Exception):
    """Base class of every exception nsbench raises on purpose."""


class ConfigError(NsbenchError, ValueError):
    """Bad input: unknown name, nonphysical parameter, malformed option or range."""


class UnsupportedProblemError(ConfigError):
    """An integrator refuses a problem it cannot solve (e.g. ``exact`` on a cubic spring)."""


class PluginLoadError(NsbenchError, ImportError):
    """A registered component (built-in or plug-in) failed to import."""
