"""numba's on-disk cache of compiled kernels, invalidated by any change of the kernel's package.

numba stamps a cached kernel with the modification time and size of the one file that defines
it (numba issue #1833, documented in "Cache invalidation" of numba's jit notes): a kernel that
calls or inlines a kernel of another file, or reads another module's constant, keeps its old
machine code after that file changes. platcal's kernels call across files (the Kalman update of
``estimation``, the frames of ``model``, a rig's model from its filter), so after an edit of a
callee a Snakemake rule would rerun - its code hash changed - with the old compiled code: a stale
result. The locators below stamp a kernel that lives in a package with its own file's stamp and
the (path, modification time, size) of every ``.py`` file of its top-level package, so any edit
of the package recompiles the package's kernels (once; numba then overwrites the stale entries).
A kernel outside a package keeps numba's own stamp.

``platcal/__init__.py`` selects these locators (in numba's default order) through numba's
``NUMBA_CACHE_LOCATOR_CLASSES`` unless the variable is already set; one who sets it keeps
numba's own stamps (``python -c "import platcal; print(platcal._LOCATORS)"`` gives platcal's).
"""

from __future__ import annotations

import functools
import hashlib
from pathlib import Path

from numba.core import caching


def package_root(py_file: str | Path) -> Path | None:
    """The directory of the top-level package holding ``py_file`` (the highest directory of an
    unbroken chain of ``__init__.py`` above it), or None for a file outside a package."""
    here = Path(py_file).resolve().parent
    root = None
    while (here / "__init__.py").is_file():
        root = here
        here = here.parent
    return root


@functools.cache  # once per process: its modules were imported from the tree as it was then
def package_stamp(root: Path) -> str:
    """SHA-256 of the relative path, modification time (ns) and size of every ``.py`` file under
    ``root``: changes when any source file of the package is edited, added, removed or renamed."""
    digest = hashlib.sha256()
    for path in sorted(root.rglob("*.py")):
        st = path.stat()
        digest.update(f"{path.relative_to(root).as_posix()}\0{st.st_mtime_ns}\0{st.st_size}\n".encode())
    return digest.hexdigest()


class _PackageStamp:
    """Mixin for numba's file-backed locators: the package's stamp beside the file's own."""

    def get_source_stamp(self):
        own = super().get_source_stamp()
        root = package_root(self._py_file)
        return own if root is None else (own, package_stamp(root))


class PackageUserProvidedLocator(_PackageStamp, caching.UserProvidedCacheLocator):
    """``NUMBA_CACHE_DIR`` when set, package-stamped."""


class PackageInTreeLocator(_PackageStamp, caching.InTreeCacheLocator):
    """``__pycache__`` beside the source, package-stamped."""


class PackageUserWideLocator(_PackageStamp, caching.UserWideCacheLocator):
    """The user's cache directory (a read-only install), package-stamped."""

