"""Bifurcation sweeps, the locus of sticking phase, Lyapunov exponents and the paper's results.

Modules, one job each: :mod:`.sweep` (one parameter value, a sweep spec),
:mod:`.storage` (incremental tidy results with resume), :mod:`.parallel`
(local processes and Dask), :mod:`.detect` (qualitative changes and candidate
bifurcation points), :mod:`.locus`, :mod:`.lyapunov`, :mod:`.figures`,
:mod:`.compare` (several integrators) and :mod:`.paper`; the commands ``nsbench bifurcation``
and ``nsbench continuation`` as functions: :mod:`.request` (what they ask for, checked once),
:mod:`.sweep_command`, :mod:`.continuation_command`, and :mod:`.cluster` (a Dask scheduler
reached up front). Every run goes
through the engine (:func:`nsbench.engine.run`: ``simulate``'s defaults and its
missed-crossing check), shaped by the problem: the
tables name the problem's state names and per-block counters. Nothing heavy is
imported here.
"""

#: Most parameter values of one sweep (``--sweep`` COUNT, ``paper --points``): a typo such as
#: 1e12 must not allocate terabytes. Split a longer sweep into several.
MAX_SWEEP_POINTS = 1_000_000
