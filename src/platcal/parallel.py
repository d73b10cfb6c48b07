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

from contextlib import contextmanager
from threading import Thread

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
    (None or 0: the kernels' thread count now, :func:`get_threads`, which a job's threads set;
    never more chunks than items, and one item runs in the calling thread without asking),
    one Python thread each: the first chunk in the calling thread, the others in threads started
    for this call (the caller would otherwise only wait; a pool started per call cost about twice
    a thread's start, issue 22 item 2). Every chunk runs to its end before this returns; the
    exception of the first chunk (in item order) that raised is raised then.

    For kernels compiled ``nogil`` over independent items (replicates, blocks of replicates):
    the numbers do not depend on the thread count, and there is no ``parallel=True`` compile
    (which would cost a much longer compile).
    """
    # one item or none runs here whatever was asked, and asks no thread count (numba then stays
    # unloaded beside a kernel compiled ahead of time)
    threads = 1 if n <= 1 else max(1, min(int(threads or get_threads()), n))
    if threads == 1:
        fn(0, n, *args)
        return
    bounds = [int(b) for b in np.linspace(0, n, threads + 1).astype(np.int64)]
    errors: list[BaseException | None] = [None] * threads

    def chunk(i: int) -> None:
        try:
            fn(bounds[i], bounds[i + 1], *args)
        except BaseException as exc:  # re-raised by the caller, in chunk order
            errors[i] = exc

    workers = [Thread(target=chunk, args=(i,), daemon=True) for i in range(1, threads)]
    for t in workers:
        t.start()
    try:
        chunk(0)
    finally:
        for t in workers:
            t.join()
    first = next((e for e in errors if e is not None), None)
    if first is not None:
        raise first
