"""numba kernels that import numba on their first call, not at their module's import (issue 22 item 3).

``import numba`` alone costs about 65 MB of resident memory, and the first JIT kernel it loads
another 65 (LLVM and numba's CPU target). A command whose kernels were compiled ahead of time
(:mod:`platcal.aot`) calls none of numba's, so the modules on its path declare their kernels
with this module's :func:`njit` and :data:`prange` instead of numba's: the same Python function
is the kernel's one definition (the JIT compiles it, the ahead-of-time build compiles its
``py_func``), and numba is imported only when a kernel is first called (or an attribute of
numba's dispatcher is read: ``signatures``, ``overloads``...).

When numba is first needed, :func:`load_numba` makes every kernel declared so far a numba
dispatcher with its options, and puts that dispatcher (and ``numba.prange``) in place of the
lazy object in every loaded ``platcal`` module: numba then types the calls between kernels and
their ``prange`` loops as if the modules had used numba's own decorators (the numbers and
numba's on-disk cache are the same). A kernel declared after numba is loaded is numba's
dispatcher at once. The lazy object also carries numba's type (``_numba_type_``), so one
captured elsewhere still types as its dispatcher.
"""

from __future__ import annotations

import sys
from contextlib import nullcontext

import numpy as np

from . import numba_inline

PACKAGE = __name__.rsplit(".", 1)[0]
"""The package whose modules' lazy kernels :func:`load_numba` replaces by numba's dispatchers."""


class Kernel:
    """A kernel declared by :func:`njit` before numba was imported: ``py_func`` and the options
    of ``numba.njit``; calling it (or reading any attribute numba's dispatcher has) loads numba
    and compiles or loads it from numba's cache as ``numba.njit(**options)(py_func)`` would."""

    def __init__(self, py_func, options: dict):
        self.py_func = py_func
        self.options = options
        self._dispatcher = None
        self.__name__ = py_func.__name__
        self.__qualname__ = py_func.__qualname__
        self.__module__ = py_func.__module__
        self.__doc__ = py_func.__doc__
        self.__wrapped__ = py_func

    @property
    def dispatcher(self):
        """numba's dispatcher of this kernel (numba loaded first if it is not)."""
        if self._dispatcher is None:
            load_numba()
        return self._dispatcher

    def __call__(self, *args, **kwargs):
        return self.dispatcher(*args, **kwargs)

    def __getattr__(self, name):
        return getattr(self.dispatcher, name)

    def __repr__(self):
        state = "not loaded" if self._dispatcher is None else "loaded"
        return f"<platcal.jit.Kernel {self.__qualname__} ({state})>"


class _Prange:
    """``prange`` before numba is loaded: ``range`` when the Python function runs as Python; in
    the kernels' modules it is replaced by ``numba.prange`` before numba types them."""

    def __call__(self, *args):
        return range(*args)


prange = _Prange()
_KERNELS: list[Kernel] = []
_PRANGE = prange


def numba_loaded() -> bool:
    """Whether numba has been imported in this process."""
    return "numba" in sys.modules


def njit(*args, **options):
    """``numba.njit`` without importing numba: ``@njit`` or ``@njit(cache=True, ...)`` with
    numba's options. A :class:`Kernel` until numba is loaded, numba's dispatcher after."""
    if args and callable(args[0]) and not options:
        return _declare(args[0], {})
    if args:
        raise TypeError("platcal.jit.njit takes numba's options by keyword (no signatures)")
    return lambda fn: _declare(fn, options)


def _declare(fn, options: dict):
    if numba_loaded() and _PRANGE is not prange:  # numba already loaded by load_numba
        import numba  # loaded already: a lookup in sys.modules
        return numba.njit(**options)(fn)
    kernel = Kernel(fn, options)
    _KERNELS.append(kernel)
    return kernel


def load_numba():
    """Import numba, make every declared kernel numba's dispatcher and put the dispatchers and
    ``numba.prange`` in place of the lazy objects in the loaded modules of the package; returns
    the numba module. Idempotent."""
    global prange
    # here, not at the module's top: this import is what a command with ahead-of-time kernels avoids
    import numba
    # before any kernel compiles: numba's inliner without its copies of the callee's fresh IR
    numba_inline.install(numba)
    if prange is _PRANGE:
        for k in _KERNELS:
            if k._dispatcher is None:
                k._dispatcher = numba.njit(**k.options)(k.py_func)
        prange = numba.prange
        for name, mod in list(sys.modules.items()):
            # not this module: its own _PRANGE must stay the placeholder the others are compared with
            if mod is None or name == __name__ or not (name == PACKAGE or name.startswith(PACKAGE + ".")):
                continue
            space = vars(mod)
            for attr, value in list(space.items()):
                if isinstance(value, Kernel):
                    space[attr] = value._dispatcher
                elif value is _PRANGE:
                    space[attr] = numba.prange
    return numba


def parallel_chunksize(n: int):
    """``numba.parallel_chunksize(n)`` when numba is loaded, else nothing: a parallel kernel is
    chosen by :func:`platcal.parallel.get_threads`, which loads numba, before this is entered."""
    return load_numba().parallel_chunksize(n) if numba_loaded() else nullcontext()


def kernel_input(a) -> np.ndarray:
    """``a`` as a C-contiguous float64 array that numba types as writable: a copy where numpy hands
    over a read-only view (a broadcast that needed no copy: one seed's rates, a record's own sample
    intervals), else ``a`` itself. numba compiles a kernel once per argument writeability, so a
    kernel fed through this compiles one signature for every batch and record (issue 22 item 4)."""
    a = np.ascontiguousarray(a, dtype=np.float64)
    return a if a.flags.writeable else a.copy()
