"""Engines whose backend is an optional dependency (a pip extra): how they say what is missing.

An engine of this kind imports its backend only inside its methods, never at module level,
so that its module (and ``nsbench`` itself) imports without it. Its class derives from
:class:`OptionalBackend` and names the backend's import names and its extra:
:meth:`OptionalBackend.unavailable` then gives the reason and the install command, which
``nsbench list`` prints (``UNAVAILABLE: ...``), the suites record for the engines they
leave out, and :meth:`OptionalBackend.setup` raises as an ``UnsupportedProblemError``.
"""

from __future__ import annotations

import importlib.util
from typing import TYPE_CHECKING, ClassVar

from nsbench.errors import UnsupportedProblemError
from nsbench.integrators.base import Integrator

if TYPE_CHECKING:  # pragma: no cover
    from nsbench.problems.base import HybridProblem


def install_command(extra: str) -> str:
    """The command that installs an extra in a checkout (and from an index)."""
    return f'pip install -e ".[{extra}]" (from an index: pip install "nsbench[{extra}]")'


def missing_modules(modules: tuple[str, ...]) -> list[str]:
    """The import names of ``modules`` that are not installed (found without importing them)."""
    out = []
    for name in modules:
        try:
            found = importlib.util.find_spec(name) is not None
        except (ImportError, ValueError):
            found = False
        if not found:
            out.append(name)
    return out


class OptionalBackend(Integrator):
    """Mixin of an integrator whose backend comes with a pip extra (see the module docstring)."""

    #: Import names of the backend's packages (``("CyRK",)``, ``("jax", "diffrax")``).
    backend_modules: ClassVar[tuple[str, ...]] = ()
    #: The extra of ``pyproject.toml`` that installs them.
    extra: ClassVar[str] = ""

    @classmethod
    def unavailable(cls) -> str | None:
        """Why it cannot run here (a backend package not installed, and the command that installs it), or ``None``."""
        gone = missing_modules(cls.backend_modules)
        if not gone:
            return None
        return f"{', '.join(gone)} not installed; install with {install_command(cls.extra)}"

    def setup(self, problem: "HybridProblem") -> None:
        reason = type(self).unavailable()
        if reason:
            raise UnsupportedProblemError(f"{self.name}: {reason}")
        super().setup(problem)
