"""The hybrid core's Python side: one call runs a problem with an integrator through the compiled loop.

The compiled ground floor lives in :mod:`nsbench.model` (the law ABI, the generic
rules, the loop, the records); :mod:`.run` prepares a run's bundles, drives the
loop (growing buffers, building a kernel's data for a new mode, or running an
integrator's ``advance`` for each arc when it has no compiled kernel) and returns
a :class:`~nsbench.hybrid.run.RawRun`; :mod:`.records` makes the event log of it.

:func:`nsbench.simulate` (in :mod:`nsbench.engine`) is the public entry point.
"""
