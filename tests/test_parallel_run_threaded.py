"""platcal.parallel.run_threaded: contiguous chunks over the items, the first in the calling
thread, each run to its end, the first chunk's exception (in item order) raised after all."""

import threading
import time

import numpy as np
import pytest

from platcal import parallel
from platcal.parallel import run_threaded


def _record(lo, hi, out, names):
    out[lo:hi] += 1
    names[lo:hi] = [threading.current_thread().name] * (hi - lo)


@pytest.mark.parametrize("n, threads", [(1, 2), (5, 1), (5, 2), (7, 3), (3, 8), (20, 2)])
def test_every_item_once_in_contiguous_chunks(n, threads):
    out = np.zeros(n, dtype=np.int64)
    names = [None] * n
    run_threaded(_record, n, threads, out, names)
    assert np.all(out == 1)
    k = min(threads, n)
    bounds = np.linspace(0, n, k + 1).astype(np.int64)
    chunks = [names[bounds[i]:bounds[i + 1]] for i in range(k)]
    assert all(len(set(c)) == 1 for c in chunks)                      # one thread per chunk
    assert len({c[0] for c in chunks}) == k                          # distinct threads
    assert chunks[0][0] == threading.current_thread().name           # the first chunk: the caller's


def test_first_exception_in_item_order_after_every_chunk():
    done = []

    def fn(lo, hi):
        if lo == 0:
            time.sleep(0.05)
            raise ValueError("chunk 0")
        time.sleep(0.1 if lo else 0)
        done.append(lo)
        if lo >= 6:
            raise KeyError(f"chunk at {lo}")

    with pytest.raises(ValueError, match="chunk 0"):
        run_threaded(fn, 9, 3)
    assert sorted(done) == [3, 6]                                     # the others ran to their end

    def late(lo, hi):
        if lo:
            raise KeyError(lo)

    with pytest.raises(KeyError, match="3"):
        run_threaded(late, 9, 3)                                      # chunk at 3 before chunk at 6


@pytest.mark.parametrize("n", [0, 1])
def test_one_item_runs_here_without_asking_for_threads(monkeypatch, n):
    """A batch of one (an identify of one record) runs in the calling thread and never asks
    numba for a thread count, which would load numba beside a kernel compiled ahead of time."""
    def no_numba():
        raise AssertionError("asked numba for threads")

    monkeypatch.setattr(parallel, "get_threads", no_numba)
    seen = []
    run_threaded(lambda lo, hi: seen.append((lo, hi, threading.current_thread().name)), n, None)
    assert seen == [(0, n, threading.current_thread().name)]
