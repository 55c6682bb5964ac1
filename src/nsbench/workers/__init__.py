"""Supervised worker processes: the floor every app's parallel work runs on.

A worker is a child process that answers tasks (:mod:`.protocol`, :mod:`.worker`);
the parent's handle on one is in :mod:`.pool`; on Linux workers are forked from a
factory that imports and prepares once (:mod:`.factory`); :mod:`.jobs` runs jobs
under hard time limits, each crash or hang costing only its own job. This package
imports no app (bench, bifurcation, periodic, testing, cli): the apps' tasks are
calls into their own packages (:class:`~.protocol.Call`, or a message with a
``perform`` method such as :mod:`nsbench.bench.tasks`).
"""
