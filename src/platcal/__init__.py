"""platcal: identification of inertial-platform error coefficients from test-rig data."""

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
