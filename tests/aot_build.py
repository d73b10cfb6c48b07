"""A kernel set built ahead of time into a test's temporary folder (:func:`platcal.aot.build`), for
the rigs' ahead-of-time tests (``tests/test_aot*.py``)."""

from pathlib import Path

from platcal import aot


def built_folder(tmp_path_factory, kernels: aot.KernelSet) -> Path:
    """A fresh folder holding ``kernels`` built from these sources (the build checked: its module is
    where :func:`platcal.aot.module_path` looks)."""
    folder = tmp_path_factory.mktemp("aot")
    path, _ = aot.build(kernels, folder)
    assert path == aot.module_path(kernels, folder) and path.is_file()
    return folder
