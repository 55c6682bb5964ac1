"""Bifurcation sweeps, the locus of sticking phase, Lyapunov exponents and the paper's results.

Modules, one job each: :mod:`.sweep` (one parameter value, a sweep spec),
:mod:`.storage` (incremental tidy results with resume), :mod:`.parallel`
(local processes and Dask), :mod:`.detect` (qualitative changes and candidate
bifurcation points), :mod:`.locus`, :mod:`.lyapunov`, :mod:`.figures`,
:mod:`.compare` (several integrators) and :mod:`.paper`. The compiled fast path
is :mod:`.jit_integrators` (integrators ``exact-jit`` and ``henon-rk4-jit``).
Nothing heavy is imported here.
"""
