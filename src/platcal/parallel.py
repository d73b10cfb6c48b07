"""Threads of the batched kernels (simulator, EKF, covariance-only runs).

The batched kernels run one replicate (or candidate scheme) per numba ``prange`` iteration.
Every replicate runs the same sequential code, so the thread count changes the speed only,
never the numbers. By default numba uses every core (``NUMBA_NUM_THREADS``); set fewer when
several processes share the machine (e.g. parallel workflow jobs)::

    from platcal.parallel import set_threads, threads
    set_threads(1)            # this Python thread's kernels use 1 numba thread from now on
    with threads(2):          # temporarily 2
        ...

``NUMBA_NUM_THREADS`` (environment, read at import) caps what can be set. numba is imported by
the first of these calls (:func:`platcal.jit.load_numba`), not by this module: a command whose
kernels are compiled ahead of time (:mod:`platcal.aot`) never asks for threads.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from contextlib import contextmanager

import numpy as np

from .jit import load_numba


def max_threads() -> int:
    """Most threads the kernels can use in this process (``NUMBA_NUM_THREADS``)."""
    return int(load_numba().config.NUMBA_NUM_THREADS)


def get_threads() -> int:
    """Threads the kernels use now (for the calling Python thread)."""
    return int(load_numba().get_num_threads())


def set_threads(n: int | None = None) -> int:
    """Use ``n`` numba threads for the batched kernels (None or 0: all, ``max_threads()``).

    Values above ``max_threads()`` are clipped to it; returns the number set. The setting is
    per calling Python thread (numba's rule).
    """
    cap = max_threads()
    n = cap if not n else max(1, min(int(n), cap))
    load_numba().set_num_threads(n)
    return n


@contextmanager
def threads(n: int | None):
    """Context manager: :func:`set_threads` ``(n)`` inside, the previous count restored after."""
    old = get_threads()
    set_threads(n)
    try:
        yield get_threads()
    finally:
        load_numba().set_num_threads(old)


def run_threaded(fn, n: int, threads: int | None, *args) -> None:
    """Run ``fn(lo, hi, *args)`` over the items [0, n) split into ``threads`` contiguous chunks
    (None or 0: the kernels' thread count now, :func:`get_threads`, which a job's threads set),
    one Python thread each.

    For kernels compiled ``nogil`` over independent items (replicates, blocks of replicates):
    the numbers do not depend on the thread count, and there is no ``parallel=True`` compile
    (which would cost a much longer compile).
    """
    threads = max(1, min(int(threads or get_threads()), n))
    if threads == 1:
        fn(0, n, *args)
        return
    bounds = np.linspace(0, n, threads + 1).astype(np.int64)
    with ThreadPoolExecutor(threads) as pool:
        list(pool.map(lambda i: fn(int(bounds[i]), int(bounds[i + 1]), *args), range(threads)))
