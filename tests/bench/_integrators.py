"""Test-only integrators for the runner tests, importable by spawned worker processes.

They wrap real integrators (no fake results): one that sleeps per arc (to hit
the time limit), one that fails in ``setup``, one that can interrupt a run, ones that crash or hang only in the
timed runs (not in the short warm-up), and a tight DOP853 that stands in for the
high-precision cubic reference. The stand-in is *not* a certified reference: it
only lets the tests exercise the reference path on cubic problems.
"""

from __future__ import annotations

import os
from pathlib import Path
import time

from nsbench.integrators.base import Option
from nsbench.integrators.henon_rk4 import HenonRK4
from nsbench.integrators.scipy_ import ScipyDOP853, ScipyRK45


class SleepyRK45(ScipyRK45):
    """Sleeps 0.5 s per arc, so a wall-clock limit of 1 s ends its runs (a plain run takes milliseconds:
    the limit leaves the other cases a wide margin on a busy machine)."""

    name = "sleepy-rk45-test"
    accuracy_levels = ({"rtol": 1e-6, "atol": 1e-8},)

    def advance(self, request):
        time.sleep(0.5)
        return super().advance(request)


class BrokenSetup(ScipyRK45):
    """Raises an unexpected exception in setup (a bug in a plug-in)."""

    name = "broken-setup-test"
    accuracy_levels = ({"rtol": 1e-6, "atol": 1e-8},)

    def setup(self, problem):
        raise RuntimeError("plug-in bug in setup")


class HangingSetup(ScipyRK45):
    """Never returns from ``setup`` (a plug-in whose set-up loops)."""

    name = "hanging-setup-test"
    accuracy_levels = ({"rtol": 1e-6, "atol": 1e-8},)

    def setup(self, problem):
        time.sleep(3600)


#: Runs whose span ends past this are the timed ones in the tests (their warm-up covers a tenth).
TIMED_AFTER = 10.0


class Interrupting(ScipyRK45):
    """Raises KeyboardInterrupt (like Ctrl-C) in a timed run while NSBENCH_TEST_INTERRUPT names a
    run's folder that already holds a stored row (so that the interrupt finds finished work, whatever
    order the load gave the timed runs)."""

    name = "interrupting-test"
    accuracy_levels = ({"rtol": 1e-6, "atol": 1e-8},)

    def advance(self, request):
        folder = os.environ.get("NSBENCH_TEST_INTERRUPT")
        if folder and request.t_end > TIMED_AFTER and any(Path(folder, "cases").glob("*.parquet")):
            raise KeyboardInterrupt
        return super().advance(request)


class StandInReference(ScipyDOP853):
    """A tight DOP853 standing in for the quad-precision cubic reference (tests only)."""

    name = "standin-reference-test"
    options = {**ScipyDOP853.options}
    accuracy_levels = ({"rtol": 1e-13, "atol": 1e-15},)

    def __init__(self, **options):
        super().__init__(**{"rtol": 1e-13, "atol": 1e-15, **options})


class CoarseReference(HenonRK4):
    """RK4 at a coarse step (h = 1, stable but inaccurate) named as a suite's reference: a reference
    whose independent check logs another event sequence (on 2-DOF case 1 from t = 0.1 on)."""

    name = "coarse-reference-test"
    options = {"h": Option(1.0, float, lower=0.0)}
    accuracy_levels = ({"h": 1.0},)


class Crashing(ScipyRK45):
    """Kills its own process in the middle of a run, like a segfault in compiled code."""

    name = "crashing-test"
    accuracy_levels = ({"rtol": 1e-6, "atol": 1e-8},)

    def advance(self, request):
        os._exit(3)


class CrashingWhenTimed(ScipyRK45):
    """Warms up cleanly, then kills its process in the first timed run (a crash while timing)."""

    name = "crashing-when-timed-test"
    accuracy_levels = ({"rtol": 1e-9, "atol": 1e-11},)  # tighter than the others of its test: timed first

    def advance(self, request):
        if request.t_end > TIMED_AFTER:
            os._exit(5)
        return super().advance(request)


class HangingWhenTimed(ScipyRK45):
    """Warms up cleanly, then never returns from a timed run (only the parent can stop it)."""

    name = "hanging-when-timed-test"
    accuracy_levels = ({"rtol": 1e-9, "atol": 1e-11},)  # tighter than the others of its test: timed first

    def advance(self, request):
        if request.t_end > TIMED_AFTER:
            time.sleep(3600)
        return super().advance(request)


#: Sweep values of ``v0`` in this window make the ``*-at-test`` integrators misbehave.
BAD_V0 = (0.15, 0.17)


class _BadAtV0(ScipyRK45):
    """scipy-rk45 that misbehaves (``_fault``) only at belt speeds inside :data:`BAD_V0`."""

    accuracy_levels = ({"rtol": 1e-6, "atol": 1e-8},)

    def setup(self, problem):
        self._bad = BAD_V0[0] < problem.v0 < BAD_V0[1]
        return super().setup(problem)

    def advance(self, request):
        if self._bad:
            self._fault()
        return super().advance(request)


class HangingAt(_BadAtV0):
    """Never returns at the bad belt speeds (a hung plug-in)."""

    name = "hanging-at-test"

    def _fault(self):
        time.sleep(3600)


class ExitingAt(_BadAtV0):
    """Ends its process at the bad belt speeds (``os._exit``, like an abort in C)."""

    name = "exiting-at-test"

    def _fault(self):
        os._exit(7)


class SegfaultingAt(_BadAtV0):
    """Dies of SIGSEGV at the bad belt speeds (a crash in compiled code)."""

    name = "segfaulting-at-test"

    def _fault(self):
        import signal

        os.kill(os.getpid(), signal.SIGSEGV)


class UnevenRK45(ScipyRK45):
    """Every other run computes each arc four times (real work, same results): its samples spread far
    beyond 25 % on every clock whatever the machine does, so the runner gives it its extra samples."""

    name = "uneven-rk45-test"
    accuracy_levels = ({"rtol": 1e-6, "atol": 1e-8},)
    runs = 0

    def setup(self, problem):
        type(self).runs += 1  # the engine sets the integrator up once per run
        super().setup(problem)

    def advance(self, request):
        for _ in range(3 if type(self).runs % 2 else 0):
            super().advance(request)
        return super().advance(request)


class CompilingRK45(ScipyRK45):
    """Compiles for 1.5 s on its first arc in each process, as a kernel numba compiles on first use:
    the compile notice is told as numba's listener tells it (:mod:`nsbench.compiling`), around a
    sleep, so that the compilation outlasts a 1 s limit on any machine. The arcs themselves take
    milliseconds."""

    name = "compiling-rk45-test"
    accuracy_levels = ({"rtol": 1e-6, "atol": 1e-8},)
    compiled = False

    def advance(self, request):
        if not CompilingRK45.compiled:
            from nsbench.compiling import _NOTICE

            _NOTICE.on_start(f"{__name__}.CompilingRK45.advance")
            try:
                time.sleep(1.5)
            finally:
                _NOTICE.on_end()
            CompilingRK45.compiled = True
        return super().advance(request)
