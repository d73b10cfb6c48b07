"""Kernels compiled ahead of time with ``numba.pycc`` (issue 22 item 3: identify under 200 MB).

Why: ``import numba`` costs about 65 MB of resident memory over numpy and the first JIT kernel
another 65 (LLVM's code and numba's CPU target), so no command that JIT-loads a kernel stays
under 200 MB once it holds a record chunk and pyarrow. A kernel compiled ahead of time into a
CPython extension module runs on numpy's C API and the helpers pycc links into the module:
loading it imports neither numba nor llvmlite.

What: a rig declares a :class:`KernelSet` -- the kernels one of its commands calls, each by the
module path of its numba kernel (its ``py_func`` is compiled: the one definition the JIT compiles
too, no copy) and its numba signature (the types the command's glue passes). ``platcal kernels
--config <rig config>`` builds the set (:func:`build`) into the per-user cache
(:func:`cache_dir`: beside numba's own kind of cache, per user because the module is built for
this Python, numpy and numba, and outside the source tree so a read-only install works). The
module's name carries :func:`source_key`, a hash of every source file of the platcal package and
of the numpy, numba and Python versions: after any edit the name changes, the old module is never
loaded, and the command falls back to the JIT until it is built again. Nothing is built
implicitly (pycc takes seconds to a minute and needs a C compiler).

Where it is used: only in a command that asks for it (:func:`enable`; a rig's ``identify``), at
a batch of one (the serial kernels); the Monte Carlo, the study and every other command keep the
JIT. ``PLATCAL_AOT=0`` turns it off (the JIT as before); ``PLATCAL_AOT_DIR`` moves the cache.
The numbers are the JIT's: the same Python function compiled by the same numba, without
fastmath, for a generic x86-64 (``tests/test_aot.py`` checks the estimates, covariance and
history bit for bit).
"""

from __future__ import annotations

import functools
import hashlib
import importlib.machinery
import importlib.util
import json
import os
import re
import sys
import tempfile
import time
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .errors import InputError
from .io import atomic_files
from .jit import load_numba
from .parallel import get_threads
from .rig import resolve

PACKAGE_DIR = Path(__file__).resolve().parent
"""The platcal package whose sources key a build (:func:`source_key`)."""

_ENABLED = False
_LOADED: dict[str, object] = {}


@dataclass(frozen=True)
class AotKernel:
    """One kernel of a set: its exported ``name``, the ``module:attribute`` path of its numba
    kernel (:func:`platcal.jit.njit`) and its numba ``signature`` string (numba's types, e.g.
    ``"none(f8[:, ::1], i8)"``)."""

    name: str
    kernel: str
    signature: str


@dataclass(frozen=True)
class KernelSet:
    """The kernels a rig's command calls, compiled together into one extension module ``name``."""

    name: str
    kernels: tuple[AotKernel, ...]


def cache_dir() -> Path:
    """Where built modules live: ``PLATCAL_AOT_DIR``, else ``$XDG_CACHE_HOME/platcal/aot``
    (default ``~/.cache/platcal/aot``)."""
    if os.environ.get("PLATCAL_AOT_DIR"):
        return Path(os.environ["PLATCAL_AOT_DIR"])
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base) / "platcal" / "aot"


def _version_file(package: str) -> bytes:
    """The bytes of ``package``'s ``_version.py`` (its version, read without importing it)."""
    spec = importlib.util.find_spec(package)
    if spec is None or spec.origin is None:
        return b""
    path = Path(spec.origin).parent / "_version.py"
    return path.read_bytes() if path.is_file() else b""


@functools.cache  # once per process: its modules were imported from the tree as it was then
def source_key() -> str:
    """SHA-256 (first 20 hex digits) of the content of every ``.py`` file of the platcal package
    (path and bytes) and of the Python, numpy and numba versions: a build is current when it was
    made from exactly these sources by this toolchain."""
    digest = hashlib.sha256()
    for path in sorted(PACKAGE_DIR.rglob("*.py")):
        digest.update(path.relative_to(PACKAGE_DIR).as_posix().encode() + b"\0" + path.read_bytes() + b"\0")
    digest.update(sys.version.encode() + np.__version__.encode() + _version_file("numba"))
    return digest.hexdigest()[:20]


