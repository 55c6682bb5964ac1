"""The first call's cost: an integrator that compiles in its first ``advance``/``integrate``, not in ``setup``.

A bench times each case after a warm-up, so a compilation in the first call does
not reach a case's timed samples; but a single run (``nsbench simulate``,
:func:`nsbench.simulate`) times it as the method's, the estimate before a suite
counts it as work, and every worker process pays it again. The kit's flag says so:
:func:`first_call_cost` times ``setup``, then the same first arc (or whole run)
twice on one configured instance, and flags a first call that costs more than
:data:`FIRST_CALL_RATIO` times the second and more than :data:`FIRST_CALL_FLOOR`
seconds above it.

It is a flag, not a check of :data:`~nsbench.testing.CHECKS`: a ratio of wall
times is no property of the integrator's results, and on a loaded machine one
call can stall, so ``nsbench check`` prints it beside the checks' table and never
fails on it, and :func:`~nsbench.testing.parametrize_with_checks` does not turn it
into a test item.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any, Callable

from nsbench.integrators.base import ArcRequest
from nsbench.integrators.whole import is_whole_system

#: A first call is flagged when it costs more than this many times the second ...
FIRST_CALL_RATIO = 10.0
#: ... and more than this many seconds above it: below, a ratio is the scheduler's noise on calls of
#: microseconds, not a compilation (numba's smallest takes about 0.1 s, a kernel's seconds).
FIRST_CALL_FLOOR = 0.25


@dataclass(frozen=True)
class FirstCall:
    """Wall seconds of ``setup`` and of the first and second identical call after it."""

    integrator: str
    #: ``'advance'`` (one arc, a per-arc integrator) or ``'integrate'`` (a whole-system method).
    call: str
    setup: float
    first: float
    second: float

    @property
    def flagged(self) -> bool:
        """The first call costs more than :data:`FIRST_CALL_RATIO` times the second, by more than
        :data:`FIRST_CALL_FLOOR` seconds."""
        excess = self.first - self.second
        return excess > FIRST_CALL_FLOOR and self.first > FIRST_CALL_RATIO * self.second

    @property
    def message(self) -> str:
        """One line: the three times and, when flagged, what to do."""
        ratio = self.first / self.second if self.second > 0 else float("inf")
        times = (
            f"setup {self.setup:.3g} s, first {self.call} {self.first:.3g} s, second {self.second:.3g} s ({ratio:.3g}x)"
        )
        if not self.flagged:
            return times
        return (
            f"{times}: the first call compiles or loads something that setup() should; a single run "
            f"times it as {self.integrator}'s cost and every worker pays it again (move it into setup)"
        )


def first_call_cost(
    obj: Any,
    problem: str | dict[str, Any] | None = None,
    options: dict[str, Any] | None = None,
    stage: Callable[[str], None] | None = None,
):
    """Time ``setup``, then the first and the second identical call of ``obj`` on the kit's problem.

    Parameters
    ----------
    obj, options
        As for :func:`~nsbench.testing.check_integrator`.
    problem
        As for :func:`~nsbench.testing.check_integrator`: the belt's case 2 (by
        default the 2-DOF oscillator's), or the problem as given.
    stage
        Called with ``'integrator set-up'`` before ``setup`` and ``'first call'`` before
        the calls (a supervised worker announces each step with its own limit).

    Returns
    -------
    FirstCall
        The times; :attr:`FirstCall.flagged` says whether the first call compiled.

    Notes
    -----
    Run it before anything else in the process has used the integrator: numba's and
    the libraries' compilations are shared by a process, so a call after another run
    is warm whatever ``setup`` does (``nsbench check`` runs it first).
    """
    from nsbench.testing._checks import _problem, checking_on, on_presets
    from nsbench.testing._kit import configure

    integ, _ = configure(obj, options)
    integ = type(integ).from_config(integ.config())
    with checking_on(problem):
        prob = _problem(2)
        # the protocol check's first arc: tau in [0, 5] on the belt, five time scales elsewhere
        t_end = 5.0 if on_presets() else 5.0 * prob.time_scale
    y0 = prob.initial_state()
    announce = stage or (lambda what: None)
    announce("integrator set-up")
    tic = time.perf_counter()
    integ.setup(prob)
    setup = time.perf_counter() - tic
    if is_whole_system(integ):
        from nsbench.integrators.whole import SystemRequest

        def call():
            integ.integrate(SystemRequest(problem=prob, t0=0.0, y0=y0.copy(), t_end=t_end))

        kind = "integrate"
    else:
        mode = prob.initial_mode(0.0, y0)

        def call():
            integ.advance(
                ArcRequest(problem=prob, mode=mode, t0=0.0, y0=y0.copy(), t_end=t_end, guards=prob.guards(mode))
            )

        kind = "advance"
    times = []
    announce("first call")
    for _ in range(2):
        tic = time.perf_counter()
        call()
        times.append(time.perf_counter() - tic)
    return FirstCall(type(integ).name, kind, setup, times[0], times[1])
