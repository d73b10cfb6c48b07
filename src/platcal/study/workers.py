"""The Monte Carlo runner's ``joblib`` backend: a cell's chunks of replicates in worker processes.

Its own module, named by path in :data:`platcal.study.montecarlo.BACKENDS` and imported
(:func:`platcal.rig.resolve`) only when a cell runs on it: the default ``numba`` backend's cell
jobs do not load joblib (about 0.08 s CPU a job; issue 22 item 4).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable

from joblib import Parallel, delayed, parallel_config


def map_chunks(fn: Callable, calls: Iterable[tuple], workers: int, consume: Callable):
    """``consume`` applied to the results of ``fn(*args)`` for each ``args`` of ``calls``, run by
    ``workers`` loky worker processes with one numba and one BLAS thread each (``workers``
    workers use ``workers`` cores); the results come in the order of ``calls``."""
    with parallel_config(backend="loky", inner_max_num_threads=1):
        return consume(Parallel(n_jobs=workers, return_as="generator")(delayed(fn)(*a) for a in calls))