def module_name(kset: KernelSet) -> str:
    """The extension module's name: the set's name and the :func:`source_key`."""
    return f"_platcal_aot_{kset.name}_{source_key()}"


def module_path(kset: KernelSet, folder: Path | None = None) -> Path:
    """The built module's file in ``folder`` (default :func:`cache_dir`)."""
    return Path(folder or cache_dir()) / (module_name(kset) + importlib.machinery.EXTENSION_SUFFIXES[0])


def checks_path(kset: KernelSet, folder: Path | None = None) -> Path:
    """The argument checks of the built module (JSON beside it, :func:`_check`)."""
    return Path(folder or cache_dir()) / (module_name(kset) + ".json")


def enable(on: bool = True) -> None:
    """Use the ahead-of-time kernels in this process where they are built and current (a
    command's choice: the rigs' ``identify``); ``PLATCAL_AOT=0`` in the environment overrides."""
    global _ENABLED
    _ENABLED = bool(on)


def enabled() -> bool:
    """Whether :func:`kernel` may return ahead-of-time kernels now."""
    return _ENABLED and os.environ.get("PLATCAL_AOT", "1").strip() != "0"


def kernel(kset: KernelSet, name: str):
    """The ahead-of-time kernel ``name`` of ``kset`` when enabled and its module is built from
    the current sources, else None (the caller runs the JIT kernel). Its arguments are checked
    against the signature it was built for (:func:`_check`): a mismatch is a TypeError."""
    if not enabled():
        return None
    mod = _load(kset)
    if mod is None:
        return None
    fn = getattr(mod, name)
    spec = _LOADED[kset.name + ".spec"][name]

    def call(*args):
        _check(name, spec, args)
        return fn(*args)

    return call


def pick(kset: KernelSet, name: str, serial, threaded, batch: int):
    """The kernel a batch of ``batch`` replicates runs: at a batch of one the ahead-of-time
    kernel ``name`` of ``kset`` when enabled and current (:func:`kernel`), else the JIT's
    ``serial``; a larger batch ``serial`` on one numba thread, else ``threaded`` (its ``prange``
    over replicates). A batch of one asks no thread count, so numba stays unloaded with the
    ahead-of-time kernel."""
    if batch == 1:
        return kernel(kset, name) or serial
    return serial if get_threads() == 1 else threaded


def in_use() -> tuple[str, ...]:
    """The kernel sets this process has loaded (run on their ahead-of-time kernels)."""
    return tuple(name for name, mod in _LOADED.items() if not name.endswith(".spec") and mod is not None)


def missing() -> tuple[str, ...]:
    """The kernel sets this process asked for (enabled) and found not built for the current
    sources (:func:`source_key`): it ran their JIT kernels."""
    return tuple(name for name, mod in _LOADED.items() if not name.endswith(".spec") and mod is None)


def kernels_note() -> str:
    """What a command's summary line says of its kernels: how to build them when a set it asked
    for is not built for the current sources (:func:`missing`: numba and LLVM were loaded, about
    100 MB of peak memory that ``platcal kernels`` saves, README "Long records in bounded
    memory"), that they were compiled ahead of time when it ran on them (:func:`in_use`), else
    nothing (``PLATCAL_AOT=0``, or a command that asked for none)."""
    if missing():
        return (" (JIT kernels: `platcal kernels` with this --config compiles them ahead of time, once;"
                " identify then loads no numba and needs less memory)")
    if in_use():
        return " (kernels compiled ahead of time)"
    return ""


def _load(kset: KernelSet):
    """The set's current module (imported once per process), or None when it is not built."""
    if kset.name in _LOADED:
        return _LOADED[kset.name]
    path = module_path(kset)
    spec_path = checks_path(kset)
    mod = None
    if path.is_file() and spec_path.is_file():
        spec = importlib.util.spec_from_file_location(module_name(kset), path)
        mod = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(mod)
        _LOADED[kset.name + ".spec"] = json.loads(spec_path.read_text())
    _LOADED[kset.name] = mod
    return mod


_SCALARS = {"float64": (float, np.float64), "int64": (int, np.integer), "bool": (bool, np.bool_)}


