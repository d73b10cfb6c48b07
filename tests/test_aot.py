"""The centrifuge's identify on kernels compiled ahead of time (:mod:`platcal.aot`, issue 22 item 3):
built with numba.pycc, it loads neither numba nor llvmlite and gives the JIT's numbers bit for bit;
a module built from other sources is never loaded (the JIT runs instead)."""

import os
import shutil
import subprocess
import sys

import numpy as np
import pytest

from aot_helpers import REPORT, built_folder, run_probe
from centrifuge_short import short_config
from platcal import aot
from platcal.cli import main
from platcal.rigs.centrifuge.aot_kernels import KERNELS

pytestmark = pytest.mark.slow  # the build compiles two kernels with pycc and a C compiler

PROBE = """
import json, sys
import numpy as np
from platcal.cli import main
from platcal.rigs.centrifuge import commands

write = commands.write_identification

def keep(out_dir, est, *args, **kw):  # the run's arrays, before the tables round them
    np.savez(sys.argv[1], x=est.x, P=est.P, history_t=est.history_t, history_x=est.history_x,
             history_sigma=est.history_sigma, nis=est.mean_nis)
    return write(out_dir, est, *args, **kw)

commands.write_identification = keep
code = main(sys.argv[2:])
""" + REPORT


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    """A folder holding the centrifuge's kernel set built from these sources."""
    return built_folder(tmp_path_factory, KERNELS)


@pytest.fixture(scope="module")
def record(tmp_path_factory):
    """The short study's config and a noisy record of it (3 positions x 4 s, 2400 rows)."""
    folder = tmp_path_factory.mktemp("rec")
    cfg = folder / "config.yaml"
    cfg.write_text(short_config())
    rec = folder / "rec.csv"
    assert main(["simulate", "--config", str(cfg), "--scheme", "short", "--seed", "1", "--out", str(rec)]) == 0
    return cfg, rec


def identify(record, folder, out, chunk_rows: str, aot_on: bool) -> tuple[dict, dict]:
    """Run identify in a fresh interpreter with the kernels of ``folder``; its modules and arrays."""
    cfg, rec = record
    return run_probe(PROBE, folder, cfg, rec, out, chunk_rows, aot_on, ("--scheme", "short"))


@pytest.mark.parametrize("chunk_rows", ["0", "500"])
def test_aot_identify_loads_no_numba_and_equals_the_jit(built, record, tmp_path, chunk_rows):
    """Whole (``--chunk-rows 0``) and streamed (500 rows: the kernel runs chunk by chunk), the
    identify on the built module imports neither numba nor llvmlite; with ``PLATCAL_AOT=0`` the JIT
    runs (numba loaded) and the estimate, covariance, history and NIS are equal bit for bit. A
    streamed identify writes its history to history.csv block by block (the Estimate holds none):
    there the files are compared, and with the whole read's."""
    info_a, a = identify(record, built, tmp_path / "aot", chunk_rows, True)
    info_j, j = identify(record, built, tmp_path / "jit", chunk_rows, False)
    assert not info_a["numba"] and not info_a["llvmlite"]
    assert "(kernels compiled ahead of time)" in info_a["stderr"] and "platcal kernels" not in info_a["stderr"]
    assert info_j["numba"] and info_j["llvmlite"]
    assert "ahead of time" not in info_j["stderr"]
    assert a.keys() == j.keys()
    for k in a:
        assert np.array_equal(a[k], j[k]), k
    history = (tmp_path / "aot" / "history.csv").read_bytes()
    assert history == (tmp_path / "jit" / "history.csv").read_bytes()
    # the header and a row at each whole second of each 4 s position (1, 2, 3 s; one pass)
    assert history.count(b"\n") == 1 + 3 * 3
    if chunk_rows == "0":
        assert a["history_x"].shape[1] > 0
    else:
        _, w = identify(record, built, tmp_path / "whole", "0", True)
        assert history == (tmp_path / "whole" / "history.csv").read_bytes()
        for k in ("x", "P", "nis"):
            assert np.array_equal(a[k], w[k]), k


def test_a_module_built_from_other_sources_is_not_loaded(built, record, tmp_path):
    """A module whose name carries another source key (any edit of the package changes it) is
    ignored: identify falls back to the JIT, with the same numbers, and its line says how to build
    the kernels (:func:`platcal.aot.kernels_note`)."""
    stale = tmp_path / "stale"
    stale.mkdir()
    name = aot.module_name(KERNELS)
    other = f"_platcal_aot_{KERNELS.name}_{'0' * 20}"
    for f in built.iterdir():
        shutil.copy(f, stale / f.name.replace(name, other))
    assert not aot.module_path(KERNELS, stale).exists()
    info, s = identify(record, stale, tmp_path / "stale_out", "0", True)
    assert info["numba"]
    assert "JIT kernels: `platcal kernels` with this --config" in info["stderr"]
    assert "(kernels compiled ahead of time)" not in info["stderr"]
    _, a = identify(record, built, tmp_path / "aot", "0", True)
    for k in a:
        assert np.array_equal(a[k], s[k]), k


def test_the_source_key_changes_with_any_source_file(tmp_path, monkeypatch):
    """The key hashes every .py file of the package by content: an edit of one changes it, and
    the same sources give the same key."""
    copy = tmp_path / "platcal"
    shutil.copytree(aot.PACKAGE_DIR, copy, ignore=shutil.ignore_patterns("__pycache__"))
    monkeypatch.setattr(aot, "PACKAGE_DIR", copy)
    aot.source_key.cache_clear()
    try:
        k0 = aot.source_key()
        aot.source_key.cache_clear()
        assert aot.source_key() == k0
        kalman = copy / "estimation" / "kalman.py"
        kalman.write_text(kalman.read_text() + "\n# an edit\n")
        aot.source_key.cache_clear()
        assert aot.source_key() != k0
    finally:
        aot.source_key.cache_clear()


def test_arguments_unlike_the_build_are_refused():
    """The argument check refuses what pycc's wrapper would convert silently: an int for a
    float64, a strided array for a contiguous one, another dtype."""
    spec = [["array", "float64", 2, True], ["float64"], ["tuple", [["int64"], ["bool"]]]]
    good = (np.zeros((2, 3)), 1.0, (np.int64(2), True))
    aot._check("k", spec, good)
    for bad in [(np.zeros((2, 3)), 1, good[2]), (np.zeros((3, 4))[:, ::2], 1.0, good[2]),
                (np.zeros((2, 3), np.float32), 1.0, good[2]), (np.zeros((2, 3)), 1.0, (2.0, True))]:
        with pytest.raises(TypeError, match="ahead-of-time kernel k"):
            aot._check("k", spec, bad)


def test_no_c_compiler_is_refused_naming_cc(record, tmp_path):
    """Without a working C compiler ``platcal kernels`` exits 2 naming CC, and writes nothing
    (a fresh process: pycc checks the compiler once per process)."""
    cfg, _ = record
    env = {**os.environ, "CC": str(tmp_path / "no-such-compiler"), "PLATCAL_AOT_DIR": str(tmp_path / "aot")}
    res = subprocess.run([sys.executable, "-m", "platcal.cli", "kernels", "--config", str(cfg)], capture_output=True,
                         text=True, env=env)
    assert res.returncode == 2, res.stderr
    assert res.stderr.startswith("platcal kernels: error: CC: numba.pycc finds no working C compiler"), res.stderr
    assert len(res.stderr.strip().splitlines()) == 1
    assert not any(p.is_file() for p in (tmp_path / "aot").rglob("*"))
