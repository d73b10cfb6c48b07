"""Settings of the whole test run, read by every pytest process before any test module.

pytest-xdist (``-n auto`` in pyproject.toml's pytest options) runs the suite in one worker process
per core. numba's batched kernels use every core by default, so two workers on two cores would
each run two kernel threads: four busy threads on two cores, the suite's wall time about doubled
by the switching. Each worker therefore runs its kernels on its share of the cores (1 of 2 here),
and hands the same share to the commands and Snakemake runs it starts (platcal/__init__.py sizes
their pool from OMP_NUM_THREADS). The pool itself keeps numba's size: platcal and numba are
imported before OMP_NUM_THREADS is set, so the tests about threads (``threads(2)``, ``threads=2``,
bit-identical on 1 and 2 threads) still run two threads. A count the user set (NUMBA_NUM_THREADS
or OMP_NUM_THREADS) is kept, and a run without xdist's workers is left as it was.
"""

import os

import platcal  # noqa: F401  first: its OMP_NUM_THREADS rule sizes numba's pool as in any run
import numba

_WORKERS = int(os.environ.get("PYTEST_XDIST_WORKER_COUNT", "1"))
if _WORKERS > 1 and not {"NUMBA_NUM_THREADS", "OMP_NUM_THREADS"} & set(os.environ):
    _share = max(1, numba.config.NUMBA_NUM_THREADS // _WORKERS)
    numba.set_num_threads(_share)          # this worker's kernels (tests run in its main thread)
    os.environ["OMP_NUM_THREADS"] = str(_share)  # the processes it starts
