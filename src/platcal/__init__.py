"""platcal: identification of inertial-platform error coefficients from test-rig data."""

import atexit
import gc
import os
import sys

__version__ = "0.1.0"

# numba's cache knows a kernel's own file only: platcal.kernelcache stamps every kernel with its
# whole package, so that an edited callee is never run from a stale cache. Named here, before
# any kernel is decorated, without importing numba (a command that compiles nothing loads none).
_LOCATORS = ("platcal.kernelcache.PackageUserProvidedLocator,platcal.kernelcache.PackageInTreeLocator,"
             "platcal.kernelcache.PackageUserWideLocator,IPythonCacheLocator,ZipCacheLocator")
os.environ.setdefault("NUMBA_CACHE_LOCATOR_CLASSES", _LOCATORS)
if "numba.core.config" in sys.modules and not sys.modules["numba.core.config"].CACHE_LOCATOR_CLASSES:
    sys.modules["numba.core.config"].CACHE_LOCATOR_CLASSES = _LOCATORS  # numba imported before us

# numba's thread pool defaults to every core. A job given N threads runs its kernels on N: the
# job's OMP_NUM_THREADS (Snakemake sets it to the rule's threads, as BLAS and OpenMP read it) sizes
# the pool unless NUMBA_NUM_THREADS is set; a later --threads above it is clipped to it
# (platcal.parallel.set_threads). Before numba is imported only: the pool is fixed at its import.
_omp = os.environ.get("OMP_NUM_THREADS", "").strip()
if _omp.isdigit() and int(_omp) > 0 and "NUMBA_NUM_THREADS" not in os.environ and "numba" not in sys.modules:
    os.environ["NUMBA_NUM_THREADS"] = _omp

# A process that loaded numba's target holds over a million objects the garbage collector tracks
# (numba's typing and lowering registries, its cached kernels' libraries); the interpreter's
# collections at exit walk them all, 0.2-0.3 s CPU that every workflow job and command paid after
# its work was done (issue 22 item 4). Frozen at exit they are not walked: the atexit handlers
# and the modules' teardown run as before, and only reference cycles still alive at exit are left
# to the operating system, whose finalisers Python does not promise to run at exit anyway.
atexit.register(gc.freeze)
