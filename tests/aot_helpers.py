"""What every rig's test of its identify on kernels compiled ahead of time shares
(:mod:`platcal.aot`, issue 22 item 3): the build into a test's folder and the line a probe
interpreter prints (its command's exit code and whether numba and llvmlite were loaded)."""

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np

from platcal import aot

REPORT = ('print(json.dumps({"code": code, "numba": "numba" in sys.modules, '
          '"llvmlite": "llvmlite" in sys.modules}))\n')
"""The probe's last statement: ``code`` (the command's exit status) and the modules it loaded,
one JSON line on stdout (the probe imports json and sys)."""


def built_folder(tmp_path_factory, kernels: aot.KernelSet) -> Path:
    """A fresh folder holding ``kernels`` built from these sources (the build checked: its module is
    where :func:`platcal.aot.module_path` looks)."""
    folder = tmp_path_factory.mktemp("aot")
    path, _ = aot.build(kernels, folder)
    assert path == aot.module_path(kernels, folder) and path.is_file()
    return folder


def run_probe(probe: str, folder, cfg, data, out: Path, chunk_rows: str, aot_on: bool,
              options: tuple[str, ...] = ()) -> tuple[dict, dict]:
    """``platcal identify --config cfg [options] --data data --chunk-rows chunk_rows --out out`` run by
    ``probe`` (whose first argument is the .npz it saves its arrays to; its last line
    :data:`REPORT`'s) in a fresh interpreter on the kernels built in ``folder`` (``aot_on``) or on
    the JIT: the probe's report with the command's messages (``stderr``), and its arrays."""
    env = {**os.environ, "PLATCAL_AOT_DIR": str(folder), "PLATCAL_AOT": "1" if aot_on else "0"}
    arrays = out.with_name(out.name + ".npz")
    res = subprocess.run([sys.executable, "-c", probe, str(arrays), "identify", "--config", str(cfg), *options,
                          "--data", str(data), "--chunk-rows", chunk_rows, "--out", str(out)],
                         capture_output=True, text=True, env=env)
    assert res.returncode == 0, res.stderr
    info = json.loads(res.stdout.splitlines()[-1])
    assert info["code"] == 0, res.stderr
    info["stderr"] = res.stderr
    with np.load(arrays) as z:
        return info, {k: z[k] for k in z.files}
