"""What every rig's test of its identify on kernels compiled ahead of time shares
(:mod:`platcal.aot`, issue 22 item 3): the build into a test's folder and the line a probe
interpreter prints (its command's exit code and whether numba and llvmlite were loaded)."""

from platcal import aot

REPORT = ('print(json.dumps({"code": code, "numba": "numba" in sys.modules, '
          '"llvmlite": "llvmlite" in sys.modules}))\n')
"""The probe's last statement: ``code`` (the command's exit status) and the modules it loaded,
one JSON line on stdout (the probe imports json and sys)."""


def build_into(kset: aot.KernelSet, folder):
    """Build ``kset`` into ``folder`` under its current name; the folder."""
    path, _ = aot.build(kset, folder)
    assert path == aot.module_path(kset, folder) and path.is_file()
    return folder
