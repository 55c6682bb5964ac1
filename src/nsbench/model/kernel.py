"""An integrator's compiled arc kernel as the core sees it: its address table, data, options and hooks.

An integrator with a compiled kernel writes ``arc(kd, fo, prob, arc, sec, hits,
dense, si, y_out, cnt)`` (:mod:`nsbench.model.abi`) as a numba function in its
own module and returns an :class:`ArcKernel` from its ``kernel(problem)``
method; the core calls the function through its addresses and never imports
the integrator. :func:`one_arc` runs one arc of a kernel from Python (what an
integrator's ``advance`` does when the core asks it for a single arc).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np

from nsbench.model import abi
from nsbench.model.abi import KernelData


def arc_table(arc_function: Any, problem) -> np.ndarray:
    """The address table of a kernel's arc function compiled for ``problem``'s family
    (:func:`~nsbench.model.abi.arc_signature` of the type of its data)."""
    import numba

    from nsbench.model.functions import table

    data_type = numba.typeof(problem.data)
    key = (arc_function, data_type)
    if key not in _TABLES:  # addresses of compiled code stay put for the life of the process
        _TABLES[key] = table({0: (arc_function, abi.arc_signature(data_type))}, 1)
    return _TABLES[key].copy()


_TABLES: dict[tuple[Any, Any], np.ndarray] = {}


@dataclass
class ArcKernel:
    """A compiled arc kernel an integrator provides (see ``Integrator.kernel``).

    Attributes
    ----------
    table
        Addresses of the arc function (:func:`arc_table`).
    data
        The kernel's data (:class:`~nsbench.model.abi.KernelData`).
    options
        Float options the kernel reads (``fo``), in the integrator's named layout.
    counters
        Names of the method-specific counter slots, in order.
    prepare_mode
        Called with a mode (int array) the kernel has no data for; returns the new ``data``.
    prepare_run
        Called with the number of sections before a run or an arc; returns the ``data`` to use.
    failure
        ``failure(code, t)``: the message of a method-specific failure code.
    """

    table: np.ndarray
    data: KernelData
    options: np.ndarray
    counters: tuple[str, ...] = ()
    prepare_mode: Callable[[np.ndarray], KernelData] | None = None
    prepare_run: Callable[[int], KernelData] | None = None
    failure: Callable[[int, float], str] | None = None
    name: str = field(default="")

    def data_for(self, n_sections: int) -> KernelData:
        return self.prepare_run(n_sections) if self.prepare_run is not None else self.data


def section_bundle(sections, n: int, hit_from: float = -math.inf, hit_stop: int = -1) -> abi.Sections:
    """The :class:`~nsbench.model.abi.Sections` of linear state sections (objects with ``coeffs``,
    ``level``, ``direction``)."""
    coeffs = np.ascontiguousarray(np.array([s.coeffs for s in sections], dtype=float).reshape(len(sections), n))
    levels = np.ascontiguousarray([s.level for s in sections], dtype=float)
    directions = np.ascontiguousarray([s.direction for s in sections], dtype=np.int64)
    return abi.Sections(coeffs, levels, directions, float(hit_from), int(hit_stop))


@dataclass
class ArcOutcome:
    """What one arc of a kernel gave, as Python values (``status`` is a kernel code)."""

    status: int
    t: float
    t_lo: float
    fired: int
    y: np.ndarray
    y_eval: np.ndarray  # (n_states, n_points)
    hits: list[tuple[int, float, np.ndarray]]
    counters: np.ndarray  # the kernel's counter slots


def one_arc(
    kernel: ArcKernel,
    prob,
    mode,
    guards: tuple[np.ndarray, np.ndarray, np.ndarray],
    n_guards: int,
    t0: float,
    t0_lo: float,
    y0,
    t_end: float,
    max_steps: int,
    sections,
    t_eval: np.ndarray,
) -> ArcOutcome:
    """One arc of ``kernel`` (growing the hit buffer and building mode data as it asks), from Python."""
    from nsbench.model.loop import call_arc

    y0 = np.array(y0, dtype=float)
    n = y0.shape[0]
    mode = np.ascontiguousarray(mode, dtype=np.int64)
    sec = section_bundle(sections, n)
    t_eval = np.ascontiguousarray(t_eval, dtype=float)
    dense = abi.Dense(t_eval, np.empty((t_eval.size, n)))
    hits = abi.Hits(np.empty(16, np.int64), np.empty(16), np.empty((16, n)))
    y_out = np.empty(n)
    kd = kernel.data_for(len(sections))
    gk, gi, gs = (np.ascontiguousarray(g, dtype=np.int64) for g in guards)
    arc = abi.Arc(
        mode, gk, gi, gs, int(n_guards), float(t0), float(t0_lo), y0, float(t_end), int(min(max_steps, 2**62))
    )
    while True:
        si = np.zeros(abi.N_SI, np.int64)
        cnt = np.zeros(abi.N_COUNTERS, np.int64)
        status, t, t_lo, fired = call_arc(kernel.table, kd, kernel.options, prob, arc, sec, hits, dense, si, y_out, cnt)
        if status == abi.K_HIT_FULL:
            size = 2 * hits.t.shape[0]
            hits = abi.Hits(np.empty(size, np.int64), np.empty(size), np.empty((size, n)))
        elif status == abi.K_NEED_MODE:
            # only a kernel with prepare_mode asks for a mode (K_NEED_MODE)
            assert kernel.prepare_mode is not None
            kd = kernel.prepare_mode(mode.copy())
        else:
            break
    found = [(int(hits.index[j]), float(hits.t[j]), hits.y[j].copy()) for j in range(int(si[abi.SI_NHITS]))]
    return ArcOutcome(
        int(status),
        float(t),
        float(t_lo),
        int(fired),
        y_out.copy(),
        dense.y[: int(si[abi.SI_IEVAL])].T.copy(),
        found,
        cnt,
    )
