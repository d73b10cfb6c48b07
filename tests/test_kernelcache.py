"""numba's cache after an edit of a callee in another file (platcal.kernelcache, numba #1833)."""

import os
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

import platcal
from platcal.kernelcache import package_root, package_stamp

SRC = Path(platcal.__file__).resolve().parents[1]

CALLER = """
from numba import njit
from .callee import g

@njit(cache=True)
def f():
    return g() + 1
"""
CALLEE = """
from numba import njit

@njit(cache=True)
def g():
    return {value}
"""


def _package(root: Path, value: int) -> None:
    pkg = root / "kpkg"
    pkg.mkdir(exist_ok=True)
    (pkg / "__init__.py").write_text("")
    (pkg / "caller.py").write_text(textwrap.dedent(CALLER))
    callee = pkg / "callee.py"
    before = callee.stat().st_mtime_ns if callee.exists() else 0
    callee.write_text(textwrap.dedent(CALLEE.format(value=value)))
    if callee.stat().st_mtime_ns == before:  # a coarse clock: the edit must show in the stamp
        os.utime(callee, ns=(before + 10**9, before + 10**9))


def _run(root: Path, locators: str | None) -> int:
    env = {k: v for k, v in os.environ.items() if not k.startswith("NUMBA_CACHE")}
    env["PYTHONPATH"] = os.pathsep.join([str(root), str(SRC)])
    if locators is not None:
        env["NUMBA_CACHE_LOCATOR_CLASSES"] = locators
    out = subprocess.run([sys.executable, "-c", "import platcal\nfrom kpkg.caller import f\nprint(f())"],
                         env=env, capture_output=True, text=True, check=True)
    return int(out.stdout.split()[-1])


def test_an_edited_callee_recompiles_its_callers(tmp_path):
    _package(tmp_path, 1)
    assert _run(tmp_path, None) == 2
    _package(tmp_path, 10)
    assert _run(tmp_path, None) == 11  # numba alone would load f's stale code: 2 (below)


def test_numba_alone_keeps_the_stale_kernel(tmp_path):
    """Why platcal sets the locators: with numba's own, the caller's cache survives the edit."""
    defaults = "UserProvidedCacheLocator,InTreeCacheLocator,UserWideCacheLocator,IPythonCacheLocator,ZipCacheLocator"
    _package(tmp_path, 1)
    assert _run(tmp_path, defaults) == 2
    _package(tmp_path, 10)
    assert _run(tmp_path, defaults) == 2


def test_package_root_and_stamp(tmp_path):
    _package(tmp_path, 1)
    assert package_root(tmp_path / "kpkg" / "callee.py") == tmp_path / "kpkg"
    assert package_root(tmp_path / "script.py") is None
    assert package_root(Path(platcal.__file__).parent / "estimation" / "kalman.py") == Path(platcal.__file__).parent
    first = package_stamp.__wrapped__(tmp_path / "kpkg")
    time.sleep(0.01)
    (tmp_path / "kpkg" / "extra.py").write_text("x = 1\n")
    assert package_stamp.__wrapped__(tmp_path / "kpkg") != first


def test_platcal_names_its_locators():
    """numba (imported before or after platcal) takes platcal's locators, each of which exists."""
    import numba.core.config
    import platcal.kernelcache as kc
    if os.environ["NUMBA_CACHE_LOCATOR_CLASSES"] != platcal._LOCATORS:
        pytest.skip("NUMBA_CACHE_LOCATOR_CLASSES set by the environment: the user's choice is kept")
    assert numba.core.config.CACHE_LOCATOR_CLASSES == platcal._LOCATORS
    for entry in platcal._LOCATORS.split(","):
        if entry.startswith("platcal."):
            assert issubclass(getattr(kc, entry.rsplit(".", 1)[1]), kc._PackageStamp), entry


@pytest.mark.parametrize("env, expected", [
    ({"OMP_NUM_THREADS": "1"}, 1),                                # a one-thread Snakemake job
    ({"OMP_NUM_THREADS": "1", "NUMBA_NUM_THREADS": "2"}, 2),       # numba's own variable wins
    ({"OMP_NUM_THREADS": "abc"}, None),                           # not a count: numba's default
])
def test_numba_threads_follow_the_jobs_omp_threads(env, expected):
    """A job's numba pool is sized by its OMP_NUM_THREADS (platcal/__init__.py), which Snakemake
    sets to the rule's threads; NUMBA_NUM_THREADS, when set, is numba's own and wins."""
    base = {k: v for k, v in os.environ.items() if k not in ("OMP_NUM_THREADS", "NUMBA_NUM_THREADS")}
    code = "import platcal, numba; print(numba.config.NUMBA_NUM_THREADS, numba.config.NUMBA_DEFAULT_NUM_THREADS)"
    out = subprocess.run([sys.executable, "-c", code], env={**base, **env, "PYTHONPATH": str(SRC)},
                         capture_output=True, text=True, check=True).stdout.split()
    got, default = int(out[0]), int(out[1])
    assert got == (default if expected is None else expected)