def _check(name: str, spec: list, args: tuple) -> None:
    """Refuse arguments a pycc wrapper would convert silently (an int where the JIT would have
    compiled a float64 version, a strided array read as contiguous): TypeError naming the kernel
    and the argument."""
    if len(args) != len(spec):
        raise TypeError(f"ahead-of-time kernel {name}: {len(args)} arguments, built for {len(spec)}")
    for i, (a, s) in enumerate(zip(args, spec)):
        kind = s[0]
        if kind == "array":
            _, dtype, ndim, contiguous = s
            ok = (isinstance(a, np.ndarray) and a.dtype == np.dtype(dtype) and a.ndim == ndim
                  and (a.flags.c_contiguous or not contiguous) and a.flags.aligned)
        elif kind == "tuple":
            ok = isinstance(a, tuple)
            if ok:
                _check(f"{name} argument {i}", s[1], a)
        else:
            ok = isinstance(a, _SCALARS[kind]) and (kind == "bool" or not isinstance(a, (bool, np.bool_)))
        if not ok:
            raise TypeError(f"ahead-of-time kernel {name}: argument {i} is {type(a).__name__} "
                            f"{getattr(a, 'dtype', '')}{getattr(a, 'shape', '')}, built for {s}; "
                            "update the kernel set's signature and run 'platcal kernels' again")


def _spec_of(ty) -> list:
    """The argument check of one numba type (:func:`_check`), as JSON."""
    numba = load_numba()
    if isinstance(ty, numba.types.Array):
        return ["array", str(np.dtype(ty.dtype.name)), ty.ndim, ty.layout == "C"]
    if isinstance(ty, numba.types.BaseTuple):
        return ["tuple", [_spec_of(t) for t in ty.types]]
    names = {numba.types.float64: "float64", numba.types.int64: "int64", numba.types.boolean: "bool"}
    if ty not in names:
        raise TypeError(f"argument type {ty} is not one the ahead-of-time check knows; add it to platcal.aot")
    return [names[ty]]


def build(kset: KernelSet, folder: Path | None = None) -> tuple[Path, float]:
    """Compile ``kset`` with ``numba.pycc`` into ``folder`` (default :func:`cache_dir`) under its
    current name (:func:`module_path`), atomically (the argument checks, then the module, land
    together); older builds of the set there are removed. Returns the module's path and the build's
    wall time, s. Needs numba and a C compiler (the one Python's ``sysconfig`` names)."""
    t0 = time.perf_counter()
    numba = load_numba()  # the kernels' modules then hold numba's dispatchers, which pycc types
    # pycc is imported only here: the build's own dependency, never a command's at run time. Its
    # pending deprecation (numba 0.57) is known and said in the README; not repeated per build
    from numba.core import sigutils
    from setuptools.errors import CCompilerError, ExecError  # what pycc's compiler calls raise
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", numba.NumbaPendingDeprecationWarning)
        from numba.pycc import CC
    no_compiler = InputError("CC", "numba.pycc finds no working C compiler; install one (gcc: apt-get install gcc) or "
                                   "name it in the environment variable CC; identify runs on the JIT meanwhile")

    folder = Path(folder or cache_dir())
    folder.mkdir(parents=True, exist_ok=True)
    target = module_path(kset, folder)
    name = module_name(kset)
    checks = {}
    with tempfile.TemporaryDirectory(dir=folder, prefix=".build-") as work:
        try:  # pycc looks for the C compiler here, before any kernel is compiled (once per process)
            cc = CC(name)
        except RuntimeError as exc:
            raise no_compiler from exc
        cc.output_dir = work
        for k in kset.kernels:
            fn = resolve(k.kernel)
            args, _ = sigutils.normalize_signature(k.signature)
            checks[k.name] = [_spec_of(a) for a in args]
            cc.export(k.name, k.signature)(fn.py_func)
        try:
            cc.compile()
        except (CCompilerError, ExecError) as exc:  # a compiler that went away since pycc's check
            raise no_compiler from exc
        built = Path(work) / cc.output_file
        with atomic_files(folder) as tmp:
            tmp(checks_path(kset, folder).name).write_text(json.dumps(checks))
            os.replace(built, tmp(target.name))
    for old in folder.glob(f"_platcal_aot_{kset.name}_*"):
        stem = old.name.split(".")[0]
        # an older build of this set only: its name and another key (a set named "<name>_<more>" is another set's)
        if stem != name and re.fullmatch(r"[0-9a-f]{20}", stem[len(f"_platcal_aot_{kset.name}_"):]):
            old.unlink(missing_ok=True)
    return target, time.perf_counter() - t0
