"""The workflow jobs' memory allocator settings (platcal.parallel.job_environment; issue 22 item 4):
with them a process that allocates, fills and frees a large array over and over takes fresh pages
from the system for the first array only."""

import os
import subprocess
import sys

from platcal.parallel import job_environment

CHILD = """
import resource
import numpy as np
faults = []
for _ in range(20):
    before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
    a = np.empty(1 << 20)   # 8 MB: above glibc's default mmap threshold, and numpy's huge-page size
    a[:] = 1.0
    del a
    faults.append(resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before)
print(sum(faults[1:]))
"""


def faults_after_first(env: dict) -> int:
    """Page faults of the 2nd to 20th allocate-fill-free of an 8 MB array in a fresh process."""
    done = subprocess.run([sys.executable, "-c", CHILD], env=env, capture_output=True, text=True, check=True)
    return int(done.stdout.strip())


def test_job_environment_reuses_freed_memory():
    plain = {k: v for k, v in os.environ.items() if k not in job_environment()}
    # by default each array is a fresh mapping: at least one fault per allocation (4 with 2 MB
    # pages, 2048 with 4 kB ones); with the settings the freed memory is taken again, no fault
    assert faults_after_first(plain) >= 19
    assert faults_after_first({**plain, **job_environment()}) < 10

