"""The hybrid core: the stick/slip/reverse rules of MODEL.md and the one loop that applies them.

- :mod:`.rules`: the rules themselves, compiled once (modes, guards of a mode and
  their expected signs, the transition map, the initial mode, the wrong-side test,
  the settle step with event storms and budgets). Nothing else in nsbench
  re-implements them.
- :mod:`.loop`: the compiled hybrid loop. It runs an integrator's compiled arc
  kernel (``exact``, ``henon-rk4``, ``ofapi``, ``mcpi``) with no Python per event,
  or hands each arc back to Python for integrators without a kernel.
- :mod:`.records`: the growable buffers the loop writes (events, section hits,
  dense states) and their tidy frames.
- :mod:`.run`: the Python side: one call runs a problem with an integrator
  through the loop and returns a :class:`~nsbench.hybrid.run.RawRun`.

:func:`nsbench.simulate` (in :mod:`nsbench.engine`) is the public entry point.
"""
